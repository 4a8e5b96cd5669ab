// MeshAssembly on its own (no gRPC): memory is taken as chunks arrive, never for what a
// header declares; every growth is charged to the upload budget first; a refusal takes
// nothing and names the budget; the charge returns when the assembly stores, fails or is
// dropped.
#include "rpc/mesh_assembly.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cstring>

#include "rpc/open_uploads.h"
#include "skinserve/reference/synthetic.h"

namespace skinserve::testing {
namespace {

std::unique_ptr<Engine> SerialEngine() {
  EngineOptions options;
  options.compute_threads = 1;
  options.enabled_backends = {"serial"};
  auto engine = Engine::Create(options);
  EXPECT_TRUE(engine.ok()) << engine.status().ToString();
  return std::move(engine).value();
}

v1::UploadMeshRequest Header(uint32_t vertices, uint32_t influences, bool normals) {
  v1::UploadMeshRequest message;
  message.mutable_header()->set_vertex_count(vertices);
  message.mutable_header()->set_influences(influences);
  message.mutable_header()->set_joint_count(77);
  message.mutable_header()->set_has_normals(normals);
  return message;
}

template <typename T>
v1::UploadMeshRequest Chunk(v1::MeshArray array, const std::vector<T>& values, std::size_t offset,
                            std::size_t count) {
  v1::UploadMeshRequest message;
  message.mutable_chunk()->set_array(array);
  message.mutable_chunk()->set_offset(offset);
  message.mutable_chunk()->set_data(values.data() + offset, count * sizeof(T));
  return message;
}

// Every chunk of `arrays`, `per_chunk` values at most, array after array.
std::vector<v1::UploadMeshRequest> Chunks(const MeshArrays& arrays, std::size_t per_chunk) {
  std::vector<v1::UploadMeshRequest> chunks;
  auto add = [&](v1::MeshArray kind, const auto& values) {
    for (std::size_t offset = 0; offset < values.size(); offset += per_chunk) {
      chunks.push_back(Chunk(kind, values, offset, std::min(per_chunk, values.size() - offset)));
    }
  };
  add(v1::MESH_ARRAY_POSITIONS, arrays.positions);
  add(v1::MESH_ARRAY_NORMALS, arrays.normals);
  add(v1::MESH_ARRAY_JOINTS, arrays.joints);
  add(v1::MESH_ARRAY_WEIGHTS, arrays.weights);
  return chunks;
}

TEST(MeshAssemblyTest, AHeaderAloneTakesAndChargesNothing) {
  auto engine = SerialEngine();
  server::InflightBudget budget(64 << 20, server::kUploadBudgetWording);
  server::MeshAssembly assembly(engine.get(), &budget);
  // The attack of issue 27: 4M vertices, 8 influences and normals declared (288 MB).
  ASSERT_TRUE(assembly.Accept(Header(4'000'000, 8, true)).ok());
  EXPECT_EQ(assembly.charged_bytes(), 0u);
  EXPECT_EQ(budget.used(), 0u);
}

TEST(MeshAssemblyTest, AnEmptyChunkTakesNothing) {
  auto engine = SerialEngine();
  server::InflightBudget budget(64 << 20, server::kUploadBudgetWording);
  server::MeshAssembly assembly(engine.get(), &budget);
  ASSERT_TRUE(assembly.Accept(Header(1000, 2, false)).ok());
  ASSERT_TRUE(assembly.Accept(Chunk(v1::MESH_ARRAY_POSITIONS, std::vector<float>(), 0, 0)).ok());
  EXPECT_EQ(assembly.charged_bytes(), 0u);
}

// Progress (what resets an upload's idle clock, issue 42): the header and array bytes; not
// an empty chunk, nor a message refused.
TEST(MeshAssemblyTest, ProgressIsTheHeaderAndArrayBytesNotEmptyChunks) {
  auto engine = SerialEngine();
  server::MeshAssembly assembly(engine.get());
  const std::vector<float> positions(3000, 0.5f);
  EXPECT_EQ(assembly.progress(), 0u);
  ASSERT_TRUE(assembly.Accept(Header(1000, 2, false)).ok());
  const uint64_t after_header = assembly.progress();
  EXPECT_GT(after_header, 0u);
  for (int i = 0; i < 3; ++i) {
    ASSERT_TRUE(assembly.Accept(Chunk(v1::MESH_ARRAY_POSITIONS, positions, 0, 0)).ok());
  }
  EXPECT_EQ(assembly.progress(), after_header) << "empty chunks are no progress";
  EXPECT_FALSE(assembly.Accept(Header(1000, 2, false)).ok()) << "a second header is refused";
  EXPECT_EQ(assembly.progress(), after_header);
  ASSERT_TRUE(assembly.Accept(Chunk(v1::MESH_ARRAY_POSITIONS, positions, 0, 3)).ok());
  EXPECT_EQ(assembly.progress(), after_header + 3 * sizeof(float));
}

TEST(MeshAssemblyTest, ArraysGrowWithTheirChunksAndAreChargedAsTheyGrow) {
  auto engine = SerialEngine();
  const MeshArrays arrays =
      MakeSyntheticMesh({.vertex_count = 20'000, .influences = 3, .normals = true, .seed = 5});
  const uint64_t mesh_bytes = MeshByteSize(20'000, 3, true);
  server::InflightBudget budget(64 << 20, server::kUploadBudgetWording);
  server::MeshAssembly assembly(engine.get(), &budget);
  ASSERT_TRUE(assembly.Accept(Header(20'000, 3, true)).ok());
  uint64_t received = 0, previous_charge = 0;
  for (const v1::UploadMeshRequest& chunk : Chunks(arrays, 1000)) {
    ASSERT_TRUE(assembly.Accept(chunk).ok());
    received += chunk.chunk().data().size();
    // The charge is what the arrays hold: never less than received, at most twice that
    // (doubling), never beyond the declared mesh, and it never shrinks mid-upload.
    EXPECT_EQ(budget.used(), assembly.charged_bytes());
    EXPECT_GE(assembly.charged_bytes(), received);
    EXPECT_LE(assembly.charged_bytes(), 2 * received);
    EXPECT_LE(assembly.charged_bytes(), mesh_bytes);
    EXPECT_GE(assembly.charged_bytes(), previous_charge);
    previous_charge = assembly.charged_bytes();
  }
  EXPECT_EQ(received, mesh_bytes);
  EXPECT_EQ(assembly.charged_bytes(), mesh_bytes) << "a complete array holds no spare room";

  auto info = assembly.Store();
  ASSERT_TRUE(info.ok()) << info.status().ToString();
  EXPECT_EQ(info->id, Mesh::Create(arrays).value()->id()) << "the mesh stored is the one sent";
  EXPECT_EQ(budget.used(), 0u) << "storing returns the upload's charge";
  EXPECT_EQ(assembly.charged_bytes(), 0u);
}

TEST(MeshAssemblyTest, AChunkBeyondTheBudgetIsRefusedNamingItAndTakesNothing) {
  auto engine = SerialEngine();
  const MeshArrays arrays = MakeSyntheticMesh({.vertex_count = 100'000, .influences = 4});
  server::InflightBudget budget(1 << 20, server::kUploadBudgetWording);  // 1 MiB
  ASSERT_TRUE(budget.TryCharge(256 << 10).ok());                         // another upload's 256 KiB
  server::MeshAssembly assembly(engine.get(), &budget);
  ASSERT_TRUE(assembly.Accept(Header(100'000, 4, false)).ok());
  Status refused;
  uint64_t charged_before = 0;
  for (const v1::UploadMeshRequest& chunk : Chunks(arrays, 64 << 10)) {
    charged_before = assembly.charged_bytes();
    refused = assembly.Accept(chunk);
    if (!refused.ok()) break;
  }
  ASSERT_EQ(refused.code(), StatusCode::kResourceExhausted) << refused.ToString();
  EXPECT_NE(refused.message().find("--upload-budget-mb"), std::string::npos) << refused.message();
  EXPECT_EQ(assembly.charged_bytes(), charged_before) << "the refused chunk took nothing";
  EXPECT_EQ(budget.used(), (256u << 10) + charged_before);
  EXPECT_LE(budget.used(), budget.limit());
  EXPECT_EQ(budget.refused(), 1u);

  assembly.Discard();
  EXPECT_EQ(budget.used(), 256u << 10) << "discarding returns the upload's charge";
  EXPECT_EQ(engine->Stats().meshes, 0u);
}

TEST(MeshAssemblyTest, ATruncatedUploadStoresNothingAndReturnsItsCharge) {
  auto engine = SerialEngine();
  const MeshArrays arrays = MakeSyntheticMesh({.vertex_count = 5'000});
  server::InflightBudget budget(64 << 20, server::kUploadBudgetWording);
  server::MeshAssembly assembly(engine.get(), &budget);
  ASSERT_TRUE(assembly.Accept(Header(5'000, 2, false)).ok());
  ASSERT_TRUE(assembly.Accept(Chunk(v1::MESH_ARRAY_POSITIONS, arrays.positions, 0, 15'000)).ok());
  EXPECT_GT(budget.used(), 0u);
  auto info = assembly.Store();
  EXPECT_EQ(info.status().code(), StatusCode::kInvalidArgument);
  EXPECT_NE(info.status().message().find("truncated"), std::string::npos)
      << info.status().message();
  EXPECT_EQ(budget.used(), 0u);
  EXPECT_EQ(engine->Stats().meshes, 0u);
}

TEST(MeshAssemblyTest, DroppingAnAssemblyReturnsItsCharge) {
  auto engine = SerialEngine();
  const MeshArrays arrays = MakeSyntheticMesh({.vertex_count = 5'000});
  server::InflightBudget budget(64 << 20, server::kUploadBudgetWording);
  {
    server::MeshAssembly assembly(engine.get(), &budget);
    ASSERT_TRUE(assembly.Accept(Header(5'000, 2, false)).ok());
    ASSERT_TRUE(assembly.Accept(Chunk(v1::MESH_ARRAY_JOINTS, arrays.joints, 0, 4'000)).ok());
    EXPECT_EQ(budget.used(), 4'000u * sizeof(uint16_t));
  }
  EXPECT_EQ(budget.used(), 0u);
}

}  // namespace
}  // namespace skinserve::testing
