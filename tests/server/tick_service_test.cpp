// Ticks (SkinRequest.characters) through a real server over loopback and the real client
// library (Tick, SkinTick, StreamTicks): every character of a tick mixing meshes, crowds,
// morph weights, encodings and normals matches the float64 reference within its encoding's
// stated bound (CompareEncodedWithReference) on every backend, unary and streamed; a bad
// character fails alone, named with its field; a tick's own fields and its limits refuse it
// whole, naming the field or the option; ticks and frames keep request order on a stream;
// characters written into their ranges of one or two shared-memory regions match too.
#include <gtest/gtest.h>

#include <cstring>
#include <filesystem>
#include <string>
#include <vector>

#include "observability/metrics_frames.h"
#include "skinserve/client/shared_memory_region.h"
#include "skinserve/client/tick.h"
#include "skinserve/model/palette.h"
#include "skinserve/reference/encoded_reference.h"
#include "skinserve/reference/synthetic.h"
#include "skinserve/reference/synthetic_morph.h"
#include "skinserve/wire/region_layout.h"
#include "test_server.h"

namespace skinserve::testing {
namespace {

using client::FrameResult;
using client::SkinOptions;
using client::Tick;
using client::TickResult;

constexpr uint32_t kJoints = 30;
constexpr uint32_t kTargets = 8;

// Three distinct meshes: with normals and morph targets, with normals, without normals.
struct Meshes {
  std::vector<MeshArrays> arrays;
  std::vector<std::shared_ptr<const Mesh>> meshes;
  std::vector<std::string> ids;

