// OwnedRegions on its own: names checked, each limit refused by name and counted, a
// reservation that holds its name and bytes until released, and regions that exist for their
// owner alone (found, acquired, listed and removed by the owner's id only). The registries
// built on it are tested in region_registry_test.cpp and tests/gpu/gpu_region_registry_test.cpp.
#include "shm/owned_regions.h"

#include <gtest/gtest.h>

#include <memory>
#include <string>

#include "expect_status.h"

namespace skinserve::testing {
namespace {

using server::OwnedRegionLimits;
using server::OwnedRegions;
using server::RegionOwner;
using server::RegionWords;

// The little a region needs here: a name, and the clock of its last use.
struct FakeRegion {
  std::string name;
  int64_t last_used_ns = 0;
  void Touch(int64_t now_ns) { last_used_ns = now_ns; }
};

constexpr RegionWords kWords{.kind = "test region",
                             .max_regions = "--test-max-regions",
                             .budget = "--test-budget-mb",
                             .held = "held"};

class OwnedRegionsTest : public ::testing::Test {
 protected:
  static constexpr uint64_t kMiB = uint64_t{1} << 20;
  OwnedRegions<FakeRegion> regions_{
      kWords, {.budget_bytes = 4 * kMiB, .max_regions = 3, .max_per_owner = 2, .idle_seconds = 9}};
  RegionOwner alice_{.id = "uid 1 pid 1"};
  RegionOwner bob_{.id = "uid 2 pid 2"};

  // Reserves and enters a region, as a registry does once it is set up.
  void Add(const RegionOwner& owner, const std::string& name, uint64_t bytes) {
    ASSERT_TRUE(regions_.Reserve(name, bytes, owner).ok());
    regions_.Enter(owner, name, std::make_shared<FakeRegion>(FakeRegion{name}));
  }
};

TEST_F(OwnedRegionsTest, NamesAreCheckedByTheirRules) {
  EXPECT_TRUE(regions_.CheckName("skin-1.a_B").ok());
  ExpectStatus(regions_.CheckName(""), StatusCode::kInvalidArgument, "test region name ''");
  ExpectStatus(regions_.CheckName("a/b"), StatusCode::kInvalidArgument, "[A-Za-z0-9._-]");
  ExpectStatus(regions_.CheckName(std::string(65, 'a')), StatusCode::kInvalidArgument, "1-64");
  EXPECT_TRUE(regions_.CheckName(std::string(64, 'a')).ok());
}

TEST_F(OwnedRegionsTest, EachLimitIsRefusedByItsOptionAndCounted) {
  Add(alice_, "a", kMiB);
  ExpectStatus(regions_.Reserve("a", kMiB, alice_), StatusCode::kAlreadyExists,
               "has a test region named 'a' already");
  EXPECT_EQ(regions_.rejected(), 0u);  // a name in use is not a limit
  ExpectStatus(regions_.Reserve("big", 3 * kMiB + 1, alice_), StatusCode::kResourceExhausted,
               "--test-budget-mb = 4 MiB");
  Add(alice_, "b", kMiB);
  ExpectStatus(regions_.Reserve("c", kMiB, alice_), StatusCode::kResourceExhausted,
               "--shm-max-regions-per-connection = 2");
  Add(bob_, "a", kMiB);  // the same name, another owner's
  ExpectStatus(regions_.Reserve("d", 1, bob_), StatusCode::kResourceExhausted,
               "--test-max-regions = 3");
  EXPECT_EQ(regions_.rejected(), 3u);
  EXPECT_EQ(regions_.bytes(), 3 * kMiB);
}

TEST_F(OwnedRegionsTest, AReservationHoldsItsNameAndBytesUntilReleased) {
  ASSERT_TRUE(regions_.Reserve("pending", 3 * kMiB, alice_).ok());
  EXPECT_EQ(regions_.bytes(), 3 * kMiB);
  // Reserved, not there yet: not found, acquired or listed; but its name and bytes are taken.
  EXPECT_EQ(regions_.FindToRemove("pending", alice_).status().code(), StatusCode::kNotFound);
  EXPECT_EQ(regions_.Acquire("pending", alice_, 1).status().code(),
            StatusCode::kFailedPrecondition);
  EXPECT_TRUE(regions_.List(alice_, [](const FakeRegion& r) { return r.name; }).empty());
  EXPECT_EQ(regions_.Reserve("pending", 1, alice_).code(), StatusCode::kAlreadyExists);
  EXPECT_EQ(regions_.Reserve("more", 2 * kMiB, bob_).code(), StatusCode::kResourceExhausted);
  regions_.Release(alice_, "pending", 3 * kMiB);  // its setup failed
  EXPECT_EQ(regions_.bytes(), 0u);
  Add(bob_, "more", 2 * kMiB);
  Add(alice_, "pending", kMiB);  // the name is free again, and alice's count back to 0
  Add(alice_, "second", kMiB);
  EXPECT_EQ(regions_.bytes(), 4 * kMiB);
}

TEST_F(OwnedRegionsTest, RegionsExistForTheirOwnerAlone) {
  Add(alice_, "mine", kMiB);
  Add(alice_, "also", kMiB);
  Add(bob_, "other", kMiB);
  ExpectStatus(regions_.Acquire("mine", bob_, 5).status(), StatusCode::kFailedPrecondition,
               "this client has no test region named 'mine' (never registered, unregistered, or "
               "idle for --shm-idle-seconds = 9)");
  EXPECT_EQ(regions_.FindToRemove("mine", bob_).status().code(), StatusCode::kNotFound);
  const auto names = [](const FakeRegion& r) { return r.name; };
  EXPECT_EQ(regions_.List(alice_, names), (std::vector<std::string>{"also", "mine"}));
  EXPECT_EQ(regions_.List(bob_, names), (std::vector<std::string>{"other"}));
  auto acquired = regions_.Acquire("mine", alice_, 42);
  ASSERT_TRUE(acquired.ok());
  EXPECT_EQ((*acquired)->last_used_ns, 42);  // acquiring is use
  auto found = regions_.FindToRemove("mine", alice_);
  ASSERT_TRUE(found.ok());
  regions_.Release(*found, kMiB);
  EXPECT_EQ(regions_.Acquire("mine", alice_, 43).status().code(), StatusCode::kFailedPrecondition);
  EXPECT_EQ(regions_.List(alice_, names), (std::vector<std::string>{"also"}));
  EXPECT_EQ(regions_.bytes(), 2 * kMiB);
  EXPECT_EQ((*acquired)->name, "mine");  // a holder keeps its region after the removal
}

}  // namespace
}  // namespace skinserve::testing
