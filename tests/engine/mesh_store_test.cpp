#include "mesh_store.h"

#include <gtest/gtest.h>

#include "skinserve/reference/synthetic.h"

namespace skinserve {
namespace {

std::shared_ptr<const Mesh> MeshWithSeed(uint64_t seed) {
  return Mesh::Create(MakeSyntheticMesh({.vertex_count = 100, .influences = 1, .seed = seed}))
      .value();
}

constexpr uint64_t kMeshBytes = 100 * (12 + 6);

TEST(MeshStoreTest, StoresOnceByContent) {
  MeshStore store(10 * kMeshBytes, 1);
  bool already = true;
  ASSERT_TRUE(store.Insert(MeshWithSeed(1), &already).ok());
  EXPECT_FALSE(already);
  ASSERT_TRUE(store.Insert(MeshWithSeed(1), &already).ok());
  EXPECT_TRUE(already);
  EXPECT_EQ(store.count(), 1u);
  EXPECT_EQ(store.bytes(), kMeshBytes);
}

TEST(MeshStoreTest, EvictsLeastRecentlyUsedFirst) {
  MeshStore store(2 * kMeshBytes, 1);
  bool already;
  auto a = MeshWithSeed(1), b = MeshWithSeed(2), c = MeshWithSeed(3);
  ASSERT_TRUE(store.Insert(a, &already).ok());
  ASSERT_TRUE(store.Insert(b, &already).ok());
  ASSERT_NE(store.Acquire(a->id()), nullptr);  // a is now more recent than b
  ASSERT_TRUE(store.Insert(c, &already).ok());
  EXPECT_NE(store.Acquire(a->id()), nullptr);
  EXPECT_EQ(store.Acquire(b->id()), nullptr);
  EXPECT_NE(store.Acquire(c->id()), nullptr);
  EXPECT_EQ(store.evictions(), 1u);
}

// A kept plan (Engine::Reuse) uses a mesh without Acquire: MarkUsed makes it count as
// recently used at the next eviction, and an entry knows when it left the store.
TEST(MeshStoreTest, AMeshUsedThroughAKeptPlanCountsAsRecentlyUsed) {
  MeshStore store(2 * kMeshBytes, 1);
  bool already;
  auto a = MeshWithSeed(1), b = MeshWithSeed(2), c = MeshWithSeed(3);
  ASSERT_TRUE(store.Insert(a, &already).ok());
  std::weak_ptr<MeshStore::Entry> kept = store.Acquire(a->id());  // as a kept plan holds it
  ASSERT_TRUE(store.Insert(b, &already).ok());                    // b is more recent than a
  {
    const MeshStore::Lease used = kept.lock();  // a frame reused a's plan
    ASSERT_NE(used, nullptr);
    used->MarkUsed();
  }
  ASSERT_TRUE(store.Insert(c, &already).ok());
  EXPECT_NE(store.Acquire(a->id()), nullptr) << "the mesh a kept plan used was evicted";
  EXPECT_EQ(store.Acquire(b->id()), nullptr);
  MeshStore::Lease pinned = store.Acquire(c->id());
  EXPECT_TRUE(pinned->stored());
  ASSERT_TRUE(store.Erase(c->id()));
  EXPECT_FALSE(pinned->stored()) << "an erased entry a frame still pins says it is stored";
}

TEST(MeshStoreTest, NeverEvictsAPinnedMesh) {
  MeshStore store(kMeshBytes, 1);
  bool already;
  auto a = MeshWithSeed(1);
  ASSERT_TRUE(store.Insert(a, &already).ok());
  MeshStore::Lease pinned = store.Acquire(a->id());
  Status s = store.Insert(MeshWithSeed(2), &already);
  EXPECT_EQ(s.code(), StatusCode::kResourceExhausted) << s.ToString();
  EXPECT_NE(s.message().find("held by meshes in use"), std::string::npos) << s.message();
  pinned.reset();
  EXPECT_TRUE(store.Insert(MeshWithSeed(2), &already).ok());
  EXPECT_EQ(store.Acquire(a->id()), nullptr);
}

TEST(MeshStoreTest, RefusesAMeshLargerThanTheBudget) {
  MeshStore store(kMeshBytes - 1, 1);
  bool already;
  EXPECT_EQ(store.Insert(MeshWithSeed(1), &already).code(), StatusCode::kResourceExhausted);
  EXPECT_EQ(store.CheckFits(kMeshBytes).code(), StatusCode::kResourceExhausted);
  EXPECT_EQ(store.count(), 0u);
  EXPECT_EQ(store.bytes(), 0u);
}

TEST(MeshStoreTest, EraseKeepsAPinnedEntryAliveForItsHolder) {
  MeshStore store(10 * kMeshBytes, 1);
  bool already;
  auto a = MeshWithSeed(1);
  ASSERT_TRUE(store.Insert(a, &already).ok());
  MeshStore::Lease pinned = store.Acquire(a->id());
  EXPECT_TRUE(store.Erase(a->id()));
  EXPECT_FALSE(store.Erase(a->id()));
  EXPECT_EQ(store.Acquire(a->id()), nullptr);
  EXPECT_EQ(pinned->mesh()->vertex_count(), 100u);
  EXPECT_EQ(store.bytes(), 0u);
}

}  // namespace
}  // namespace skinserve