  explicit Meshes(client::SkinClient& client) {
    MeshArrays morphed = MakeSyntheticMesh({.vertex_count = 1500,
                                            .influences = 3,
                                            .joint_count = kJoints,
                                            .normals = true,
                                            .seed = 41});
    AddSyntheticMorphTargets({.targets = kTargets, .fraction = 0.2, .seed = 41}, &morphed);
    arrays.push_back(std::move(morphed));
    arrays.push_back(MakeSyntheticMesh({.vertex_count = 900,
                                        .influences = 2,
                                        .joint_count = kJoints,
                                        .normals = true,
                                        .seed = 42}));
    arrays.push_back(MakeSyntheticMesh({.vertex_count = 2200,
                                        .influences = 4,
                                        .joint_count = kJoints,
                                        .normals = false,
                                        .seed = 43}));
    for (const MeshArrays& a : arrays) {
      meshes.push_back(std::move(Mesh::Create(a)).value());
      auto info = client.Upload(a);
      EXPECT_TRUE(info.ok()) << info.status().ToString();
      ids.push_back(info.ok() ? info->mesh_id() : "");
    }
  }
};

// One character as a test asks for it, with the inputs its check needs.
struct Character {
  int mesh = 0;
  uint32_t instances = 1;
  VertexEncoding encoding = VertexEncoding::kFloat32;
  bool normals = false;
  int morph = 0;  // 0: none, 1: shared weights, 2: weights per instance
  std::vector<float> palettes;
  std::vector<MorphWeight> weights;
  std::vector<std::vector<MorphWeight>> instance_weights;
};

// The mix every backend gets: distinct meshes, crowds, morph weights, every encoding.
std::vector<Character> Mix(uint64_t frame) {
  std::vector<Character> mix = {
      {.mesh = 0,
       .instances = 1,
       .encoding = VertexEncoding::kFloat32,
       .normals = true,
       .morph = 1},
      {.mesh = 1, .instances = 3, .encoding = VertexEncoding::kFloat16, .normals = true},
      {.mesh = 2, .instances = 1, .encoding = VertexEncoding::kSnorm16},
      {.mesh = 0,
       .instances = 2,
       .encoding = VertexEncoding::kSnorm16,
       .normals = true,
       .morph = 2},
      {.mesh = 1, .instances = 1, .encoding = VertexEncoding::kFloat32},
      {.mesh = 2, .instances = 4, .encoding = VertexEncoding::kFloat16},
  };
  for (std::size_t c = 0; c < mix.size(); ++c) {
    Character& m = mix[c];
    for (uint32_t k = 0; k < m.instances; ++k) {
      const auto one = MakeSyntheticPalette(kJoints, 100 * c + k, frame + k);
      m.palettes.insert(m.palettes.end(), one.begin(), one.end());
      if (m.morph == 2)
        m.instance_weights.push_back(MakeMorphWeights(kTargets, 3 + k, c + k, frame));
    }
    if (m.morph == 1) m.weights = MakeMorphWeights(kTargets, 5, c, frame);
  }
  return mix;
}

void AddTo(const Meshes& meshes, const std::vector<Character>& characters,
           const std::string& backend, Tick* tick) {
  for (const Character& c : characters) {
    tick->Add(meshes.ids[c.mesh], c.palettes,
              {.backend = backend,
               .want_normals = c.normals,
               .encoding = c.encoding,
               .instances = c.instances,
               .morph_weights = c.weights,
               .instance_morph_weights = c.instance_weights});
  }
}

// Every instance of the character against the float64 reference (in a region: decoded).
void ExpectMatches(const Meshes& meshes, const Character& c, FrameResult result,
                   const std::string& what) {
  ASSERT_TRUE(result.status.ok()) << what << ": " << result.status.ToString();
  ASSERT_TRUE(client::DecodeRegionFrame(&result).ok()) << what;
  const Mesh& mesh = *meshes.meshes[c.mesh];
  ASSERT_EQ(result.instances, c.instances) << what;
  ASSERT_EQ(result.vertices, mesh.vertex_count()) << what;
  ASSERT_EQ(result.encoding, c.encoding) << what;
  ASSERT_EQ(result.normals.empty(), !c.normals) << what;
  const std::size_t floats = kFloatsPerJoint * kJoints;
  for (uint32_t k = 0; k < c.instances; ++k) {
    const std::span<const MorphWeight> morph =
        c.morph == 2 ? std::span<const MorphWeight>(c.instance_weights[k]) : c.weights;
    const EncodedDeviation d = CompareEncodedWithReference(
        mesh, std::span(c.palettes).subspan(k * floats, floats), c.encoding, result.bounds[k],
        result.instance_positions(k),
        c.normals ? result.instance_normals(k) : std::span<const float>(), SkinningMethod::kLinear,
        morph);
    EXPECT_TRUE(d.within_tolerance())
        << what << " instance " << k << ": worst position ratio " << d.worst_position_ratio
        << ", normal ratio " << d.worst_normal_ratio << " at vertex " << d.worst_vertex;
  }
}

TEST(TickTest, EveryCharacterOfAMixedTickMatchesTheReferenceOnEveryBackend) {
  TestServer t;
  const Meshes meshes(*t.client);
  const server::TickCounts before = server::TickTotals();
  const std::vector<std::string> backends = SkinningBackends(*t.client);
  EXPECT_GE(backends.size(), 4u);
  uint64_t ticks = 0, characters = 0;
  for (const std::string& backend : backends) {
    SCOPED_TRACE(backend);
    // Unary Skin with a tick.
    const std::vector<Character> mix = Mix(7);
    Tick tick;
    tick.set_frame(7);
    AddTo(meshes, mix, backend, &tick);
    TickResult result;
    ASSERT_TRUE(t.client->SkinTick(tick, &result).ok()) << result.status.ToString();
    ++ticks;
    characters += mix.size();
    EXPECT_EQ(result.frame, 7u);
    ASSERT_EQ(result.characters.size(), mix.size());
    for (std::size_t c = 0; c < mix.size(); ++c) {
      ExpectMatches(meshes, mix[c], result.characters[c], "unary, character " + std::to_string(c));
    }
    // Streamed: three ticks of new poses, two in flight.
    std::vector<std::vector<Character>> sent(3);
    int answered = 0;
    client::TickStreamSummary summary;
    const Status streamed = client::StreamTicks(
        *t.client, {.first_tick = 20, .ticks = 3, .window = 2},
        [&](uint64_t frame, Tick* next) {
          sent[frame - 20] = Mix(frame);
          AddTo(meshes, sent[frame - 20], backend, next);
        },
        [&](TickResult& r, std::chrono::nanoseconds) {
          ASSERT_TRUE(r.status.ok()) << r.status.ToString();
          EXPECT_EQ(r.frame, 20u + answered);  // in request order
          const auto& mix_sent = sent[r.frame - 20];
          ASSERT_EQ(r.characters.size(), mix_sent.size());
          for (std::size_t c = 0; c < mix_sent.size(); ++c) {
            ExpectMatches(meshes, mix_sent[c], r.characters[c],
                          "tick " + std::to_string(r.frame) + ", character " + std::to_string(c));
          }
          ++answered;
        },
        &summary);
    ASSERT_TRUE(streamed.ok()) << streamed.ToString();
    EXPECT_EQ(answered, 3);
    EXPECT_EQ(summary.characters_answered, 3 * mix.size());
    EXPECT_EQ(summary.characters_failed, 0u);
    ticks += 3;
    characters += 3 * mix.size();
  }
  const server::TickCounts after = server::TickTotals();
  EXPECT_EQ(after.ticks - before.ticks, ticks);
  EXPECT_EQ(after.characters - before.characters, characters);
}

// Sends `request` as a tick through Skin and assembles its answer (for requests the Tick
// builder would not make).
Status RawSkinTick(client::SkinClient& client, const Tick& tick, const v1::SkinRequest& request,
                   TickResult* result) {
  grpc::ClientContext context;
  auto reader = client.SkinRaw(&context, request);
  client::TickAssembler assembler(tick, result);
  client::RawPart part;
  grpc::ByteBuffer bytes;
  bool complete = false;
  while (reader->Read(&bytes)) {
    if (!complete) complete = assembler.Add(bytes, &part);
  }
  if (Status s = wire::FromGrpc(reader->Finish()); !s.ok()) return s;
  EXPECT_TRUE(complete);
  return result->status;
}

TEST(TickTest, ABadCharacterFailsAloneNamingItselfAndItsField) {
  TestServer t;
  const Meshes meshes(*t.client);
  const std::vector<Character> mix = Mix(3);
  const std::vector<float> short_palette(12 * (kJoints - 1), 0.5f);
  Tick tick;
  tick.set_frame(3);
  tick.Add(meshes.ids[0], mix[0].palettes, {.want_normals = true, .morph_weights = mix[0].weights});
  tick.Add(std::string(64, 'f'), mix[1].palettes, {.instances = 3});  // no such mesh
  tick.Add(meshes.ids[1], short_palette, {});                         // a joint short
  tick.Add(meshes.ids[1], mix[1].palettes,
           {.want_normals = true, .encoding = VertexEncoding::kFloat16, .instances = 3});
  tick.Add(meshes.ids[2], mix[2].palettes, {.want_normals = true});                  // no normals
  tick.Add(meshes.ids[2], mix[2].palettes, {.encoding = VertexEncoding::kSnorm16});  // frame set
  v1::SkinRequest request;
  tick.ToWire(&request);
  request.mutable_characters(5)->set_frame(9);
  TickResult result;
  ASSERT_TRUE(RawSkinTick(*t.client, tick, request, &result).ok()) << result.status.ToString();
  ASSERT_EQ(result.characters.size(), 6u);
  ExpectMatches(meshes, mix[0], result.characters[0], "character 0");
  ExpectMatches(meshes, mix[1], result.characters[3], "character 3");
  EXPECT_EQ(result.failed(), 4u);
  const auto expect_error = [&](std::size_t c, StatusCode code, const std::string& words) {
    const Status& s = result.characters[c].status;
    EXPECT_EQ(s.code(), code) << c << ": " << s.ToString();
    EXPECT_NE(s.message().find("character " + std::to_string(c) + ": "), std::string::npos)
        << s.ToString();
    EXPECT_NE(s.message().find(words), std::string::npos) << s.ToString();
    EXPECT_TRUE(result.characters[c].positions.empty());
  };
  expect_error(1, StatusCode::kNotFound, std::string(64, 'f'));
  expect_error(2, StatusCode::kInvalidArgument, "palette");
  expect_error(4, StatusCode::kInvalidArgument, "want_normals");
  expect_error(5, StatusCode::kInvalidArgument, "frame is set");
}

TEST(TickTest, ATicksOwnFieldRefusesItWholeNamingTheField) {
  TestServer t;
  const Meshes meshes(*t.client);
  const std::vector<Character> mix = Mix(1);
  Tick tick;
  tick.set_frame(1);
  AddTo(meshes, mix, "", &tick);
  for (const char* field : {"mesh_id", "want_normals", "palette"}) {
    SCOPED_TRACE(field);
    v1::SkinRequest request;
    tick.ToWire(&request);
    if (std::string(field) == "mesh_id") request.set_mesh_id(meshes.ids[0]);
    if (std::string(field) == "want_normals") request.set_want_normals(true);
    if (std::string(field) == "palette") request.set_palette("x");
    TickResult result;
    const Status s = RawSkinTick(*t.client, tick, request, &result);  // unary: the call's status
    EXPECT_EQ(s.code(), StatusCode::kInvalidArgument) << s.ToString();
    EXPECT_NE(s.message().find(std::string("own field ") + field), std::string::npos)
        << s.ToString();
  }
  // On a stream the tick is answered with its error, and the stream goes on.
  v1::SkinRequest bad, good;
  tick.ToWire(&bad);
  bad.set_mesh_id(meshes.ids[0]);
  Tick next;
  next.set_frame(2);
  AddTo(meshes, mix, "", &next);
  next.ToWire(&good);
  grpc::ClientContext context;
  auto stream = t.client->StreamSkinRaw(&context);
  ASSERT_TRUE(stream->Write(bad));
  ASSERT_TRUE(stream->Write(good));
  stream->WritesDone();
  client::RawPart part;
  grpc::ByteBuffer bytes;
  for (const Tick* sent : {&tick, &next}) {
    TickResult result;
    client::TickAssembler assembler(*sent, &result);
    bool complete = false;
    while (!complete && stream->Read(&bytes)) complete = assembler.Add(bytes, &part);
    ASSERT_TRUE(complete);
    if (sent == &tick) {
      EXPECT_EQ(result.status.code(), StatusCode::kInvalidArgument) << result.status.ToString();
      EXPECT_NE(result.status.message().find("own field mesh_id"), std::string::npos);
      continue;
    }
    ASSERT_TRUE(result.status.ok()) << result.status.ToString();
    for (std::size_t c = 0; c < mix.size(); ++c) {
      ExpectMatches(meshes, mix[c], result.characters[c], "after the refused tick");
    }
  }
  EXPECT_TRUE(stream->Finish().ok());
}

TEST(TickTest, TooManyCharactersOrBytesAreRefusedNamingTheOption) {
  server::ServerOptions options;
  options.max_tick_characters = 4;
  options.max_tick_bytes = 64 << 10;
  TestServer t(options);
  const Meshes meshes(*t.client);
  std::vector<Character> mix = Mix(2);
  Character plain = mix[1];  // as the ticks below send it
  plain.encoding = VertexEncoding::kFloat32;
  plain.normals = false;
  const auto tick_of = [&](std::size_t characters, uint32_t instances) {
    Tick tick;
    tick.set_frame(2);
    for (std::size_t c = 0; c < characters; ++c) {
      tick.Add(meshes.ids[1], mix[1].palettes, {.instances = instances});  // 3 palettes each
    }
    return tick;
  };
  struct Case {
    std::size_t characters;
    uint32_t instances;
    const char* option;
  };
  // 5 characters > 4; 4 characters of 3 x 1,440 palette bytes fit 64 KiB; a crowd of 64
  // palettes (92 KB) does not.
  for (const Case& c : {Case{5, 3, "--max-tick-characters"}, Case{4, 3, nullptr}}) {
    SCOPED_TRACE(c.characters);
    const Tick tick = tick_of(c.characters, c.instances);
    TickResult result;
    const Status s = t.client->SkinTick(tick, &result);
    if (c.option == nullptr) {
      EXPECT_TRUE(s.ok()) << s.ToString();
      EXPECT_EQ(result.failed(), 0u);
      continue;
    }
    EXPECT_EQ(s.code(), StatusCode::kResourceExhausted) << s.ToString();
    EXPECT_NE(s.message().find(c.option), std::string::npos) << s.ToString();
  }
  std::vector<float> crowd;
  for (int k = 0; k < 64; ++k) {
    crowd.insert(crowd.end(), mix[1].palettes.begin(), mix[1].palettes.begin() + 12 * kJoints);
  }
  Tick big;
  big.set_frame(5);
  big.Add(meshes.ids[1], crowd, {.instances = 64});  // 64 x 1,440 bytes > 64 KiB
  TickResult result;
  const Status s = t.client->SkinTick(big, &result);
  EXPECT_EQ(s.code(), StatusCode::kResourceExhausted) << s.ToString();
  EXPECT_NE(s.message().find("--max-tick-bytes"), std::string::npos) << s.ToString();
  // On a stream a refused tick is answered with its error and the next one goes on.
  int calls = 0;
  const Status streamed = client::StreamTicks(
      *t.client, {.first_tick = 0, .ticks = 2, .window = 2},
      [&](uint64_t frame, Tick* next) {
        for (std::size_t c = 0; c < (frame == 0 ? 5u : 2u); ++c) {
          next->Add(meshes.ids[1], mix[1].palettes, {.instances = 3});
        }
      },
      [&](TickResult& r, std::chrono::nanoseconds) {
        if (calls++ == 0) {
          EXPECT_EQ(r.status.code(), StatusCode::kResourceExhausted) << r.status.ToString();
          EXPECT_NE(r.status.message().find("--max-tick-characters"), std::string::npos);
          return;
        }
        ASSERT_TRUE(r.status.ok()) << r.status.ToString();
        for (std::size_t c = 0; c < 2; ++c) ExpectMatches(meshes, plain, r.characters[c], "");
      });
  EXPECT_TRUE(streamed.ok()) << streamed.ToString();
  EXPECT_EQ(calls, 2);
}

// The wire itself: ticks and plain frames keep request order on one stream; a tick's
// vertex parts name their character with `last` false, and its final part holds a header
// per character in request order.
TEST(TickTest, TicksAndFramesKeepRequestOrderAndTheTickAnswersAsTheContractSays) {
  TestServer t;
  const Meshes meshes(*t.client);
  const std::vector<Character> mix = Mix(0);
  auto stub = v1::Skinning::NewStub(client::MakeChannel(t.target));
  grpc::ClientContext context;
  auto stream = stub->StreamSkin(&context);
  for (uint64_t frame = 0; frame < 4; ++frame) {
    v1::SkinRequest request;
    if (frame % 2 == 1) {
      Tick tick;
      tick.set_frame(frame);
      AddTo(meshes, mix, "", &tick);
      tick.ToWire(&request);
    } else {
      request.set_mesh_id(meshes.ids[1]);
      request.set_frame(frame);
      request.set_palette(mix[4].palettes.data(), mix[4].palettes.size() * sizeof(float));
    }
    ASSERT_TRUE(stream->Write(request));
  }
  stream->WritesDone();
  v1::SkinResponse part;
  for (uint64_t frame = 0; frame < 4; ++frame) {
    SCOPED_TRACE(frame);
    std::vector<int> parts(mix.size(), 0);
    while (true) {
      ASSERT_TRUE(stream->Read(&part));
      ASSERT_EQ(part.frame(), frame);
      ASSERT_FALSE(part.has_error()) << part.error().message();
      if (frame % 2 == 0 || part.last()) break;
      ASSERT_LT(part.character(), mix.size());
      ++parts[part.character()];
    }
    EXPECT_TRUE(part.last());
    if (frame % 2 == 0) {
      EXPECT_FALSE(part.has_tick());
      continue;
    }
    ASSERT_EQ(part.tick().characters_size(), static_cast<int>(mix.size()));
    for (std::size_t c = 0; c < mix.size(); ++c) {
      const v1::SkinResponse& h = part.tick().characters(static_cast<int>(c));
      EXPECT_EQ(h.character(), c);
      EXPECT_EQ(h.frame(), frame);
      EXPECT_EQ(h.instances(), mix[c].instances);
      EXPECT_EQ(h.total_vertices(), meshes.meshes[mix[c].mesh]->vertex_count());
      EXPECT_FALSE(h.has_error());
      EXPECT_GT(h.timing().compute_ns(), 0);
      EXPECT_GE(parts[c], 1) << "character " << c << " sent no vertex part";
    }
  }
  EXPECT_TRUE(stream->Finish().ok());
}

// Shared memory: each character writes its own range of one region (or of two), and the
// answer is the one final part listing every character's RegionWrite.
class ShmDir {
 public:
  ShmDir() {
    char name[] = "/dev/shm/skinserve-tick-XXXXXX";
    path_ = mkdtemp(name);
  }
  ~ShmDir() { std::filesystem::remove_all(path_); }
  const std::string& path() const { return path_; }

