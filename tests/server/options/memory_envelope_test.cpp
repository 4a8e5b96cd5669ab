// The memory envelope against hand-computed sums: derived budgets fill what the footprint
// and the given budgets leave, each counted with its copies; budgets that do not fit are
// refused naming every term; the backends decide a stored mesh's copies; and a server
// whose budgets do not fit its memory does not start.
#include "options/memory_envelope.h"

#include <gtest/gtest.h>

#include "options/server_options.h"

namespace skinserve::server {
namespace {

constexpr uint64_t kMiB = 1 << 20;

ServerOptions WithMemory(uint64_t mb) {
  ServerOptions options;
  options.memory_limit_mb = mb;
  return options;
}

TEST(MemoryEnvelopeTest, DerivedBudgetsShareWhatTheFootprintLeavesCountedWithTheirCopies) {
  const MemoryEnvelope e = WithMemory(4096).Envelope();
  EXPECT_EQ(e.memory_bytes, 4096 * kMiB);
  EXPECT_EQ(e.memory_source, "--memory-limit-mb");
  // --clip-budget-mb is given by default (64 MiB): it comes off first, as given budgets do.
  EXPECT_FALSE(e.term("--clip-budget-mb").derived);
  const double left = 4096 * 0.9 * kMiB - 256.0 * kMiB - 64.0 * kMiB;
  // Every backend enabled: a mesh, opencl's buffers and simd's copies, 2.5 times its bytes.
  EXPECT_EQ(e.term("--mesh-budget-mb").copies, 2.5);
  EXPECT_EQ(e.term("--upload-budget-mb").copies, 2);
  for (const auto& [flag, share, copies] :
       {std::tuple{"--mesh-budget-mb", 0.30, 2.5}, std::tuple{"--inflight-budget-mb", 0.20, 1.0},
        std::tuple{"--grpc-memory-mb", 0.10, 1.0}, std::tuple{"--upload-budget-mb", 0.20, 2.0},
        std::tuple{"--shm-budget-mb", 0.20, 1.0}}) {
    const EnvelopeTerm& t = e.term(flag);
    EXPECT_TRUE(t.derived) << flag;
    EXPECT_NEAR(static_cast<double>(t.budget_bytes), left * share / copies, kMiB) << flag;
    EXPECT_EQ(t.budget_bytes % kMiB, 0u) << flag << ": not whole MiB";
  }
  EXPECT_LE(e.sum_bytes(), e.limit_bytes());
  // Each derived budget is whole MiB (rounded down): it leaves less than its copies in MiB.
  double rounding = 0;
  for (const EnvelopeTerm& t : e.terms) rounding += t.derived ? t.copies * kMiB : 0;
  EXPECT_GE(static_cast<double>(e.sum_bytes()), static_cast<double>(e.limit_bytes()) - rounding)
      << "the derived budgets leave memory unused";
  EXPECT_TRUE(e.Check().ok());
  // The server's getters hand out the envelope's budgets.
  ServerOptions options = WithMemory(4096);
  EXPECT_EQ(options.InflightBudgetBytes(), e.term("--inflight-budget-mb").budget_bytes);
  EXPECT_EQ(options.UploadBudgetBytes(), e.term("--upload-budget-mb").budget_bytes);
  EXPECT_EQ(options.ToRegionLimits().budget_bytes, e.term("--shm-budget-mb").budget_bytes);
  EXPECT_EQ(options.ToEngineOptions().mesh_budget_bytes, e.term("--mesh-budget-mb").budget_bytes);
  EXPECT_EQ(options.GrpcMemoryBytes(), e.term("--grpc-memory-mb").budget_bytes);
  EXPECT_EQ(options.ToEngineOptions().clip_budget_bytes, 64 * kMiB);
}

TEST(MemoryEnvelopeTest, GivenBudgetsComeFirstAndTheRestShareWhatIsLeft) {
  ServerOptions options = WithMemory(4096);
  options.mesh_budget_mb = 1000;
  options.backends = {"sse", "opencl"};  // no simd: a mesh and opencl's buffers
  options.shm_dir = "";                  // shared memory off: no regions term
  const MemoryEnvelope e = options.Envelope();
  EXPECT_EQ(e.term("--mesh-budget-mb").copies, 2.0);
  EXPECT_FALSE(e.term("--mesh-budget-mb").derived);
  EXPECT_EQ(e.term("--mesh-budget-mb").held_bytes(), 2000 * kMiB);
  EXPECT_THROW(e.term("--shm-budget-mb"), std::logic_error);
  const double left = 4096 * 0.9 * kMiB - 256.0 * kMiB - 2000.0 * kMiB - 64.0 * kMiB;
  EXPECT_NEAR(static_cast<double>(e.term("--inflight-budget-mb").budget_bytes), left * 0.20 / 0.50,
              kMiB);
  EXPECT_NEAR(static_cast<double>(e.term("--upload-budget-mb").budget_bytes),
              left * 0.20 / 0.50 / 2, kMiB);
  EXPECT_NEAR(static_cast<double>(e.term("--grpc-memory-mb").budget_bytes), left * 0.10 / 0.50,
              kMiB);
  EXPECT_TRUE(e.Check().ok());
}

TEST(MemoryEnvelopeTest, BudgetsThatDoNotFitAreRefusedNamingEveryTermAndTheSum) {
  ServerOptions options = WithMemory(3072);
  options.mesh_budget_mb = 1024;  // 2560 MiB held with every backend: over 90% of 3072 + 256
  const MemoryEnvelope e = options.Envelope();
  const Status status = e.Check();
  ASSERT_EQ(status.code(), StatusCode::kInvalidArgument);
  for (const char* named : {"--mesh-budget-mb 1024 MiB x 2.5", "--inflight-budget-mb 16 MiB",
                            "--upload-budget-mb 16 MiB", "--shm-budget-mb 16 MiB",
                            "--grpc-memory-mb 16 MiB", "--clip-budget-mb 64 MiB",
                            "the process itself", "2960 MiB", "90% of the 3072 MiB it may use"}) {
    EXPECT_NE(status.message().find(named), std::string::npos)
        << "'" << named << "' not in: " << status.message();
  }
  options.mesh_budget_mb = 900;  // 2250 + 256 + 64 + 80 of derived minimums = 2650 <= 2764
  EXPECT_TRUE(options.Envelope().Check().ok()) << options.Envelope().Describe();
}

TEST(MemoryEnvelopeTest, WithoutAGivenLimitTheCgroupOrPhysicalMemoryIsTheLimit) {
  const MemoryEnvelope e = EnvelopeMemory(0);
  EXPECT_GT(e.memory_bytes, 0u);
  EXPECT_TRUE(e.memory_source == "physical memory" ||
              e.memory_source == "the cgroup's memory limit")
      << e.memory_source;
}

}  // namespace
}  // namespace skinserve::server
