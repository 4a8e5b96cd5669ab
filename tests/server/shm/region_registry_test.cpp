// RegionRegistry on its own (no server): what a registration maps and who sees it, an
// unregister while a frame still holds the region, the budget and the counts, and refusals
// that name the field or the option and leave nothing half-registered. The RPCs around it
// are tests/server/shared_memory_test.cpp's and tests/security/region_owners_test.cpp's.
#include "shm/region_registry.h"

#include <fcntl.h>
#include <sys/mman.h>
#include <sys/resource.h>
#include <unistd.h>

#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <thread>
#include <vector>

#include "expect_status.h"
#include "shm/sigbus_guard.h"

namespace skinserve::testing {
namespace {

using server::RegionLimits;
using server::RegionOwner;
using server::RegionRegistry;

constexpr uint64_t kMiB = uint64_t{1} << 20;

class RegionRegistryTest : public ::testing::Test {
 protected:
  void SetUp() override {
    char name[] = "/dev/shm/skinserve-registry-XXXXXX";
    ASSERT_NE(mkdtemp(name), nullptr);
    dir_ = name;
  }
  void TearDown() override {
    registry_.reset();
    std::filesystem::remove_all(dir_);
  }
  void Create(RegionLimits limits) {
    limits.dir = dir_;
    auto registry = RegionRegistry::Create(limits);
    ASSERT_TRUE(registry.ok()) << registry.status().ToString();
    registry_ = std::move(registry).value();
  }
  // A file of `bytes` in the directory (sparse: nothing is written).
  void MakeFile(const std::string& file, uint64_t bytes) {
    const int fd = open((dir_ + "/" + file).c_str(), O_RDWR | O_CREAT | O_TRUNC, 0600);
    ASSERT_GE(fd, 0);
    ASSERT_EQ(ftruncate(fd, static_cast<off_t>(bytes)), 0);
    close(fd);
  }
  // Nothing is held: every refusal above gave back what it had reserved.
  void ExpectEmpty() {
    const server::RegionStats stats = registry_->Stats();
    EXPECT_EQ(stats.regions, 0u);
    EXPECT_EQ(stats.mapped_bytes, 0u);
    EXPECT_TRUE(registry_->List(alice_).empty());
  }