 private:
  std::string path_;
};

TEST(TickTest, CharactersWriteTheirOwnRangesOfOneOrTwoRegions) {
  ShmDir dir;
  server::ServerOptions options;
  options.shm_dir = dir.path();
  TestServer t(options, Transport::kUnixSocket);
  const Meshes meshes(*t.client);
  const std::vector<Character> mix = Mix(5);
  // Each character's bytes, back to back from 64 in the first region; in the second run,
  // the odd characters go into a second region.
  std::vector<uint64_t> sizes;
  uint64_t total = 64;
  for (const Character& c : mix) {
    sizes.push_back(wire::RegionFrameBytes(meshes.meshes[c.mesh]->vertex_count(), c.instances,
                                           c.encoding, c.normals));
    total += sizes.back();
  }
  std::vector<std::unique_ptr<client::SharedMemoryRegion>> regions;
  for (const char* name : {"one", "two"}) {
    auto region = client::SharedMemoryRegion::Create(client::SharedMemoryRegion::UniqueKey("tick"),
                                                     total, dir.path());
    ASSERT_TRUE(region.ok()) << region.status().ToString();
    regions.push_back(std::move(region).value());
    ASSERT_TRUE(t.client->RegisterRegion(name, *regions.back()).ok());
  }
  for (bool two : {false, true}) {
    SCOPED_TRACE(two ? "two regions" : "one region");
    Tick tick;
    tick.set_frame(5);
    uint64_t offset = 64;
    for (std::size_t c = 0; c < mix.size(); ++c) {
      const bool second = two && c % 2 == 1;
      const Character& m = mix[c];
      tick.Add(meshes.ids[m.mesh], m.palettes,
               {.want_normals = m.normals,
                .encoding = m.encoding,
                .instances = m.instances,
                .output = {.name = second ? "two" : "one",
                           .region = regions[second ? 1 : 0].get(),
                           .offset = offset},
                .morph_weights = m.weights,
                .instance_morph_weights = m.instance_weights});
      offset += sizes[c];
    }
    v1::SkinRequest request;
    tick.ToWire(&request);
    grpc::ClientContext context;
    auto reader = t.client->SkinRaw(&context, request);
    TickResult result;
    client::TickAssembler into(tick, &result);
    client::RawPart part;
    grpc::ByteBuffer bytes;
    int parts = 0;
    while (reader->Read(&bytes)) {
      ++parts;
      into.Add(bytes, &part);
    }
    ASSERT_TRUE(reader->Finish().ok());
    EXPECT_EQ(parts, 1) << "the answer over shared memory is the final part alone";
    ASSERT_TRUE(result.status.ok()) << result.status.ToString();
    offset = 64;
    for (std::size_t c = 0; c < mix.size(); ++c) {
      const FrameResult& r = result.characters[c];
      ASSERT_TRUE(r.in_region()) << c;
      const bool second = two && c % 2 == 1;
      EXPECT_EQ(r.region_positions.data(), regions[second ? 1 : 0]->bytes().data() + offset) << c;
      ExpectMatches(meshes, mix[c], r, "character " + std::to_string(c));
      offset += sizes[c];
    }
  }
}

// StreamTicks: a mesh deleted between ticks is uploaded again and the tick sent again; two
// ticks in flight write into their own slots of a region (region_stride).
TEST(TickTest, AStreamOfTicksReuploadsALostMeshAndKeepsItsRegionSlotsApart) {
  ShmDir dir;
  server::ServerOptions options;
  options.shm_dir = dir.path();
  TestServer t(options, Transport::kUnixSocket);
  const Meshes meshes(*t.client);
  const Character region_spec = Mix(0)[1];  // mesh 1, a crowd of 3 in float16 with normals
  const uint64_t stride =
      wire::RegionFrameBytes(meshes.meshes[1]->vertex_count(), region_spec.instances,
                             region_spec.encoding, region_spec.normals);
  auto region = client::SharedMemoryRegion::Create(client::SharedMemoryRegion::UniqueKey("tick"),
                                                   2 * stride, dir.path());
  ASSERT_TRUE(region.ok()) << region.status().ToString();
  ASSERT_TRUE(t.client->RegisterRegion("slots", **region).ok());
  std::vector<std::vector<Character>> sent(6);
  std::vector<bool> seen(sent.size(), false);
  int answered = 0;
  client::TickStreamSummary summary;
  const Status streamed = client::StreamTicks(
      *t.client, {.first_tick = 0, .ticks = 6, .window = 2, .region_stride = stride},
      [&](uint64_t frame, Tick* tick) {
        if (frame == 3 && sent[3].empty()) {  // the server loses mesh 0 (once)
          ASSERT_TRUE(t.client->DeleteMesh(meshes.ids[0]).ok());
        }
        sent[frame] = Mix(frame);
        const Character& r = sent[frame][1];
        const Character& w = sent[frame][0];  // mesh 0 with morph weights, over the wire
        tick->Add(meshes.ids[0], w.palettes,
                  {.want_normals = w.normals, .encoding = w.encoding, .morph_weights = w.weights});
        tick->Add(meshes.ids[1], r.palettes,
                  {.want_normals = r.normals,
                   .encoding = r.encoding,
                   .instances = r.instances,
                   .output = {.name = "slots", .region = region->get(), .offset = 0}});
      },
      [&](TickResult& r, std::chrono::nanoseconds) {
        ASSERT_TRUE(r.status.ok()) << r.status.ToString();
        // In order of answers: a tick sent again after the re-upload may be answered after
        // a later one that the server read once the mesh was back. Each tick once.
        ASSERT_LT(r.frame, sent.size());
        EXPECT_FALSE(seen[r.frame]) << "tick " << r.frame << " answered twice";
        seen[r.frame] = true;
        ASSERT_EQ(r.characters.size(), 2u);
        ExpectMatches(meshes, sent[r.frame][0], r.characters[0], "over the wire");
        // Its slot: the region's bytes stay its own until the slot is used again.
        EXPECT_TRUE(r.characters[1].in_region());
        ExpectMatches(meshes, sent[r.frame][1], r.characters[1], "in the region");
        ++answered;
      },
      &summary);
  ASSERT_TRUE(streamed.ok()) << streamed.ToString();
  EXPECT_EQ(answered, 6);
  EXPECT_GE(summary.reuploads, 1u);
  EXPECT_EQ(summary.characters_failed, 0u);
  EXPECT_EQ(summary.characters_answered, 12u);
}

}  // namespace
}  // namespace skinserve::testing
