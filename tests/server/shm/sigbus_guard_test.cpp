// SigbusGuard alone: a write into a guarded mapping whose file was truncated lands in
// anonymous memory and marks the region (instead of killing the process), and a SIGBUS
// outside every guarded range still kills it, as it would without the guard.
#include <fcntl.h>
#include <sys/mman.h>
#include <unistd.h>

#include <gtest/gtest.h>

#include <atomic>
#include <csignal>
#include <cstring>
#include <filesystem>

#include "shm/mapped_region.h"
#include "shm/sigbus_guard.h"

// clang spells "built with ASan" __has_feature(address_sanitizer); gcc __SANITIZE_ADDRESS__.
#if defined(__has_feature)
#if __has_feature(address_sanitizer)
#define SKINSERVE_HAS_ASAN 1
#endif
#endif
#if defined(__SANITIZE_ADDRESS__)
#define SKINSERVE_HAS_ASAN 1
#endif
#ifndef SKINSERVE_HAS_ASAN
#define SKINSERVE_HAS_ASAN 0
#endif

namespace skinserve::testing {
namespace {

constexpr bool kBuiltWithAsan = SKINSERVE_HAS_ASAN;

constexpr std::size_t kBytes = 1 << 20;

std::string MakeFile(const std::string& dir, const char* name) {
  const std::string path = dir + "/" + name;
  const int fd = open(path.c_str(), O_RDWR | O_CREAT | O_TRUNC, 0600);
  EXPECT_GE(fd, 0);
  EXPECT_EQ(ftruncate(fd, kBytes), 0);
  close(fd);
  return path;
}

class SigbusGuardTest : public ::testing::Test {
 protected:
  void SetUp() override {
    char name[] = "/dev/shm/skinserve-sigbus-XXXXXX";
    dir_ = mkdtemp(name);
    dir_fd_ = open(dir_.c_str(), O_RDONLY | O_DIRECTORY);
  }
  void TearDown() override {
    close(dir_fd_);
    std::filesystem::remove_all(dir_);
  }
  std::string dir_;
  int dir_fd_ = -1;
};

TEST_F(SigbusGuardTest, AWriteIntoATruncatedRegionLandsElsewhereAndFailsTheRegion) {
  const std::string path = MakeFile(dir_, "region");
  auto region = server::MappedRegion::Open(dir_fd_, "r", "region", kBytes, "test", geteuid());
  ASSERT_TRUE(region.ok()) << region.status().ToString();
  std::memset((*region)->bytes().data(), 1, kBytes);
  EXPECT_TRUE((*region)->CheckIntact().ok());
  ASSERT_EQ(truncate(path.c_str(), 0), 0);  // the client takes the pages away
  // Without the guard this memset dies of SIGBUS on its first byte.
  std::memset((*region)->bytes().data(), 2, kBytes);
  const Status s = (*region)->CheckIntact();
  EXPECT_EQ(s.code(), StatusCode::kFailedPrecondition);
  EXPECT_NE(s.message().find("'r' was truncated by its owner while the server wrote"),
            std::string::npos)
      << s.message();
}

TEST_F(SigbusGuardTest, ASigbusOutsideEveryRegionStillKillsTheProcess) {
  server::SigbusGuard::Install();
  const std::string path = MakeFile(dir_, "unguarded");
  const auto write_past_a_truncated_file = [&path] {
    const int fd = open(path.c_str(), O_RDWR);
    auto* bytes =
        static_cast<char*>(mmap(nullptr, kBytes, PROT_READ | PROT_WRITE, MAP_SHARED, fd, 0));
    if (ftruncate(fd, 0) != 0) std::_Exit(3);
    bytes[0] = 1;  // not guarded: SIGBUS, as without the guard
    std::_Exit(0);
  };
  if (kBuiltWithAsan) {
    // Under ASan the guard hands the signal on to ASan's handler, which reports the BUS and
    // exits 1: the process still dies of it.
    EXPECT_EXIT(write_past_a_truncated_file(), ::testing::ExitedWithCode(1),
                "AddressSanitizer: BUS");
  } else {
    EXPECT_EXIT(write_past_a_truncated_file(), ::testing::KilledBySignal(SIGBUS), "");
  }
}

// A library that puts its own SIGBUS handler over the guard's (PoCL's LLVM does when it
// compiles a kernel; its handler then restores the default action): Install(), which the
// server calls before each frame it writes into a region, takes the signal back, and the
// foreign handler becomes the one faults outside every region go to. In a child process,
// so this process's handlers stay as they were: exit 42 is success (the foreign handler
// reached from outside the region only), 41 the foreign handler reached from inside it.
std::atomic<bool> g_outside_phase{false};
void ForeignHandler(int) { std::_Exit(g_outside_phase.load() ? 42 : 41); }

TEST_F(SigbusGuardTest, AHandlerInstalledOverTheGuardsIsTakenBackAndChained) {
  const std::string region_path = MakeFile(dir_, "region");
  const std::string other_path = MakeFile(dir_, "unguarded");
  const auto scenario = [&] {
    auto region = server::MappedRegion::Open(dir_fd_, "r", "region", kBytes, "test", geteuid());
    if (!region.ok()) std::_Exit(3);
    struct sigaction foreign = {};
    foreign.sa_handler = &ForeignHandler;
    sigemptyset(&foreign.sa_mask);
    sigaction(SIGBUS, &foreign, nullptr);  // over the guard's, as LLVM's RegisterHandlers
    server::SigbusGuard::Install();        // what the server does before a region frame
    if (truncate(region_path.c_str(), 0) != 0) std::_Exit(4);
    std::memset((*region)->bytes().data(), 2, kBytes);  // caught by the guard, not the foreign one
    if ((*region)->CheckIntact().code() != StatusCode::kFailedPrecondition) std::_Exit(5);
    g_outside_phase.store(true);
    const int fd = open(other_path.c_str(), O_RDWR);
    auto* bytes =
        static_cast<char*>(mmap(nullptr, kBytes, PROT_READ | PROT_WRITE, MAP_SHARED, fd, 0));
    if (ftruncate(fd, 0) != 0) std::_Exit(6);
    bytes[0] = 1;  // outside every region: handed on to the foreign handler
    std::_Exit(7);
  };
  EXPECT_EXIT(scenario(), ::testing::ExitedWithCode(42), "");
}

// What LLVM's handler does (llvm/lib/Support/Unix/Signals.inc): put back the handler it
// replaced and return for the fault to rerun. The fault must then end as it would without
// the foreign handler (the original action: ASan's report, or death by SIGBUS), not come
// back to the guard for ever nor skip the original: CI's ASan run lost ASan's report when
// the guard forgot the original handler for the foreign one.
struct sigaction g_replaced_by_foreign;
std::atomic<int> g_foreign_calls{0};
void ForeignHandlerThatReturns(int) {
  g_foreign_calls.fetch_add(1);
  sigaction(SIGBUS, &g_replaced_by_foreign, nullptr);
}

TEST_F(SigbusGuardTest, AForeignHandlerThatReturnsLeavesTheFaultToTheOriginalAction) {
  server::SigbusGuard::Install();
  const std::string path = MakeFile(dir_, "unguarded");
  const auto scenario = [&path] {
    struct sigaction foreign = {};
    foreign.sa_handler = &ForeignHandlerThatReturns;
    sigemptyset(&foreign.sa_mask);
    sigaction(SIGBUS, &foreign, &g_replaced_by_foreign);  // over the guard's, as LLVM does
    server::SigbusGuard::Install();
    const int fd = open(path.c_str(), O_RDWR);
    auto* bytes =
        static_cast<char*>(mmap(nullptr, kBytes, PROT_READ | PROT_WRITE, MAP_SHARED, fd, 0));
    if (ftruncate(fd, 0) != 0) std::_Exit(3);
    bytes[0] = 1;  // outside every region: foreign handler, then the original action
    std::_Exit(g_foreign_calls.load() == 1 ? 0 : 10 + g_foreign_calls.load());
  };
  if (kBuiltWithAsan) {
    EXPECT_EXIT(scenario(), ::testing::ExitedWithCode(1), "AddressSanitizer: BUS");
  } else {
    EXPECT_EXIT(scenario(), ::testing::KilledBySignal(SIGBUS), "");
  }
}

}  // namespace
}  // namespace skinserve::testing
