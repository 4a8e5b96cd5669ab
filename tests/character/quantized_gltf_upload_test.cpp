// A glTF file picks its own rest encoding (issue 29 item 1: "taken from a quantized glTF"):
// the importer records how the file stored POSITION, NORMAL and WEIGHTS_n
// (SkinnedPrimitive::stored), RestEncodingFromFile turns that into an encoding, and
// skinserve-load's glTF workload (ChooseRestEncoding) uses it unless the user asked for one.
// Through a real server on loopback: the KHR_mesh_quantization character (test_scenes.h's
// Quantized, 16-bit positions, uint8/uint16 weights) is stored quantized and every answer
// lies within the bound of docs/backends/quantized-rest.md#error of the float64 result on the
// glTF's dequantized floats (CheckQuantized: half a position step through the blended
// matrix, one weight step per stored weight, plus float32 rounding), and within float32
// rounding of the result on the values the stream decodes to; a float file stays float32;
// an explicit float32 on the quantized file stays float32.
#include <gtest/gtest.h>

#include <sys/wait.h>
#include <unistd.h>

#include <cstdlib>
#include <fstream>
#include <iterator>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <tuple>
#include <vector>

#include "quantized_reference.h"
#include "skinserve/character/gltf_import.h"
#include "skinserve/character/rest_encoding_choice.h"
#include "test_scenes.h"
#include "test_server.h"
#include "workload.h"

