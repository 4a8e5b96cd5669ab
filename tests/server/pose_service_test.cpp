// Poses on the server (SkinRequest.pose) through a real server over loopback: a skeleton
// and clips uploaded, frames and ticks naming clip layers, every skinned vertex checked
// against a float64 evaluation of the ORIGINAL clip channels (tests/animation's reference:
// glTF's formulas in double, with its own slerp, Hermite and hierarchy; it never reads the
// compact store), blended here in double, skinned here in double. Bad ids, times and
// weights are named; a bad upload stores nothing; the clip budget refuses with
// RESOURCE_EXHAUSTED and keeps nothing of the refused clip.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <cstring>
#include <functional>
#include <map>
#include <set>
#include <string>
#include <vector>

#include "pose_reference.h"
#include "skinserve/client/frame_stream.h"
#include "skinserve/client/tick.h"
#include "skinserve/model/palette.h"
#include "skinserve/reference/synthetic.h"
#include "skinserve/reference/synthetic_morph.h"
#include "skinserve/wire/animation_conversions.h"
#include "test_server.h"

namespace skinserve::testing {
namespace {

constexpr uint32_t kJoints = 77;

// Local TRS of every reference node at `t` (clamped), the clip's channels applied to the
// rest pose, in double.
struct Local {
  double t[3], r[4], s[3];
};

std::vector<Local> RefLocal(const PoseCase& c, double t) {
  std::vector<Local> local(c.ref.nodes.size());
  for (std::size_t n = 0; n < local.size(); ++n) {
    const RefNode& node = c.ref.nodes[n];
    std::copy_n(node.t, 3, local[n].t);
    std::copy_n(node.r, 4, local[n].r);
    std::copy_n(node.s, 3, local[n].s);
  }
  for (const RefChannel& ch : c.ref_clip.channels) {
    const std::vector<double> v = RefSample(ch, t);
    Local& l = local[static_cast<std::size_t>(ch.node)];
    double* out = ch.path == "translation" ? l.t : ch.path == "rotation" ? l.r : l.s;
    std::copy(v.begin(), v.end(), out);
  }
  return local;
}

// A layer as the test asks the server for it. Looped times stay off keys: the server wraps
// them in float32, which may land either side of a STEP key that double lands on.
struct Layer {
  double time = 0;
  double weight = 1;
  bool loop = false;
};

// The blend of the spec (normalised weights, rotations onto the first layer's hemisphere
// and normalised), then model matrices root down and the palette, in double (12 a joint).
std::vector<double> RefBlendedPalette(const PoseCase& c, const std::vector<Layer>& layers) {
  double total = 0;
  for (const Layer& l : layers) total += l.weight;
  std::vector<Local> blended(c.ref.nodes.size(), Local{{0, 0, 0}, {0, 0, 0, 0}, {0, 0, 0}});
  std::vector<Local> first;
  for (const Layer& l : layers) {
    // The time the server gets (float32): on a key, a STEP track takes that key's value.
    double t = static_cast<float>(l.time);
    if (l.loop) t -= c.ref_clip.duration * std::floor(t / c.ref_clip.duration);
    const std::vector<Local> local = RefLocal(c, t);
    if (first.empty()) first = local;
    const double w = l.weight / total;
    for (std::size_t n = 0; n < local.size(); ++n) {
      double dot = 0;
      for (int i = 0; i < 4; ++i) dot += local[n].r[i] * first[n].r[i];
      const double sign = dot < 0 ? -1 : 1;
      for (int i = 0; i < 3; ++i) blended[n].t[i] += w * local[n].t[i];
      for (int i = 0; i < 3; ++i) blended[n].s[i] += w * local[n].s[i];
      for (int i = 0; i < 4; ++i) blended[n].r[i] += sign * w * local[n].r[i];
    }
  }
  std::vector<Mat4> model(blended.size());
  for (std::size_t n = 0; n < blended.size(); ++n) {
    Local& b = blended[n];
    const double norm =
        std::sqrt(b.r[0] * b.r[0] + b.r[1] * b.r[1] + b.r[2] * b.r[2] + b.r[3] * b.r[3]);
    for (double& q : b.r) q /= norm;
    const Mat4 m = Compose(b.t, b.r, b.s);
    const int parent = c.ref.nodes[n].parent;  // parents come first in the synthetic rig
    if (parent < 0) {
      model[n] = m;
      continue;
    }
    const Mat4& p = model[static_cast<std::size_t>(parent)];
    for (int col = 0; col < 4; ++col)
      for (int row = 0; row < 4; ++row) {
        double sum = 0;
        for (int k = 0; k < 4; ++k) sum += p[4 * k + row] * m[4 * col + k];
        model[n][static_cast<std::size_t>(4 * col + row)] = sum;
      }
  }
  std::vector<double> palette;
  for (std::size_t j = 0; j < c.ref.joints.size(); ++j) {
    const Mat4& m = model[static_cast<std::size_t>(c.ref.joints[j])];
    const Mat4& ib = c.ref.inverse_bind[j];
    for (int row = 0; row < 3; ++row)
      for (int col = 0; col < 4; ++col) {
        double sum = 0;
        for (int k = 0; k < 4; ++k) sum += m[4 * k + row] * ib[4 * col + k];
        palette.push_back(sum);
      }
  }
  return palette;
}

// Linear blend skinning of `rest` (the mesh's positions, or them morphed) with a double
// palette.
std::vector<double> RefSkinPoints(const MeshArrays& mesh, const std::vector<double>& rest,
                                  const std::vector<double>& palette) {
  std::vector<double> out(3ull * mesh.vertex_count, 0.0);
  for (uint32_t v = 0; v < mesh.vertex_count; ++v) {
    const double* p = &rest[3ull * v];
    for (uint32_t i = 0; i < mesh.influences; ++i) {
      const double w = mesh.weights[v * mesh.influences + i];
      const double* m = &palette[12ull * mesh.joints[v * mesh.influences + i]];
      for (int r = 0; r < 3; ++r)
        out[3ull * v + r] +=
            w * (m[4 * r] * p[0] + m[4 * r + 1] * p[1] + m[4 * r + 2] * p[2] + m[4 * r + 3]);
    }
  }
  return out;
}

std::vector<double> RefSkinPositions(const MeshArrays& mesh, const std::vector<double>& palette) {
  return RefSkinPoints(mesh, std::vector<double>(mesh.positions.begin(), mesh.positions.end()),
                       palette);
}

// The server's positions against the reference: each vertex within 2e-5 + 3e-4 (|rest| +
// |posed|) (the runtime's joints are within 0.01 mm + 1e-4 relative and its rotations'
// elements within 1e-4 of the float64 clip; float32 skinning adds rounding). A pose a
// thirtieth of a second off (one key) misses by millimetres.
// `scale`: the bound times this (a clip stored to a looser max_error_mm than the default).
void ExpectPositionsNear(const MeshArrays& mesh, const std::vector<float>& got,
                         const std::vector<double>& want, const std::string& what,
                         double scale = 1) {
  ASSERT_EQ(got.size(), want.size()) << what;
  double worst = 0;
  for (uint32_t v = 0; v < mesh.vertex_count; ++v) {
    double d2 = 0, rest2 = 0, posed2 = 0;
    for (int i = 0; i < 3; ++i) {
      const double d = got[3ull * v + i] - want[3ull * v + i];
      d2 += d * d;
      rest2 += double{mesh.positions[3ull * v + i]} * mesh.positions[3ull * v + i];
      posed2 += want[3ull * v + i] * want[3ull * v + i];
    }
    const double bound = scale * (2e-5 + 3e-4 * (std::sqrt(rest2) + std::sqrt(posed2)));
    worst = std::max(worst, std::sqrt(d2) / bound);
    if (std::sqrt(d2) > bound) {
      ADD_FAILURE() << what << ": vertex " << v << " off by " << std::sqrt(d2) << " (bound "
                    << bound << ")";
      return;
    }
  }
  ::testing::Test::RecordProperty(what, std::to_string(worst));
}

v1::PoseLayer* AddLayer(v1::Pose* pose, const std::string& clip, const Layer& l) {
  v1::PoseLayer* layer = pose->add_layers();
  layer->set_clip_id(clip);
  layer->set_time(static_cast<float>(l.time));
  layer->set_weight(static_cast<float>(l.weight));
  layer->set_loop(l.loop);
  return layer;
}

// One Skin call's answer: positions per character (a plain frame: character 0), the
// frame's status, and a tick's per-character headers.
struct Answer {
  Status status;
  std::map<uint32_t, std::vector<float>> positions;
  std::vector<v1::SkinResponse> headers;
};

Answer SkinRaw(client::SkinClient& c, const v1::SkinRequest& request) {
  Answer a;
  grpc::ClientContext context;
  auto reader = c.stub().Skin(&context, request);
  v1::SkinResponse part;
  while (reader->Read(&part)) {
    if (part.has_tick()) {  // a tick's final part: no vertex data
      a.headers.assign(part.tick().characters().begin(), part.tick().characters().end());
      continue;
    }
    std::vector<float>& out = a.positions[part.character()];
    out.resize(3ull * part.total_vertices() * std::max<uint32_t>(1, part.instances()));
    if (!part.positions().empty()) {
      std::memcpy(&out[3ull * part.first_vertex()], part.positions().data(),
                  part.positions().size());
    }
  }
  a.status = wire::FromGrpc(reader->Finish());
  return a;
}

struct Rig {
  PoseCase c;
  MeshArrays mesh;
  std::string skeleton_id, clip_id, mesh_id;
};

// Through the client library (SkinClient::UploadSkeleton, UploadClip).
Status UploadRig(client::SkinClient& client, const PoseCase& c, std::string* skeleton_id,
                 std::string* clip_id) {
  auto skeleton = client.UploadSkeleton(c.skeleton);
  if (!skeleton.ok()) return skeleton.status();
  *skeleton_id = skeleton->skeleton_id();
  auto clip = client.UploadClip(c.raw, *skeleton_id);
  if (!clip.ok()) return clip.status();
  *clip_id = clip->clip_id();
  return Status::Ok();
}

Rig MakeRig(client::SkinClient& client) {
  Rig rig{.c = SyntheticCase(kJoints),
          .mesh = MakeSyntheticMesh(
              {.vertex_count = 3000, .influences = 4, .joint_count = kJoints, .seed = 7})};
  EXPECT_TRUE(UploadRig(client, rig.c, &rig.skeleton_id, &rig.clip_id).ok());
  auto info = client.Upload(rig.mesh);
  EXPECT_TRUE(info.ok()) << info.status().ToString();
  if (info.ok()) rig.mesh_id = info->mesh_id();
  return rig;
}

v1::SkinRequest PoseRequest(const Rig& rig, const std::vector<Layer>& layers) {
  v1::SkinRequest request;
  request.set_mesh_id(rig.mesh_id);
  request.set_backend("serial");
  request.mutable_pose()->set_skeleton_id(rig.skeleton_id);
  for (const Layer& l : layers) AddLayer(request.mutable_pose(), rig.clip_id, l);
  return request;
}

// Writes `request` on `stream` and gathers its answer's positions (float32, every part).
void StreamFrame(grpc::ClientReaderWriter<v1::SkinRequest, v1::SkinResponse>& stream,
                 const v1::SkinRequest& request, uint32_t vertices, const std::string& what,
                 std::vector<float>* positions) {
  ASSERT_TRUE(stream.Write(request)) << what;
  positions->assign(3ull * vertices, 0.0f);
  v1::SkinResponse part;
  do {
    ASSERT_TRUE(stream.Read(&part)) << what;
    ASSERT_FALSE(part.has_error()) << what << ": " << part.error().message();
    ASSERT_LE(3ull * part.first_vertex() * sizeof(float) + part.positions().size(),
              positions->size() * sizeof(float))
        << what;
    std::memcpy(&(*positions)[3ull * part.first_vertex()], part.positions().data(),
                part.positions().size());
  } while (!part.last());
}

TEST(PoseServiceTest, PosesMatchTheFloat64EvaluationOfTheClip) {
  TestServer t;
  const Rig rig = MakeRig(*t.client);
  const double d = rig.c.ref_clip.duration;
  // One layer: on a key, between keys, before the clip, after it (clamped), looped past it.
  const std::vector<std::vector<Layer>> cases = {
      {{.time = 0.5}},
      {{.time = 0.7371}},
      {{.time = -0.3}},
      {{.time = d + 0.4}},
      {{.time = d + 0.61, .loop = true}},
      {{.time = 2 * d + 0.2137, .loop = true}},
      // Two and three layers of one clip at different times: weights normalised.
      {{.time = 0.25, .weight = 0.3}, {.time = 1.1, .weight = 0.9}},
      {{.time = 0.1, .weight = 2},
       {.time = d * 0.5, .weight = 1},
       {.time = d + 0.3123, .weight = 1, .loop = true}},
  };
  for (std::size_t i = 0; i < cases.size(); ++i) {
    const std::string what = "case " + std::to_string(i);
    const Answer a = SkinRaw(*t.client, PoseRequest(rig, cases[i]));
    ASSERT_TRUE(a.status.ok()) << what << ": " << a.status.ToString();
    ExpectPositionsNear(rig.mesh, a.positions.at(0),
                        RefSkinPositions(rig.mesh, RefBlendedPalette(rig.c, cases[i])), what);
  }
}

TEST(PoseServiceTest, StreamedPosesMatchTheReferenceOnEveryBackend) {
  TestServer t;
  const Rig rig = MakeRig(*t.client);
  auto backends = t.client->ListBackends();
  ASSERT_TRUE(backends.ok());
  for (const auto& b : backends->backends()) {
    if (!b.available() || b.id() == "passthrough") continue;
    grpc::ClientContext context;
    auto stream = t.client->stub().StreamSkin(&context);
    const std::vector<Layer> layers = {{.time = 0.4, .weight = 1},
                                       {.time = 2.3123, .weight = 3, .loop = true}};
    for (uint64_t f = 0; f < 3; ++f) {
      std::vector<Layer> at = layers;
      for (Layer& l : at) l.time += 0.1 * static_cast<double>(f);
      v1::SkinRequest request = PoseRequest(rig, at);
      request.set_backend(b.id());
      request.set_frame(f);
      std::vector<float> positions;
      ASSERT_NO_FATAL_FAILURE(
          StreamFrame(*stream, request, rig.mesh.vertex_count, b.id(), &positions));
      ExpectPositionsNear(rig.mesh, positions,
                          RefSkinPositions(rig.mesh, RefBlendedPalette(rig.c, at)),
                          b.id() + " frame " + std::to_string(f));
    }
    stream->WritesDone();
    EXPECT_TRUE(stream->Finish().ok());
  }
}

TEST(PoseServiceTest, ATickMixesPoseAndPaletteCharacters) {
  TestServer t;
  const Rig rig = MakeRig(*t.client);
  v1::SkinRequest tick;
  tick.set_frame(9);
  const std::vector<Layer> walk = {{.time = 0.9}};
  const std::vector<Layer> blend = {{.time = 0.2, .weight = 0.5}, {.time = 1.7, .weight = 0.5}};
  const std::vector<float> palette = MakeSyntheticPalette(kJoints, 3, 9);
  *tick.add_characters() = PoseRequest(rig, walk);
  v1::SkinRequest* plain = tick.add_characters();
  plain->set_mesh_id(rig.mesh_id);
  plain->set_backend("serial");
  plain->set_palette(wire::EncodeFloats(palette));
  *tick.add_characters() = PoseRequest(rig, blend);
  v1::SkinRequest bad = PoseRequest(rig, {{.time = 0.3, .weight = -1}});
  *tick.add_characters() = bad;
  const Answer a = SkinRaw(*t.client, tick);
  ASSERT_TRUE(a.status.ok()) << a.status.ToString();
  ASSERT_EQ(a.headers.size(), 4u);
  for (int c = 0; c < 3; ++c)
    EXPECT_FALSE(a.headers[c].has_error()) << a.headers[c].error().message();
  ExpectPositionsNear(rig.mesh, a.positions.at(0),
                      RefSkinPositions(rig.mesh, RefBlendedPalette(rig.c, walk)), "pose character");
  ExpectPositionsNear(rig.mesh, a.positions.at(2),
                      RefSkinPositions(rig.mesh, RefBlendedPalette(rig.c, blend)),
                      "blend character");
  const std::vector<double> palette64(palette.begin(), palette.end());
  ExpectPositionsNear(rig.mesh, a.positions.at(1), RefSkinPositions(rig.mesh, palette64),
                      "palette character");
  // The bad one failed alone, named.
  ASSERT_TRUE(a.headers[3].has_error());
  EXPECT_EQ(a.headers[3].error().code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_NE(a.headers[3].error().message().find("character 3: pose.layers[0].weight = -1"),
            std::string::npos)
      << a.headers[3].error().message();
}

// The same through the client library: Tick::AddPose beside Tick::Add, SkinTick, and
// SkinClient::SkinPose for one frame.
TEST(PoseServiceTest, TheClientLibrarySendsPoses) {
  TestServer t;
  const Rig rig = MakeRig(*t.client);
  const std::vector<client::PoseLayer> walk = {{.clip_id = rig.clip_id, .time = 0.9f}};
  const std::vector<client::PoseLayer> blend = {
      {.clip_id = rig.clip_id, .time = 0.2f, .weight = 1},
      {.clip_id = rig.clip_id, .time = 2.7123f, .weight = 3, .loop = true}};
  const std::vector<float> palette = MakeSyntheticPalette(kJoints, 4, 2);
  client::Tick tick;
  tick.set_frame(3);
  tick.AddPose(rig.mesh_id, {.skeleton_id = rig.skeleton_id, .layers = walk});
  tick.Add(rig.mesh_id, palette);
  tick.AddPose(rig.mesh_id, {.skeleton_id = rig.skeleton_id, .layers = blend});
  client::TickResult result;
  ASSERT_TRUE(t.client->SkinTick(tick, &result).ok()) << result.status.ToString();
  ASSERT_EQ(result.characters.size(), 3u);
  for (const auto& r : result.characters) ASSERT_TRUE(r.status.ok()) << r.status.ToString();
  ExpectPositionsNear(rig.mesh, result.characters[0].positions,
                      RefSkinPositions(rig.mesh, RefBlendedPalette(rig.c, {{.time = 0.9}})),
                      "client tick pose");
  const std::vector<double> palette64(palette.begin(), palette.end());
  ExpectPositionsNear(rig.mesh, result.characters[1].positions,
                      RefSkinPositions(rig.mesh, palette64), "client tick palette");
  const std::vector<Layer> blend_ref = {{.time = 0.2, .weight = 1},
                                        {.time = 2.7123, .weight = 3, .loop = true}};
  ExpectPositionsNear(rig.mesh, result.characters[2].positions,
                      RefSkinPositions(rig.mesh, RefBlendedPalette(rig.c, blend_ref)),
                      "client tick blend");
  client::FrameResult frame;
  ASSERT_TRUE(t.client
                  ->SkinPose(rig.mesh_id, {.skeleton_id = rig.skeleton_id, .layers = blend}, 5,
                             {.backend = "sse"}, &frame)
                  .ok())
      << frame.status.ToString();
  ExpectPositionsNear(rig.mesh, frame.positions,
                      RefSkinPositions(rig.mesh, RefBlendedPalette(rig.c, blend_ref)),
                      "client SkinPose");
  auto deleted = t.client->DeleteClip(rig.clip_id);
  ASSERT_TRUE(deleted.ok() && *deleted);
  const Status gone = t.client->SkinPose(
      rig.mesh_id, {.skeleton_id = rig.skeleton_id, .layers = walk}, 6, {}, &frame);
  EXPECT_EQ(gone.code(), StatusCode::kNotFound) << gone.ToString();
}

// Character i's layers in tick `frame` of PosedTickOnTwoThreads: one, two or three layers
// at times that differ from character to character and move on from tick to tick.
std::vector<Layer> CharacterLayers(uint32_t i, uint64_t frame, double duration) {
  const double t = 0.05 + 0.0313 * i + 0.1 * static_cast<double>(frame);
  switch (i % 3) {
    case 0:
      return {{.time = t}};
    case 1:
      return {{.time = t, .weight = 0.3}, {.time = duration - t, .weight = 0.9}};
    default:
      return {{.time = t, .weight = 2},
              {.time = 0.5 * t, .weight = 1},
              {.time = duration + 0.3123 + 0.0171 * i, .weight = 1, .loop = true}};
  }
}

// A tick's poses are evaluated on the compute threads that skin its characters
// (SkinJob::FillInputs), each character with its own scratch: a stream of ticks of 64
// posed characters on 2 compute threads, two ticks in flight, answers every character of
// every tick as the float64 evaluation of its own layers says.
TEST(PoseServiceTest, PosedTicksOnTwoComputeThreadsAnswerEveryCharacterRight) {
  server::ServerOptions options;
  options.threads = 2;
  TestServer t(options);
  const Rig rig = MakeRig(*t.client);
  constexpr uint32_t kCharacters = 64;
  constexpr uint64_t kTicks = 4;
  const double d = rig.c.ref_clip.duration;
  // What each tick sent: the client's layers (the Tick's spans point into them) and ours.
  std::vector<std::vector<std::vector<client::PoseLayer>>> sent(kTicks);
  std::vector<std::vector<std::vector<Layer>>> want(kTicks);
  uint64_t checked = 0;
  client::TickStreamSummary summary;
  const Status streamed = client::StreamTicks(
      *t.client, {.first_tick = 0, .ticks = kTicks, .window = 2},
      [&](uint64_t frame, client::Tick* tick) {
        sent[frame].assign(kCharacters, {});
        want[frame].assign(kCharacters, {});
        for (uint32_t i = 0; i < kCharacters; ++i) {
          want[frame][i] = CharacterLayers(i, frame, d);
          for (const Layer& l : want[frame][i]) {
            sent[frame][i].push_back({.clip_id = rig.clip_id,
                                      .time = static_cast<float>(l.time),
                                      .weight = static_cast<float>(l.weight),
                                      .loop = l.loop});
          }
          tick->AddPose(rig.mesh_id, {.skeleton_id = rig.skeleton_id, .layers = sent[frame][i]},
                        {.backend = "sse"});
        }
      },
      [&](client::TickResult& r, std::chrono::nanoseconds) {
        ASSERT_TRUE(r.status.ok()) << r.status.ToString();
        ASSERT_EQ(r.characters.size(), kCharacters);
        for (uint32_t i = 0; i < kCharacters; ++i) {
          const std::string what =
              "tick " + std::to_string(r.frame) + " character " + std::to_string(i);
          ASSERT_TRUE(r.characters[i].status.ok())
              << what << ": " << r.characters[i].status.ToString();
          ExpectPositionsNear(
              rig.mesh, r.characters[i].positions,
              RefSkinPositions(rig.mesh, RefBlendedPalette(rig.c, want[r.frame][i])), what);
          ++checked;
        }
      },
      &summary);
  ASSERT_TRUE(streamed.ok()) << streamed.ToString();
  EXPECT_EQ(checked, kTicks * kCharacters);
  EXPECT_EQ(summary.characters_failed, 0u);
}

void ExpectNamed(const Status& s, StatusCode code, const std::string& text) {
  EXPECT_EQ(s.code(), code) << s.ToString();
  EXPECT_NE(s.message().find(text), std::string::npos) << s.message();
}

// StreamFrames with StreamOptions::pose: a frame whose pose is set carries it (the palette
// source is not asked for it), a frame whose pose is empty carries the palette; every
// answer checked against the float64 reference of what that frame sent.
TEST(PoseServiceTest, StreamFramesSendsEachFramesPoseOrPalette) {
  TestServer t;
  const Rig rig = MakeRig(*t.client);
  const std::vector<float> palette = MakeSyntheticPalette(kJoints, 4, 2);
  const auto is_palette_frame = [](uint64_t f) { return f % 3 == 2; };
  // Off keys: the server's float32 time and the reference's agree on every STEP track.
  const auto time_of = [](uint64_t f) { return static_cast<float>(0.1371 * f + 0.05); };
  client::PoseLayer layer{.clip_id = rig.clip_id};
  client::StreamOptions options{
      .mesh_id = rig.mesh_id, .backend = "serial", .frames = 9, .window = 3};
  options.pose = [&](uint64_t f) {
    if (is_palette_frame(f)) return client::Pose{};
    layer.time = time_of(f);
    return client::Pose{.skeleton_id = rig.skeleton_id, .layers = {&layer, 1}};
  };
  std::vector<uint64_t> palettes_asked;
  std::map<uint64_t, std::vector<float>> got;
  client::StreamSummary summary;
  const Status s = client::StreamFrames(
      *t.client, options,
      [&](uint64_t f) {
        palettes_asked.push_back(f);
        return std::span<const float>(palette);
      },
      [&](client::FrameResult& r, std::chrono::nanoseconds) {
        EXPECT_TRUE(r.status.ok()) << "frame " << r.frame << ": " << r.status.ToString();
        got[r.frame] = r.positions;
      },
      &summary);
  ASSERT_TRUE(s.ok()) << s.ToString();
  EXPECT_EQ(summary.answered, 9u);
  EXPECT_EQ(palettes_asked, (std::vector<uint64_t>{2, 5, 8}));
  ASSERT_EQ(got.size(), 9u);
  const std::vector<double> palette64(palette.begin(), palette.end());
  for (const auto& [f, positions] : got) {
    const std::string what = "streamed frame " + std::to_string(f);
    ExpectPositionsNear(
        rig.mesh, positions,
        RefSkinPositions(rig.mesh, is_palette_frame(f)
                                       ? palette64
                                       : RefBlendedPalette(rig.c, {{.time = time_of(f)}})),
        what);
  }
  // A clip the server no longer holds: each pose frame fails NOT_FOUND naming it (after
  // the stream's re-uploads of the mesh, which cannot bring a clip back), none hangs.
  ASSERT_TRUE(*t.client->DeleteClip(rig.clip_id));
  options.frames = 2;
  options.pose = [&](uint64_t) {
    return client::Pose{.skeleton_id = rig.skeleton_id, .layers = {&layer, 1}};
  };
  std::vector<Status> failed;
  const Status gone = client::StreamFrames(
      *t.client, options, [&](uint64_t) { return std::span<const float>(palette); },
      [&](client::FrameResult& r, std::chrono::nanoseconds) { failed.push_back(r.status); });
  EXPECT_TRUE(gone.ok()) << gone.ToString();
  ASSERT_EQ(failed.size(), 2u);
  for (const Status& f : failed) {
    ExpectNamed(f, StatusCode::kNotFound, "pose.layers[0].clip_id '" + rig.clip_id + "'");
  }
}

// The status of a one-frame pose request after `edit`.
Status PoseStatus(client::SkinClient& client, const Rig& rig,
                  const std::function<void(v1::SkinRequest*)>& edit) {
  v1::SkinRequest request = PoseRequest(rig, {{.time = 0.5}, {.time = 1.0}});
  edit(&request);
  return SkinRaw(client, request).status;
}

// The server loses the clip, then the skeleton, mid-stream (deleted from its store, as a
// restart or a new replica would lose them): the client uploads the one each NOT_FOUND
// names again (the skeleton with its clips) and resends, and every frame of a stream of
// frames and of a stream of ticks is answered right against the float64 reference.
TEST(PoseServiceTest, StreamsUploadALostClipOrSkeletonAgain) {
  TestServer t;
  const Rig rig = MakeRig(*t.client);
  animation::AnimationStore& store = t.server->engine().animations();
  const auto time_of = [](uint64_t f) { return static_cast<float>(0.1371 * f + 0.05); };
  // A frame sent again is asked for again: each is lost once, the first time.
  std::set<uint64_t> asked;
  const auto lose = [&](uint64_t f) {
    if (!asked.insert(f).second) return;
    if (f == 3) {
      EXPECT_TRUE(store.DeleteClip(rig.clip_id));
    }
    if (f == 7) {
      EXPECT_TRUE(store.DeleteSkeleton(rig.skeleton_id));
    }
  };
  client::PoseLayer layer{.clip_id = rig.clip_id};
  client::StreamOptions options{
      .mesh_id = rig.mesh_id, .backend = "serial", .frames = 10, .window = 3};
  options.pose = [&](uint64_t f) {
    lose(f);
    layer.time = time_of(f);
    return client::Pose{.skeleton_id = rig.skeleton_id, .layers = {&layer, 1}};
  };
  std::map<uint64_t, std::vector<float>> got;
  client::StreamSummary summary;
  const Status s = client::StreamFrames(
      *t.client, options, [](uint64_t) { return std::span<const float>(); },
      [&](client::FrameResult& r, std::chrono::nanoseconds) {
        EXPECT_TRUE(r.status.ok()) << "frame " << r.frame << ": " << r.status.ToString();
        got[r.frame] = r.positions;
      },
      &summary);
  ASSERT_TRUE(s.ok()) << s.ToString();
  EXPECT_EQ(summary.answered, 10u);
  EXPECT_GE(summary.reuploads, 2u);
  ASSERT_EQ(got.size(), 10u);
  for (const auto& [f, positions] : got) {
    ExpectPositionsNear(
        rig.mesh, positions,
        RefSkinPositions(rig.mesh, RefBlendedPalette(rig.c, {{.time = time_of(f)}})),
        "streamed frame " + std::to_string(f));
  }
  // The same for a stream of ticks of 3 posed characters.
  asked.clear();
  std::vector<std::vector<client::PoseLayer>> layers(3);
  client::TickStreamSummary ticks;
  uint64_t checked = 0;
  const Status streamed = client::StreamTicks(
      *t.client, {.first_tick = 0, .ticks = 10, .window = 2},
      [&](uint64_t f, client::Tick* tick) {
        lose(f);
        for (uint32_t c = 0; c < 3; ++c) {
          layers[c] = {{.clip_id = rig.clip_id, .time = time_of(f + c)}};
          tick->AddPose(rig.mesh_id, {.skeleton_id = rig.skeleton_id, .layers = layers[c]},
                        {.backend = "serial"});
        }
      },
      [&](client::TickResult& r, std::chrono::nanoseconds) {
        ASSERT_TRUE(r.status.ok()) << r.status.ToString();
        ASSERT_EQ(r.characters.size(), 3u);
        for (uint32_t c = 0; c < 3; ++c) {
          const std::string what =
              "tick " + std::to_string(r.frame) + " character " + std::to_string(c);
          ASSERT_TRUE(r.characters[c].status.ok())
              << what << ": " << r.characters[c].status.ToString();
          ExpectPositionsNear(
              rig.mesh, r.characters[c].positions,
              RefSkinPositions(rig.mesh,
                               RefBlendedPalette(rig.c, {{.time = time_of(r.frame + c)}})),
              what);
          ++checked;
        }
      },
      &ticks);
  ASSERT_TRUE(streamed.ok()) << streamed.ToString();
  EXPECT_EQ(checked, 30u);
  EXPECT_EQ(ticks.characters_failed, 0u);
  EXPECT_GE(ticks.reuploads, 2u);
}

TEST(PoseServiceTest, BadPosesAreNamed) {
  TestServer t;
  const Rig rig = MakeRig(*t.client);
  auto& c = *t.client;
  ExpectNamed(PoseStatus(c, rig,
                         [](v1::SkinRequest* r) {
                           r->mutable_pose()->mutable_layers(1)->set_clip_id("nope");
                         }),
              StatusCode::kNotFound, "pose.layers[1].clip_id 'nope' is not stored");
  ExpectNamed(
      PoseStatus(c, rig,
                 [](v1::SkinRequest* r) { r->mutable_pose()->mutable_layers(0)->set_time(NAN); }),
      StatusCode::kInvalidArgument, "pose.layers[0].time = nan");
  ExpectNamed(PoseStatus(c, rig,
                         [](v1::SkinRequest* r) {
                           r->mutable_pose()->mutable_layers(0)->set_time(INFINITY);
                         }),
              StatusCode::kInvalidArgument, "pose.layers[0].time = inf");
  ExpectNamed(PoseStatus(c, rig,
                         [](v1::SkinRequest* r) {
                           r->mutable_pose()->mutable_layers(1)->set_weight(-0.5f);
                         }),
              StatusCode::kInvalidArgument, "pose.layers[1].weight = -0.5");
  ExpectNamed(
      PoseStatus(c, rig,
                 [](v1::SkinRequest* r) { r->mutable_pose()->mutable_layers(1)->set_weight(NAN); }),
      StatusCode::kInvalidArgument, "pose.layers[1].weight = nan");
  ExpectNamed(PoseStatus(c, rig,
                         [](v1::SkinRequest* r) {
                           r->mutable_pose()->mutable_layers(0)->set_weight(0);
                           r->mutable_pose()->mutable_layers(1)->set_weight(0);
                         }),
              StatusCode::kInvalidArgument,
              "pose.layers: the weights of the layers that are not additive sum to 0");
  ExpectNamed(
      PoseStatus(c, rig, [](v1::SkinRequest* r) { r->mutable_pose()->set_skeleton_id("nope"); }),
      StatusCode::kNotFound, "pose.skeleton_id 'nope' is not stored");
  ExpectNamed(PoseStatus(c, rig, [](v1::SkinRequest* r) { r->mutable_pose()->clear_layers(); }),
              StatusCode::kInvalidArgument, "pose.layers has 0 entries; 1..8");
  ExpectNamed(PoseStatus(c, rig,
                         [&](v1::SkinRequest* r) {
                           for (int i = 0; i < 8; ++i)
                             AddLayer(r->mutable_pose(), rig.clip_id, {.time = 0.1});
                         }),
              StatusCode::kInvalidArgument, "pose.layers has more than 8 entries");
  ExpectNamed(
      PoseStatus(c, rig,
                 [](v1::SkinRequest* r) { r->set_palette(std::string(48 * kJoints, '\0')); }),
      StatusCode::kInvalidArgument, "palette and pose are both set");
  ExpectNamed(PoseStatus(c, rig, [](v1::SkinRequest* r) { r->set_instances(2); }),
              StatusCode::kInvalidArgument, "pose is set with instances = 2");
  // A mesh of another joint count than the skeleton's palette.
  const MeshArrays other = MakeSyntheticMesh({.vertex_count = 100, .joint_count = 20, .seed = 3});
  auto other_info = c.Upload(other);
  ASSERT_TRUE(other_info.ok());
  ExpectNamed(
      PoseStatus(c, rig, [&](v1::SkinRequest* r) { r->set_mesh_id(other_info->mesh_id()); }),
      StatusCode::kInvalidArgument, "has a palette of 77 entries; mesh");
}

Status UploadClip(client::SkinClient& c, const v1::UploadClipRequest& clip, v1::ClipInfo* info) {
  grpc::ClientContext context;
  return wire::FromGrpc(c.stub().UploadClip(&context, clip, info));
}

TEST(PoseServiceTest, BadUploadsAreNamedAndStoreNothing) {
  TestServer t;
  const Rig rig = MakeRig(*t.client);
  auto& c = *t.client;
  v1::UploadSkeletonRequest skeleton;
  wire::SkeletonToWire(rig.c.skeleton, &skeleton);
  {
    v1::UploadSkeletonRequest bad = skeleton;
    const int16_t cycle = 5;
    std::memcpy(bad.mutable_parents()->data() + 2 * 3, &cycle, 2);  // joint 3's parent after it
    grpc::ClientContext context;
    v1::SkeletonInfo info;
    ExpectNamed(wire::FromGrpc(c.stub().UploadSkeleton(&context, bad, &info)),
                StatusCode::kInvalidArgument, "skeleton.parents[3] = 5");
    v1::UploadSkeletonRequest short_rest = skeleton;
    short_rest.mutable_rest()->resize(short_rest.rest().size() - 4);
    grpc::ClientContext context2;
    ExpectNamed(wire::FromGrpc(c.stub().UploadSkeleton(&context2, short_rest, &info)),
                StatusCode::kInvalidArgument, "rest holds");
  }
  v1::UploadClipRequest clip;
  wire::ClipToWire(rig.c.raw, rig.skeleton_id, &clip);
  v1::ClipInfo info;
  {
    v1::UploadClipRequest bad = clip;
    bad.mutable_tracks(4)->set_target(kJoints);
    ExpectNamed(UploadClip(c, bad, &info), StatusCode::kInvalidArgument,
                "tracks[4] (rotation).target = 77 is not a joint");
    bad = clip;
    const float nan = NAN;
    std::memcpy(bad.mutable_tracks(2)->mutable_values()->data() + 4, &nan, 4);
    ExpectNamed(UploadClip(c, bad, &info), StatusCode::kInvalidArgument,
                "tracks[2] (scale).values[1] is not finite");
    bad = clip;
    bad.mutable_tracks(1)->set_interpolation(static_cast<v1::ClipInterpolation>(9));
    ExpectNamed(UploadClip(c, bad, &info), StatusCode::kInvalidArgument,
                "tracks[1].interpolation = 9");
    bad = clip;
    bad.set_skeleton_id("nope");
    ExpectNamed(UploadClip(c, bad, &info), StatusCode::kNotFound, "skeleton_id 'nope'");
  }
  // The same clip again is stored once.
  ASSERT_TRUE(UploadClip(c, clip, &info).ok());
  EXPECT_TRUE(info.already_stored());
  EXPECT_EQ(info.clip_id(), rig.clip_id);
  // Stored at a quarter of its float bytes or less.
  EXPECT_LE(4 * info.bytes(), info.raw_bytes()) << info.bytes() << " of " << info.raw_bytes();
}

// UploadClipRequest.max_error_mm: the clip stored to that bound (ClipInfo says it and its
// bytes; another bound is another clip, smaller), posed by the server within the bound
// scaled as the clip's (the float64 reference of the ORIGINAL channels); a bound outside
// its limits refused naming the field and the limits, storing nothing.
TEST(PoseServiceTest, ClipsAreStoredToTheErrorAskedFor) {
  TestServer t;
  Rig rig = MakeRig(*t.client);
  auto& c = *t.client;
  v1::UploadClipRequest clip;
  wire::ClipToWire(rig.c.raw, rig.skeleton_id, &clip);
  v1::ClipInfo standard, loose;
  ASSERT_TRUE(UploadClip(c, clip, &standard).ok());
  EXPECT_TRUE(standard.already_stored()) << "MakeRig stored it at the default bound";
  EXPECT_FLOAT_EQ(standard.max_error_mm(), 0.01f);
  clip.set_max_error_mm(0.1f);
  ASSERT_TRUE(UploadClip(c, clip, &loose).ok());
  EXPECT_FALSE(loose.already_stored());
  EXPECT_FLOAT_EQ(loose.max_error_mm(), 0.1f);
  EXPECT_NE(loose.clip_id(), standard.clip_id());
  EXPECT_EQ(loose.raw_bytes(), standard.raw_bytes());
  EXPECT_LT(loose.bytes(), standard.bytes());
  std::printf("clip stored to 0.01 mm: %llu bytes, to 0.1 mm: %llu (of %llu float bytes)\n",
              static_cast<unsigned long long>(standard.bytes()),
              static_cast<unsigned long long>(loose.bytes()),
              static_cast<unsigned long long>(loose.raw_bytes()));
  rig.clip_id = loose.clip_id();
  for (const std::vector<Layer>& layers :
       std::vector<std::vector<Layer>>{{{.time = 0.7371}}, {{.time = 2.61, .loop = true}}}) {
    const Answer a = SkinRaw(c, PoseRequest(rig, layers));
    ASSERT_TRUE(a.status.ok()) << a.status.ToString();
    ExpectPositionsNear(rig.mesh, a.positions.at(0),
                        RefSkinPositions(rig.mesh, RefBlendedPalette(rig.c, layers)),
                        "stored to 0.1 mm", 0.1 / 0.01);
  }
  auto stats = c.GetServerStats();
  ASSERT_TRUE(stats.ok());
  for (float bad : {-1.0f, 0.001f, 11.0f, NAN}) {
    clip.set_max_error_mm(bad);
    ExpectNamed(UploadClip(c, clip, &loose), StatusCode::kInvalidArgument,
                "must be 0 (the default, 0.01 mm) or within [0.01, 10] mm");
    ExpectNamed(UploadClip(c, clip, &loose), StatusCode::kInvalidArgument, "max_error_mm = ");
  }
  auto after = c.GetServerStats();
  ASSERT_TRUE(after.ok());
  EXPECT_EQ(after->clips(), stats->clips());
  EXPECT_EQ(after->clip_bytes(), stats->clip_bytes());
}

// The C++ client passes the bound through (SkinClient::UploadClip's max_error_mm).
TEST(PoseServiceTest, TheClientLibraryAsksForTheClipsError) {
  TestServer t;
  const PoseCase pc = SyntheticCase(kJoints);
  auto skeleton = t.client->UploadSkeleton(pc.skeleton);
  ASSERT_TRUE(skeleton.ok()) << skeleton.status().ToString();
  auto standard = t.client->UploadClip(pc.raw, skeleton->skeleton_id());
  auto loose = t.client->UploadClip(pc.raw, skeleton->skeleton_id(), 1.0f);
  ASSERT_TRUE(standard.ok() && loose.ok()) << loose.status().ToString();
  EXPECT_FLOAT_EQ(standard->max_error_mm(), 0.01f);
  EXPECT_FLOAT_EQ(loose->max_error_mm(), 1.0f);
  EXPECT_LT(loose->bytes(), standard->bytes());
  auto bad = t.client->UploadClip(pc.raw, skeleton->skeleton_id(), 50.0f);
  ExpectNamed(bad.status(), StatusCode::kInvalidArgument, "max_error_mm = 50");
}

// GetServerStats reports the animation store: what is held, the bytes the uploads said
// they were charged (SkeletonInfo.bytes + ClipInfo.bytes), and the budget asked for; the
// same content again changes nothing, a deleted clip gives its bytes back.
TEST(PoseServiceTest, ServerStatsReportTheAnimationStore) {
  server::ServerOptions options;
  options.clip_budget_mb = 3;
  TestServer t(options);
  auto& c = *t.client;
  const auto expect_store = [&](uint64_t skeletons, uint64_t clips, uint64_t bytes,
                                const std::string& when) {
    auto stats = c.GetServerStats();
    ASSERT_TRUE(stats.ok()) << stats.status().ToString();
    EXPECT_EQ(stats->skeletons(), skeletons) << when;
    EXPECT_EQ(stats->clips(), clips) << when;
    EXPECT_EQ(stats->clip_bytes(), bytes) << when;
    EXPECT_EQ(stats->clip_budget_bytes(), 3u << 20) << when;
  };
  expect_store(0, 0, 0, "empty");
  const PoseCase pc = SyntheticCase(kJoints);
  auto skeleton = c.UploadSkeleton(pc.skeleton);
  ASSERT_TRUE(skeleton.ok()) << skeleton.status().ToString();
  auto clip = c.UploadClip(pc.raw, skeleton->skeleton_id());
  ASSERT_TRUE(clip.ok()) << clip.status().ToString();
  ASSERT_GT(skeleton->bytes(), 0u);
  ASSERT_GT(clip->bytes(), 0u);
  const uint64_t both = skeleton->bytes() + clip->bytes();
  expect_store(1, 1, both, "a skeleton and a clip");
  auto again = c.UploadClip(pc.raw, skeleton->skeleton_id());
  ASSERT_TRUE(again.ok() && again->already_stored());
  expect_store(1, 1, both, "the same clip again");
  auto deleted = c.DeleteClip(clip->clip_id());
  ASSERT_TRUE(deleted.ok() && *deleted);
  expect_store(1, 0, skeleton->bytes(), "the clip deleted");
}

TEST(PoseServiceTest, ClipsOverTheBudgetAreRefusedWhole) {
  server::ServerOptions options;
  options.clip_budget_mb = 1;
  TestServer t(options);
  auto& c = *t.client;
  // Distinct rigs (a seed each) until the budget refuses one.
  std::vector<std::string> clips;
  Status refused;
  PoseCase refused_case;
  for (uint32_t seed = 1; seed < 200 && refused.ok(); ++seed) {
    PoseCase pc;
    const animation::SyntheticRig synthetic = animation::MakeSyntheticRig(kJoints, seed, 4.0f);
    pc.skeleton = synthetic.skeleton;
    pc.raw = synthetic.clip;
    std::string skeleton_id, clip_id;
    refused = UploadRig(c, pc, &skeleton_id, &clip_id);
    if (refused.ok()) clips.push_back(clip_id);
    refused_case = pc;
  }
  ASSERT_FALSE(refused.ok()) << "1 MiB held " << clips.size() << " clips";
  ASSERT_GE(clips.size(), 2u);
  ExpectNamed(refused, StatusCode::kResourceExhausted, "--clip-budget-mb");
  // Nothing of the refused clip is held: deleting two stored clips (of about its size)
  // makes room for it.
  for (int i = 0; i < 2; ++i) {
    grpc::ClientContext context;
    v1::DeleteClipRequest del;
    del.set_clip_id(clips[static_cast<std::size_t>(i)]);
    v1::DeleteClipResponse deleted;
    ASSERT_TRUE(c.stub().DeleteClip(&context, del, &deleted).ok());
    EXPECT_TRUE(deleted.deleted());
  }
  std::string skeleton_id, clip_id;
  const Status again = UploadRig(c, refused_case, &skeleton_id, &clip_id);
  EXPECT_TRUE(again.ok()) << again.ToString();
}

// The synthetic clip's weights track (LINEAR, 4 weights a key, group 0) on a mesh with 4
// morph targets: the server samples it, blends the layers' weights and morphs the mesh
// before skinning it. The reference: tests/animation's float64 evaluation of the track.
constexpr uint32_t kMorphTargets = 4;

// The layers' weights blended as the joints are (normalised by the weights' sum), in double.
std::vector<double> RefBlendedWeights(const PoseCase& c, const std::vector<Layer>& layers) {
  double total = 0;
  for (const Layer& l : layers) total += l.weight;
  std::vector<double> out(kMorphTargets, 0.0);
  for (const Layer& l : layers) {
    double t = static_cast<float>(l.time);  // the time the server gets
    if (l.loop) t -= c.ref_clip.duration * std::floor(t / c.ref_clip.duration);
    const std::vector<double> w = RefWeightsAt(c, t);
    for (uint32_t m = 0; m < kMorphTargets; ++m) out[m] += l.weight / total * w.at(m);
  }
  return out;
}

// The mesh's rest positions with its targets' deltas times `weights`, in double.
std::vector<double> RefMorphedRest(const MeshArrays& mesh, const std::vector<double>& weights) {
  std::vector<double> p(mesh.positions.begin(), mesh.positions.end());
  std::size_t d = 0;
  for (std::size_t t = 0; t < mesh.morph_target_sizes.size(); ++t) {
    for (uint32_t i = 0; i < mesh.morph_target_sizes[t]; ++i, ++d) {
      for (int c = 0; c < 3; ++c)
        p[3ull * mesh.morph_indices[d] + c] += weights[t] * mesh.morph_position_deltas[3 * d + c];
    }
  }
  return p;
}

// MakeRig's skeleton and clip on a mesh with `targets` morph targets.
Rig MakeMorphRig(client::SkinClient& client, uint32_t targets = kMorphTargets) {
  Rig rig{.c = SyntheticCase(kJoints),
          .mesh = MakeSyntheticMesh(
              {.vertex_count = 3000, .influences = 4, .joint_count = kJoints, .seed = 7})};
  AddSyntheticMorphTargets({.targets = targets, .fraction = 0.3, .seed = 3}, &rig.mesh);
  EXPECT_EQ(rig.c.weights.size(), 1u);  // the synthetic clip's one weights track
  EXPECT_TRUE(UploadRig(client, rig.c, &rig.skeleton_id, &rig.clip_id).ok());
  auto info = client.Upload(rig.mesh);
  EXPECT_TRUE(info.ok()) << info.status().ToString();
  if (info.ok()) rig.mesh_id = info->mesh_id();
  return rig;
}

TEST(PoseServiceTest, AClipsWeightsTrackMorphsTheMesh) {
  TestServer t;
  const Rig m = MakeMorphRig(*t.client);
  const double d = m.c.ref_clip.duration;
  const std::vector<std::vector<Layer>> cases = {
      {{.time = 0}},
      {{.time = 0.41 * d}},
      {{.time = d + 0.4}},
      {{.time = 2 * d + 0.2137, .loop = true}},
      {{.time = 0.25, .weight = 0.3}, {.time = 0.8 * d, .weight = 0.9}},
  };
  for (std::size_t i = 0; i < cases.size(); ++i) {
    const std::string what = "morph case " + std::to_string(i);
    const Answer a = SkinRaw(*t.client, PoseRequest(m, cases[i]));
    ASSERT_TRUE(a.status.ok()) << what << ": " << a.status.ToString();
    const std::vector<double> rest = RefMorphedRest(m.mesh, RefBlendedWeights(m.c, cases[i]));
    ExpectPositionsNear(m.mesh, a.positions.at(0),
                        RefSkinPoints(m.mesh, rest, RefBlendedPalette(m.c, cases[i])), what);
  }
}

// The same through a tick (two characters at two times) and a stream on every backend that
// applies morph targets, whose frames reuse their job (the weights of the frame before must
// not linger).
TEST(PoseServiceTest, AClipsWeightsTrackMorphsTicksAndStreams) {
  TestServer t;
  const Rig m = MakeMorphRig(*t.client);
  const double d = m.c.ref_clip.duration;
  const auto want = [&](const std::vector<Layer>& layers) {
    return RefSkinPoints(m.mesh, RefMorphedRest(m.mesh, RefBlendedWeights(m.c, layers)),
                         RefBlendedPalette(m.c, layers));
  };
  v1::SkinRequest tick;
  tick.set_frame(3);
  const std::vector<Layer> early = {{.time = 0.13 * d}}, late = {{.time = 0.77 * d}};
  *tick.add_characters() = PoseRequest(m, early);
  *tick.add_characters() = PoseRequest(m, late);
  const Answer a = SkinRaw(*t.client, tick);
  ASSERT_TRUE(a.status.ok()) << a.status.ToString();
  ASSERT_EQ(a.headers.size(), 2u);
  for (const auto& h : a.headers) EXPECT_FALSE(h.has_error()) << h.error().message();
  ExpectPositionsNear(m.mesh, a.positions.at(0), want(early), "tick character 0");
  ExpectPositionsNear(m.mesh, a.positions.at(1), want(late), "tick character 1");

  auto backends = t.client->ListBackends();
  ASSERT_TRUE(backends.ok());
  std::set<std::string> streamed;
  for (const auto& b : backends->backends()) {
    if (!b.available() || !b.morph_targets() || b.id() == "passthrough") continue;
    streamed.insert(b.id());
    grpc::ClientContext context;
    auto stream = t.client->stub().StreamSkin(&context);
    for (uint64_t f = 0; f < 3; ++f) {
      const std::vector<Layer> at = {{.time = 0.2 * d + 0.3 * static_cast<double>(f)}};
      v1::SkinRequest request = PoseRequest(m, at);
      request.set_backend(b.id());
      request.set_frame(f);
      std::vector<float> positions;
      ASSERT_NO_FATAL_FAILURE(
          StreamFrame(*stream, request, m.mesh.vertex_count, b.id(), &positions));
      ExpectPositionsNear(m.mesh, positions, want(at), b.id() + " frame " + std::to_string(f));
    }
    stream->WritesDone();
    EXPECT_TRUE(stream->Finish().ok());
  }
  EXPECT_TRUE(streamed.contains("serial"));
  std::string ids;
  for (const std::string& id : streamed) ids += " " + id;
  ::testing::Test::RecordProperty("morph backends", ids);
  std::printf("streamed morph poses on:%s\n", ids.c_str());
}

TEST(PoseServiceTest, WeightsTracksAreCheckedAgainstTheMeshAndTheRequest) {
  TestServer t;
  const Rig m = MakeMorphRig(*t.client);
  // The clip's 4 weights on a mesh of 5 targets: named with the clip, its track and both
  // counts.
  MeshArrays five =
      MakeSyntheticMesh({.vertex_count = 300, .influences = 4, .joint_count = kJoints, .seed = 8});
  AddSyntheticMorphTargets({.targets = 5, .fraction = 0.3, .seed = 4}, &five);
  auto uploaded = t.client->Upload(five);
  ASSERT_TRUE(uploaded.ok()) << uploaded.status().ToString();
  Rig other = m;
  other.mesh_id = uploaded->mesh_id();
  Answer a = SkinRaw(*t.client, PoseRequest(other, {{.time = 0.3}}));
  EXPECT_EQ(a.status.code(), StatusCode::kInvalidArgument);
  const std::string message = a.status.message();
  EXPECT_NE(message.find("pose.layers[0].clip_id '" + m.clip_id + "'"), std::string::npos)
      << message;
  EXPECT_NE(message.find("samples 4 morph weights"), std::string::npos) << message;
  EXPECT_NE(message.find("(group 0): 4 weights"), std::string::npos) << message;
  EXPECT_NE(message.find("has 5 morph targets"), std::string::npos) << message;
  // Weights from the clip and from the request: refused, both named.
  v1::SkinRequest both = PoseRequest(m, {{.time = 0.3}});
  both.add_morph_targets(1);
  both.add_morph_weights(0.5f);
  a = SkinRaw(*t.client, both);
  EXPECT_EQ(a.status.code(), StatusCode::kInvalidArgument);
  EXPECT_NE(a.status.message().find("morph_targets / morph_weights are set"), std::string::npos)
      << a.status.message();
  EXPECT_NE(a.status.message().find("has weights tracks"), std::string::npos) << a.status.message();
  // A clip without weights tracks still takes the request's weights on a morph mesh.
  Rig joints_only = m;
  PoseCase c = m.c;
  std::erase_if(c.raw.tracks, [](const animation::RawTrack& track) {
    return track.path == animation::TrackPath::kWeights;
  });
  ASSERT_TRUE(UploadRig(*t.client, c, &joints_only.skeleton_id, &joints_only.clip_id).ok());
  v1::SkinRequest given = PoseRequest(joints_only, {{.time = 0.3}});
  given.add_morph_targets(2);
  given.add_morph_weights(0.75f);
  a = SkinRaw(*t.client, given);
  ASSERT_TRUE(a.status.ok()) << a.status.ToString();
  std::vector<double> w(kMorphTargets, 0.0);
  w[2] = 0.75;
  ExpectPositionsNear(
      m.mesh, a.positions.at(0),
      RefSkinPoints(m.mesh, RefMorphedRest(m.mesh, w), RefBlendedPalette(m.c, {{.time = 0.3}})),
      "request weights");
}

}  // namespace
}  // namespace skinserve::testing