  std::string dir_;
  std::unique_ptr<RegionRegistry> registry_;
  RegionOwner alice_{.id = "uid test pid 1", .file_uid = getuid()};
  RegionOwner bob_{.id = "uid test pid 2", .file_uid = getuid()};
};

TEST_F(RegionRegistryTest, ARegisteredRegionMapsItsFileAndIsListedAndCounted) {
  Create({.budget_bytes = 4 * kMiB});
  MakeFile("a.bin", 2 * kMiB);  // the file may be larger than the region
  auto info = registry_->Register("a", "/a.bin", kMiB, alice_);
  ASSERT_TRUE(info.ok()) << info.status().ToString();
  EXPECT_EQ(info->name, "a");
  EXPECT_EQ(info->key, "a.bin");
  EXPECT_EQ(info->byte_size, kMiB);

  auto region = registry_->Acquire("a", alice_);
  ASSERT_TRUE(region.ok()) << region.status().ToString();
  ASSERT_EQ((*region)->bytes().size(), kMiB);
  // The mapping is the file's own bytes, shared: what the server writes the client reads.
  const char text[] = "written through the mapping";
  std::memcpy((*region)->bytes().data() + 4096, text, sizeof text);
  char back[sizeof text] = {};
  const int fd = open((dir_ + "/a.bin").c_str(), O_RDONLY);
  ASSERT_GE(fd, 0);
  ASSERT_EQ(pread(fd, back, sizeof back, 4096), static_cast<ssize_t>(sizeof back));
  close(fd);
  EXPECT_STREQ(back, text);

  (*region)->CountFrame();
  const auto listed = registry_->List(alice_);
  ASSERT_EQ(listed.size(), 1u);
  EXPECT_EQ(listed[0].name, "a");
  EXPECT_EQ(listed[0].frames_written, 1u);
  const server::RegionStats stats = registry_->Stats();
  EXPECT_EQ(stats.regions, 1u);
  EXPECT_EQ(stats.mapped_bytes, kMiB);
  EXPECT_EQ(stats.budget_bytes, 4 * kMiB);
  EXPECT_EQ(stats.frames, 1u);
}

// The registration maps the region's pages in (MAP_POPULATE), so a stream's first frames take
// no page faults writing it: each costs this VM 15-18 us.
TEST_F(RegionRegistryTest, ARegionsPagesAreMappedInWhenItIsRegistered) {
  Create({.budget_bytes = 4 * kMiB});
  MakeFile("a.bin", kMiB);  // sparse: no page of it exists before the registration
  ASSERT_TRUE(registry_->Register("a", "/a.bin", kMiB, alice_).ok());
  auto region = registry_->Acquire("a", alice_);
  ASSERT_TRUE(region.ok()) << region.status().ToString();
  const std::span<std::byte> bytes = (*region)->bytes();
  const std::size_t page = static_cast<std::size_t>(sysconf(_SC_PAGESIZE));
  std::vector<unsigned char> resident(bytes.size() / page);
  ASSERT_EQ(mincore(bytes.data(), bytes.size(), resident.data()), 0) << std::strerror(errno);
  EXPECT_EQ(std::count_if(resident.begin(), resident.end(), [](unsigned char r) { return r & 1; }),
            static_cast<std::ptrdiff_t>(resident.size()))
      << "pages of the region not resident after its registration";
  rusage before = {}, after = {};
  ASSERT_EQ(getrusage(RUSAGE_THREAD, &before), 0);
  std::memset(bytes.data(), 1, bytes.size());  // a frame's writes
  ASSERT_EQ(getrusage(RUSAGE_THREAD, &after), 0);
  // Unpopulated, each of the 256 pages faults once. Populated, none does; under AddressSanitizer
  // its shadow of the region faults in, a page per 8 of the region's (32 here).
  EXPECT_LT(after.ru_minflt - before.ru_minflt, static_cast<long>(resident.size() / 4))
      << "of " << resident.size() << " pages";
}

TEST_F(RegionRegistryTest, ARegionIsItsOwnersOnlyAndAFileIsRegisteredOnce) {
  Create({.budget_bytes = 8 * kMiB});
  MakeFile("a.bin", kMiB);
  MakeFile("b.bin", kMiB);
  ASSERT_TRUE(registry_->Register("r", "a.bin", kMiB, alice_).ok());

  // To anyone else it does not exist: not listed, not acquired, not unregistered.
  EXPECT_TRUE(registry_->List(bob_).empty());
  ExpectStatus(registry_->Acquire("r", bob_).status(), StatusCode::kFailedPrecondition,
               "no region named 'r'");
  ExpectStatus(registry_->Unregister("r", bob_, nullptr), StatusCode::kNotFound,
               "no region named 'r'");
  EXPECT_TRUE(registry_->Acquire("r", alice_).ok()) << "another owner's call took it";

  // Each owner names its regions as it likes; one name is one region of an owner.
  EXPECT_TRUE(registry_->Register("r", "b.bin", kMiB, bob_).ok());
  EXPECT_EQ((*registry_->Acquire("r", bob_))->key(), "b.bin");
  EXPECT_EQ((*registry_->Acquire("r", alice_))->key(), "a.bin");
  ExpectStatus(registry_->Register("r", "b.bin", kMiB, alice_).status(), StatusCode::kAlreadyExists,
               "has a region named 'r' already");
  // A file is one registration, whoever asks and under whatever name.
  ExpectStatus(registry_->Register("s", "a.bin", kMiB, bob_).status(), StatusCode::kAlreadyExists,
               "one registration per file");
  ExpectStatus(registry_->Register("s", "/a.bin", kMiB, alice_).status(),
               StatusCode::kAlreadyExists, "one registration per file");
  EXPECT_EQ(registry_->Stats().regions, 2u);
  EXPECT_EQ(registry_->Stats().mapped_bytes, 2 * kMiB);
}

TEST_F(RegionRegistryTest, AnUnregisterWhileAFrameHoldsTheRegionUnmapsItWhenTheFrameLetsGo) {
  Create({.budget_bytes = kMiB});
  MakeFile("a.bin", kMiB);
  ASSERT_TRUE(registry_->Register("a", "a.bin", kMiB, alice_).ok());
  auto held = registry_->Acquire("a", alice_);  // a frame writing into it
  ASSERT_TRUE(held.ok());
  bool unmapped = false;
  ASSERT_TRUE(registry_->Unregister("a", alice_, [&] { unmapped = true; }).ok());
  EXPECT_FALSE(unmapped) << "unmapped under a frame that still writes into it";
  EXPECT_TRUE((*held)->removed());
  // Gone for every new frame at once, and its name, file and bytes are free again.
  ExpectStatus(registry_->Acquire("a", alice_).status(), StatusCode::kFailedPrecondition,
               "no region named 'a'");
  ExpectEmpty();
  ExpectStatus(registry_->Unregister("a", alice_, nullptr), StatusCode::kNotFound,
               "no region named 'a'");
  held->reset();  // the frame is done
  EXPECT_TRUE(unmapped);
  EXPECT_TRUE(registry_->Register("a", "a.bin", kMiB, alice_).ok());

  // With no frame holding it, the unmap is at once, on the caller's thread.
  bool at_once = false;
  ASSERT_TRUE(registry_->Unregister("a", alice_, [&] { at_once = true; }).ok());
  EXPECT_TRUE(at_once);
}

TEST_F(RegionRegistryTest, TheBudgetAndTheCountsAreRefusedNamingTheOptionAndGivenBackOnUnregister) {
  Create({.budget_bytes = 3 * kMiB, .max_regions = 3, .max_per_connection = 2});
  for (const char* file : {"a", "b", "c", "d"}) MakeFile(file, 2 * kMiB);
  ASSERT_TRUE(registry_->Register("a", "a", kMiB, alice_).ok());
  ASSERT_TRUE(registry_->Register("b", "b", kMiB, alice_).ok());
  ExpectStatus(registry_->Register("c", "c", kMiB, alice_).status(), StatusCode::kResourceExhausted,
               "--shm-max-regions-per-connection = 2");
  ExpectStatus(registry_->Register("c", "c", 2 * kMiB, bob_).status(),
               StatusCode::kResourceExhausted, "beyond --shm-budget-mb = 3 MiB");
  ASSERT_TRUE(registry_->Register("c", "c", kMiB, bob_).ok());  // exactly the budget
  ExpectStatus(registry_->Register("d", "d", 1, bob_).status(), StatusCode::kResourceExhausted,
               "--shm-max-regions = 3");
  EXPECT_EQ(registry_->Stats().rejected, 3u);
  EXPECT_EQ(registry_->Stats().mapped_bytes, 3 * kMiB);

  // An unregister gives its bytes and its place back.
  ASSERT_TRUE(registry_->Unregister("a", alice_, nullptr).ok());
  EXPECT_EQ(registry_->Stats().mapped_bytes, 2 * kMiB);
  EXPECT_TRUE(registry_->Register("d", "d", kMiB, alice_).ok());
}

TEST_F(RegionRegistryTest, BadNamesKeysSizesAndFilesAreRefusedNamingTheFieldAndHoldNothing) {
  Create({.budget_bytes = 4 * kMiB});
  MakeFile("a.bin", kMiB);
  ExpectStatus(registry_->Register("", "a.bin", kMiB, alice_).status(),
               StatusCode::kInvalidArgument, "is not 1-64 characters of [A-Za-z0-9._-]");
  ExpectStatus(registry_->Register("a/b", "a.bin", kMiB, alice_).status(),
               StatusCode::kInvalidArgument, "region name 'a/b'");
  ExpectStatus(registry_->Register(std::string(65, 'x'), "a.bin", kMiB, alice_).status(),
               StatusCode::kInvalidArgument, "1-64 characters");
  for (const char* key : {"", "/", "..", "../a.bin", "sub/a.bin"}) {
    ExpectStatus(registry_->Register("a", key, kMiB, alice_).status(), StatusCode::kInvalidArgument,
                 "must name one file inside the server's --shm-dir");
  }
  ExpectStatus(registry_->Register("a", "a.bin", 0, alice_).status(), StatusCode::kInvalidArgument,
               "byte_size must be above 0");
  ExpectStatus(registry_->Register("a", "a.bin", kMiB + 1, alice_).status(),
               StatusCode::kInvalidArgument, "fewer than byte_size = 1048577");
  ExpectStatus(registry_->Register("a", "missing.bin", kMiB, alice_).status(),
               StatusCode::kInvalidArgument, "key 'missing.bin'");
  RegionOwner stranger = alice_;
  stranger.file_uid = getuid() + 1;  // the file is not this owner's
  ExpectStatus(registry_->Register("a", "a.bin", kMiB, stranger).status(),
               StatusCode::kPermissionDenied, "is owned by uid");
  ExpectEmpty();
  EXPECT_EQ(registry_->Stats().rejected, 0u) << "only limits count as rejected";
  // The name and the file were not kept by the failures.
  EXPECT_TRUE(registry_->Register("a", "a.bin", kMiB, alice_).ok());
}

TEST_F(RegionRegistryTest, ARemoteOwnerLearnsNothingAboutTheFilesButLimitsAreNamed) {
  Create({.budget_bytes = 2 * kMiB});
  MakeFile("a.bin", kMiB);
  RegionOwner remote{.id = "certificate spiffe://test/1", .file_uid = getuid(), .remote = true};
  const Status missing = registry_->Register("a", "missing.bin", kMiB, remote).status();
  const Status small = registry_->Register("a", "a.bin", 2 * kMiB, remote).status();
  EXPECT_EQ(missing.code(), StatusCode::kInvalidArgument);
  EXPECT_EQ(small.code(), StatusCode::kInvalidArgument);
  // One answer for a missing file and a short one, but for the key it names.
  EXPECT_NE(missing.message().find("does not say which of these failed"), std::string::npos)
      << missing.message();
  EXPECT_EQ(small.message().find("holds"), std::string::npos) << small.message();
  ExpectEmpty();
  ASSERT_TRUE(registry_->Register("a", "a.bin", kMiB, remote).ok());
  MakeFile("b.bin", 2 * kMiB);
  ExpectStatus(registry_->Register("b", "b.bin", 2 * kMiB, remote).status(),
               StatusCode::kResourceExhausted, "--shm-budget-mb");
}

TEST_F(RegionRegistryTest, ARegionNoFrameNamesForTheIdleTimeIsUnregistered) {
  Create({.budget_bytes = 2 * kMiB, .idle_seconds = 0.2});
  MakeFile("a.bin", kMiB);
  ASSERT_TRUE(registry_->Register("a", "a.bin", kMiB, alice_).ok());
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(10);
  while (!registry_->List(alice_).empty() && std::chrono::steady_clock::now() < deadline) {
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  ExpectStatus(registry_->Acquire("a", alice_).status(), StatusCode::kFailedPrecondition,
               "--shm-idle-seconds = 0.2");
  ExpectEmpty();
}

TEST_F(RegionRegistryTest, CreateRefusesAMissingDirectoryAndTooManyRegionsNamingTheOption) {
  auto missing = RegionRegistry::Create({.dir = dir_ + "/missing"});
  ExpectStatus(missing.status(), StatusCode::kInvalidArgument, "--shm-dir '" + dir_ + "/missing'");
  RegionLimits many{.dir = dir_};
  many.max_regions = server::SigbusGuard::kMaxRanges + 1;
  ExpectStatus(RegionRegistry::Create(many).status(), StatusCode::kInvalidArgument,
               "--shm-max-regions = 4097");
}

}  // namespace
}  // namespace skinserve::testing