namespace skinserve::testing {
namespace {

std::string WriteScene(const Scene& scene, const std::string& name) {
  const std::string path = ::testing::TempDir() + name + "-" + std::to_string(getpid()) + ".glb";
  const std::vector<uint8_t> glb = WriteGlb(scene);
  std::ofstream out(path, std::ios::binary);
  out.write(reinterpret_cast<const char*>(glb.data()), static_cast<std::streamsize>(glb.size()));
  return path;
}

void ExpectStored(const StoredAttribute& got, StoredType type, bool normalized,
                  const std::string& what) {
  EXPECT_EQ(StoredTypeName(got.type), StoredTypeName(type)) << what;
  EXPECT_EQ(got.normalized, normalized) << what;
}

// What the importer records, primitive by primitive, against what test_scenes.cpp wrote.
TEST(QuantizedGltfUploadTest, TheImporterRecordsTheStoredComponentTypes) {
  auto quantized = LoadGltfBytes(WriteGlb(Quantized()));
  ASSERT_TRUE(quantized.ok()) << quantized.status().ToString();
  const auto& p = quantized->primitives;
  ASSERT_EQ(p.size(), 4u);  // skinned (uint8 weights), skinned (uint16), rigid box, rigid unit
  ExpectStored(p[0].stored.position, StoredType::kShort, false, "skinned POSITION");
  ExpectStored(p[0].stored.normal, StoredType::kByte, true, "skinned NORMAL");
  ExpectStored(p[0].stored.weights, StoredType::kUnsignedByte, true, "skinned WEIGHTS_0");
  ExpectStored(p[1].stored.normal, StoredType::kShort, true, "skinned16 NORMAL");
  ExpectStored(p[1].stored.weights, StoredType::kUnsignedShort, true, "skinned16 WEIGHTS_0");
  ExpectStored(p[2].stored.position, StoredType::kShort, false, "box POSITION");
  ExpectStored(p[2].stored.weights, StoredType::kNone, false, "rigid box: no WEIGHTS_0");
  ExpectStored(p[3].stored.position, StoredType::kUnsignedShort, true, "unit POSITION");

  auto floats = LoadGltfBytes(WriteGlb(TwoSkins()));
  ASSERT_TRUE(floats.ok()) << floats.status().ToString();
  for (const SkinnedPrimitive& f : floats->primitives) {
    ExpectStored(f.stored.position, StoredType::kFloat, false, f.name);
    if (!f.rigid()) ExpectStored(f.stored.weights, StoredType::kFloat, false, f.name);
  }
}

TEST(QuantizedGltfUploadTest, TheFileDecidesTheEncodingNamingWhy) {
  auto quantized = LoadGltfBytes(WriteGlb(Quantized()));
  ASSERT_TRUE(quantized.ok());
  const std::vector<int> all = {0, 1, 2, 3}, uint8_weights = {0}, rigid = {2, 3};
  RestEncodingChoice c = RestEncodingFromFile(*quantized, all);
  EXPECT_EQ(c.encoding, RestEncoding::kQuantized16) << c.reason;
  EXPECT_NE(c.reason.find("UNSIGNED_SHORT"), std::string::npos) << c.reason;
  c = RestEncodingFromFile(*quantized, uint8_weights);
  EXPECT_EQ(c.encoding, RestEncoding::kQuantized8Weights) << c.reason;
  c = RestEncodingFromFile(*quantized, rigid);
  EXPECT_EQ(c.encoding, RestEncoding::kQuantized16) << c.reason;

  auto floats = LoadGltfBytes(WriteGlb(TwoSkins()));
  ASSERT_TRUE(floats.ok());
  const std::vector<int> first = {0};
  c = RestEncodingFromFile(*floats, first);
  EXPECT_EQ(c.encoding, RestEncoding::kFloat32);
  EXPECT_NE(c.reason.find("stores POSITION as FLOAT"), std::string::npos) << c.reason;

  // 8-bit positions (KHR_mesh_quantization allows BYTE and UNSIGNED_BYTE): the 16-bit
  // stream holds them as well.
  Character bytes = *quantized;
  bytes.primitives[0].stored.position = {StoredType::kByte, true};
  bytes.primitives[2].stored.position = {StoredType::kUnsignedByte, false};
  c = RestEncodingFromFile(bytes, all);
  EXPECT_EQ(c.encoding, RestEncoding::kQuantized16) << c.reason;
  EXPECT_NE(c.reason.find("POSITION as 8- or 16-bit integers"), std::string::npos) << c.reason;

  // 16-bit positions with float weights: float32, naming the weights.
  Character mixed = *quantized;
  mixed.primitives[1].stored.weights = {StoredType::kFloat, false};
  c = RestEncodingFromFile(mixed, all);
  EXPECT_EQ(c.encoding, RestEncoding::kFloat32);
  EXPECT_NE(c.reason.find("stores WEIGHTS_n as FLOAT"), std::string::npos) << c.reason;

  auto morph = LoadGltfBytes(WriteGlb(MorphFace("LINEAR")));
  ASSERT_TRUE(morph.ok());
  c = RestEncodingFromFile(*morph, first);
  EXPECT_EQ(c.encoding, RestEncoding::kFloat32);
  EXPECT_NE(c.reason.find("morph targets"), std::string::npos) << c.reason;
}

// Every tool's order: an explicit choice wins over the file, the file over the default.
TEST(QuantizedGltfUploadTest, ToolsDecideTheEncodingInOneOrder) {
  const RestEncodingChoice file{RestEncoding::kQuantized8Weights, "the file's reason"};
  RestEncodingChoice c = DecideRestEncoding(RestEncoding::kQuantized16, file);
  EXPECT_EQ(c.encoding, RestEncoding::kQuantized16);
  EXPECT_EQ(c.reason, "asked with --rest-encoding");
  c = DecideRestEncoding(RestEncoding::kFloat32, file);
  EXPECT_EQ(c.encoding, RestEncoding::kFloat32);
  c = DecideRestEncoding(std::nullopt, file);
  EXPECT_EQ(c.encoding, RestEncoding::kQuantized8Weights);
  EXPECT_EQ(c.reason, "the file's reason");
  c = DecideRestEncoding(std::nullopt, std::nullopt);
  EXPECT_EQ(c.encoding, RestEncoding::kFloat32);
  EXPECT_EQ(c.reason, "the default");
}

// Frames of the workload's clip on `backend`, each against both references of the quantized
// stream: the float64 result on the glTF's dequantized floats (w.arrays) within the stated
// bound, and on the values the stream decodes to within float32 rounding.
void ExpectQuantizedFramesMatch(TestServer& t, const load::Workload& w, const std::string& mesh_id,
                                const std::string& backend) {
  for (uint64_t f : {0u, 11u, 29u, 44u}) {
    const std::vector<float>& palette = w.Palette(f);
    client::FrameResult r;
    Status s = t.client->Skin(mesh_id, palette, f, {.backend = backend, .want_normals = true}, &r);
    ASSERT_TRUE(s.ok()) << backend << ": " << s.ToString();
    const QuantizedErrors e = CheckQuantized(*w.mesh, *w.arrays, palette, r.positions, r.normals);
    const std::string what = backend + " frame " + std::to_string(f);
    EXPECT_LE(e.over_bound, 1.0) << what << ": against the glTF's floats, error / stated bound";
    EXPECT_LE(e.dequantized_position, FloatTolerance(palette, *w.arrays))
        << what << ": against the decoded values";
    EXPECT_LE(e.dequantized_normal, 1e-5) << what << ": normals against the decoded values";
  }
}

TEST(QuantizedGltfUploadTest, AQuantizedFileIsStoredQuantizedAndSkinsWithinTheStatedBound) {
  TestServer t;
  const std::string path = WriteScene(Quantized(), "quantized-rest");
  auto list = t.client->ListBackends();
  ASSERT_TRUE(list.ok());
  // The whole character (uint8 and uint16 weights: quantized16), and its first primitive
  // alone (uint8 weights only: quantized8-weights).
  for (auto [primitive, encoding, wire] :
       {std::tuple{-1, RestEncoding::kQuantized16, v1::REST_ENCODING_QUANTIZED16},
        std::tuple{0, RestEncoding::kQuantized8Weights, v1::REST_ENCODING_QUANTIZED8_WEIGHTS}}) {
    SCOPED_TRACE("primitive " + std::to_string(primitive));
    auto w = load::MakeGltfWorkload(path, primitive, true);
    ASSERT_TRUE(w.ok()) << w.status().ToString();
    ASSERT_TRUE(load::ChooseRestEncoding(&*w, std::nullopt).ok());
    EXPECT_EQ(w->rest_encoding, encoding) << w->rest_encoding_reason;
    EXPECT_NE(w->rest_encoding_reason.find("stores POSITION as 8- or 16-bit"), std::string::npos)
        << "the file's reason: " << w->rest_encoding_reason;
    ASSERT_NE(w->mesh->quantized_rest(), nullptr);
    auto info = t.client->Upload(*w->arrays, {.rest_encoding = w->rest_encoding});
    ASSERT_TRUE(info.ok()) << info.status().ToString();
    EXPECT_EQ(info->rest_encoding(), wire);
    EXPECT_EQ(info->mesh_id(), w->mesh->id());
    std::string checked;
    for (const auto& b : list->backends()) {
      // The backends that read the integers, and one that skins the decoded floats.
      if (b.id() != "serial" && !b.quantized_rest()) continue;
      if (!b.available()) {
        ADD_FAILURE() << b.id() << " unavailable: " << b.unavailable_reason();
        continue;
      }
      ExpectQuantizedFramesMatch(t, *w, info->mesh_id(), b.id());
      checked += " " + b.id();
    }
    EXPECT_EQ(checked, " serial simd simd-openmp opencl opencl-zerocopy");
  }
}

TEST(QuantizedGltfUploadTest, AFloatFileAndAnExplicitFloat32StayFloat32) {
  TestServer t;
  auto floats = load::MakeGltfWorkload(WriteScene(TwoSkins(), "float-rest"), -1, true);
  ASSERT_TRUE(floats.ok()) << floats.status().ToString();
  ASSERT_TRUE(load::ChooseRestEncoding(&*floats, std::nullopt).ok());
  EXPECT_EQ(floats->rest_encoding, RestEncoding::kFloat32) << floats->rest_encoding_reason;
  EXPECT_NE(floats->rest_encoding_reason.find("POSITION as FLOAT"), std::string::npos)
      << floats->rest_encoding_reason;

  auto asked = load::MakeGltfWorkload(WriteScene(Quantized(), "asked-float"), -1, true);
  ASSERT_TRUE(asked.ok()) << asked.status().ToString();
  ASSERT_TRUE(load::ChooseRestEncoding(&*asked, RestEncoding::kFloat32).ok());
  EXPECT_EQ(asked->rest_encoding, RestEncoding::kFloat32);
  EXPECT_EQ(asked->mesh->quantized_rest(), nullptr);

  for (load::Workload* w : {&*floats, &*asked}) {
    auto info = t.client->Upload(*w->arrays, {.rest_encoding = w->rest_encoding});
    ASSERT_TRUE(info.ok()) << info.status().ToString();
    EXPECT_EQ(info->rest_encoding(), v1::REST_ENCODING_FLOAT32);
    EXPECT_EQ(info->mesh_id(), w->mesh->id());
  }
}

// What skinserve-load wrote: its JSON report (empty on failure, with a test failure) and its
// stderr, after a run with `args` against `t` (`name` names the files).
struct LoadRun {
  nlohmann::json report;
  std::string stderr_text;
};
LoadRun RunLoadClient(const TestServer& t, const std::string& args, const std::string& name) {
  const std::string base = ::testing::TempDir() + name + "-" + std::to_string(getpid());
  const std::string command = std::string(SKINSERVE_LOAD_BINARY) + " --target " + t.target + " " +
                              args + " --streams 1 --warmup 0 --check-every 1 --json " + base +
                              ".json > /dev/null 2> " + base + ".err";
  const int status = std::system(command.c_str());
  EXPECT_EQ(WEXITSTATUS(status), 0) << command;
  LoadRun run;
  std::ifstream err(base + ".err");
  run.stderr_text.assign(std::istreambuf_iterator<char>(err), {});
  std::ifstream in(base + ".json");
  if (!in) {
    ADD_FAILURE() << command << " wrote no report; stderr: " << run.stderr_text;
    return run;
  }
  in >> run.report;
  return run;
}

// The load client itself: on the quantized file it uploads quantized16 unless told
// float32, says which and why, and every answer passes its own checks.
TEST(QuantizedGltfUploadTest, LoadClientPicksTheFilesEncodingUnlessAsked) {
  TestServer t;
  const std::string path = WriteScene(Quantized(), "load-quantized");
  int run = 0;
  for (auto [extra, expected] :
       {std::pair{"", "quantized16"}, std::pair{" --rest-encoding float32", "float32"}}) {
    SCOPED_TRACE(extra);
    const LoadRun load =
        RunLoadClient(t, "--mesh " + path + extra + " --backends simd,serial --normals --frames 20",
                      "load-quantized-" + std::to_string(run++));
    ASSERT_EQ(load.report["results"].size(), 2u) << load.report.dump();
    for (const auto& r : load.report["results"]) {
      EXPECT_EQ(r["rest_encoding"], expected) << r.dump();
      EXPECT_TRUE(r["errors"].empty()) << r.dump();
      EXPECT_EQ(r["checked"], 20) << r.dump();
    }
    EXPECT_NE(load.stderr_text.find(std::string("note: rest encoding ") + expected),
              std::string::npos)
        << load.stderr_text;
  }
}

// The load client asks a quantized mesh for its tangents back on every backend that reads
// the stream (and one that skins the decoded floats), each answer checked against the
// float64 reference.
TEST(QuantizedGltfUploadTest, LoadClientChecksAQuantizedMeshsTangentsOnEveryBackend) {
  TestServer t;
  const LoadRun load =
      RunLoadClient(t,
                    "--vertices 3001 --bones 4 --rest-encoding quantized16 --normals --tangents"
                    " --backends simd,simd-openmp,opencl,opencl-zerocopy,serial --frames 10",
                    "load-quantized-tangents");
  ASSERT_EQ(load.report["results"].size(), 5u) << load.report.dump();
  for (const auto& r : load.report["results"]) {
    EXPECT_EQ(r["rest_encoding"], "quantized16") << r.dump();
    EXPECT_TRUE(r["tangents"].get<bool>()) << r.dump();
    EXPECT_TRUE(r["errors"].empty()) << r.dump();
    EXPECT_EQ(r["mismatches"], 0) << r.dump();
    EXPECT_EQ(r["checked"], 10) << r.dump();
  }
}

}  // namespace
}  // namespace skinserve::testing
