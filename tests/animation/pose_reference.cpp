#include "pose_reference.h"

#include <algorithm>
#include <cmath>
#include <set>

#include "skinserve/animation/local_to_model_job.h"
#include "skinserve/animation/palette_job.h"
#include "skinserve/animation/synthetic_rig.h"
#include "skinserve/character/gltf_import.h"
#include "skinserve/character/rig.h"

namespace skinserve::testing {
namespace {

Mat4 FromAffine(const animation::Affine& a) {
  Mat4 m{};
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 4; ++c) m[static_cast<std::size_t>(4 * c + r)] = a.m[4 * r + c];
  m[15] = 1;
  return m;
}

const char* InterpolationName(animation::Interpolation i) {
  return i == animation::Interpolation::kStep     ? "STEP"
         : i == animation::Interpolation::kLinear ? "LINEAR"
                                                  : "CUBICSPLINE";
}

std::vector<RefWeights> ReadWeights(const Glb& glb, std::size_t clip) {
  std::vector<RefWeights> out;
  const nlohmann::json& a = glb.json["animations"][clip];
  for (const nlohmann::json& ch : a["channels"]) {
    if (ch["target"]["path"] != "weights") continue;
    const nlohmann::json& sampler = a["samplers"][ch["sampler"].get<std::size_t>()];
    RefWeights w;
    w.target = ch["target"]["node"];
    w.interpolation = sampler.value("interpolation", "LINEAR");
    w.times = ReadAccessor(glb, sampler["input"]);
    w.values = ReadAccessor(glb, sampler["output"]);
    w.width = w.values.size() / w.times.size() / (w.interpolation == "CUBICSPLINE" ? 3 : 1);
    out.push_back(std::move(w));
  }
  return out;
}

}  // namespace

PoseCase AssetCase(const std::string& file, std::size_t clip) {
  PoseCase c;
  c.label = file;
  const Glb glb = ParseGlb(ReadBytes(AssetPath(file)));
  c.ref = ReadReference(glb);
  c.ref_clip = c.ref.clips.at(clip);
  c.weights = ReadWeights(glb, clip);
  auto character = LoadGltfFile(AssetPath(file));
  EXPECT_TRUE(character.ok()) << character.status().ToString();
  if (!character.ok()) return c;
  auto rig = RigFromSkin(*character, 0);
  EXPECT_TRUE(rig.ok()) << rig.status().ToString();
  if (!rig.ok()) return c;
  c.skeleton = rig->skeleton;
  c.nodes = rig->nodes;
  c.raw = RawClipFromCharacter(character->clips.at(clip), *rig);
  return c;
}

PoseCase SyntheticCase(uint32_t joints) {
  PoseCase c;
  c.label = "synthetic" + std::to_string(joints);
  const animation::SyntheticRig rig = animation::MakeSyntheticRig(joints);
  c.skeleton = rig.skeleton;
  c.raw = rig.clip;
  for (uint32_t j = 0; j < joints; ++j) {
    const animation::Transform& t = rig.skeleton.rest[j];
    RefNode n;
    n.parent = rig.skeleton.parents[j];
    std::copy_n(t.translation, 3, n.t);
    std::copy_n(t.rotation, 4, n.r);
    std::copy_n(t.scale, 3, n.s);
    c.ref.nodes.push_back(n);
    c.nodes.push_back(static_cast<int>(j));
  }
  for (std::size_t p = 0; p < rig.skeleton.palette_size(); ++p) {
    c.ref.joints.push_back(rig.skeleton.palette_joints[p]);
    c.ref.inverse_bind.push_back(FromAffine(rig.skeleton.inverse_bind[p]));
  }
  c.ref_clip.duration = rig.clip.duration;
  for (const animation::RawTrack& t : rig.clip.tracks) {
    if (t.path == animation::TrackPath::kWeights) {
      c.weights.push_back(RefWeights{static_cast<int>(t.target),
                                     InterpolationName(t.interpolation),
                                     t.width,
                                     {t.times.begin(), t.times.end()},
                                     {t.values.begin(), t.values.end()}});
      continue;
    }
    RefChannel ch;
    ch.node = static_cast<int>(t.target);
    ch.path = t.path == animation::TrackPath::kTranslation ? "translation"
              : t.path == animation::TrackPath::kRotation  ? "rotation"
                                                           : "scale";
    ch.interpolation = InterpolationName(t.interpolation);
    ch.times.assign(t.times.begin(), t.times.end());
    ch.values.assign(t.values.begin(), t.values.end());
    c.ref_clip.channels.push_back(std::move(ch));
  }
  return c;
}

RuntimePose RunPose(const PoseCase& c, const animation::CompactClip& clip, float time,
                    animation::TimeMode mode, animation::SamplingContext* context) {
  RuntimePose pose;
  std::vector<animation::Transform> local(c.skeleton.joint_count());
  pose.model.resize(c.skeleton.joint_count());
  pose.palette.resize(12 * c.skeleton.palette_size());
  pose.weights.resize(clip.weight_count);
  const animation::SamplingJob sampling{&c.skeleton, &clip,        time,   mode,
                                        local,       pose.weights, context};
  EXPECT_TRUE(sampling.Run().ok());
  const animation::LocalToModelJob ltm{&c.skeleton, local, pose.model};
  EXPECT_TRUE(ltm.Run().ok());
  const animation::PaletteJob palette{&c.skeleton, pose.model, pose.palette};
  EXPECT_TRUE(palette.Run().ok());
  return pose;
}

std::vector<double> RefModel(const PoseCase& c, double t) {
  RefCharacter joints = c.ref;  // model matrices: the skeleton's nodes with identity binds
  joints.joints = c.nodes;
  Mat4 identity{};
  identity[0] = identity[5] = identity[10] = identity[15] = 1;
  joints.inverse_bind.assign(c.nodes.size(), identity);
  std::vector<double> out = RefPalette(joints, &c.ref_clip, t);
  const std::vector<double> palette = RefPalette(c.ref, &c.ref_clip, t);
  out.insert(out.end(), palette.begin(), palette.end());
  return out;
}

std::vector<double> RefWeightsAt(const PoseCase& c, double t) {
  std::vector<double> out;
  for (const RefWeights& w : c.weights) {
    const bool cubic = w.interpolation == "CUBICSPLINE";
    const std::size_t n = w.width, keys = w.times.size();
    auto at = [&](std::size_t k, std::size_t part, std::size_t i) {
      return w.values[(cubic ? 3 * k + part : k) * n + i];
    };
    for (std::size_t i = 0; i < n; ++i) {
      double v;
      if (t <= w.times.front()) {
        v = at(0, 1, i);
      } else if (t >= w.times.back()) {
        v = at(keys - 1, 1, i);
      } else {
        std::size_t k = 0;
        while (!(w.times[k] <= t && t < w.times[k + 1])) ++k;
        const double d = w.times[k + 1] - w.times[k], u = (t - w.times[k]) / d;
        if (w.interpolation == "STEP") {
          v = at(k, 1, i);
        } else if (!cubic) {
          v = at(k, 1, i) + u * (at(k + 1, 1, i) - at(k, 1, i));
        } else {
          v = (2 * u * u * u - 3 * u * u + 1) * at(k, 1, i) +
              (u * u * u - 2 * u * u + u) * d * at(k, 2, i) +
              (-2 * u * u * u + 3 * u * u) * at(k + 1, 1, i) +
              (u * u * u - u * u) * d * at(k + 1, 0, i);
        }
      }
      out.push_back(v);
    }
  }
  return out;
}

double RotationAngle(const float* a, const double* b) {
  double la = 0, lb = 0, dot = 0;
  for (int c = 0; c < 4; ++c) {
    la += double{a[c]} * a[c];
    lb += b[c] * b[c];
    dot += double{a[c]} * b[c];
  }
  const double sign = dot < 0 ? -1 : 1;
  double d2 = 0;
  for (int c = 0; c < 4; ++c) {
    const double d = a[c] / std::sqrt(la) - sign * b[c] / std::sqrt(lb);
    d2 += d * d;
  }
  return 4 * std::asin(std::min(1.0, std::sqrt(d2) / 2));
}

std::size_t GltfFloatBytes(const animation::RawClip& raw) {
  std::set<std::vector<float>> times;
  std::size_t bytes = 0;
  for (const animation::RawTrack& t : raw.tracks) {
    times.insert(t.times);
    bytes += 4 * t.values.size();
  }
  for (const std::vector<float>& t : times) bytes += 4 * t.size();
  return bytes;
}

std::vector<double> SampleTimes(const PoseCase& c) {
  const double d = c.ref_clip.duration;
  std::vector<double> times = {-0.25, 0.0, d, d + 0.5};
  for (const RefChannel& ch : c.ref_clip.channels) {
    for (std::size_t k = 0; k + 1 < ch.times.size();
         k += std::max<std::size_t>(1, ch.times.size() / 9)) {
      times.push_back(ch.times[k]);
      times.push_back(ch.times[k] + 0.37 * (ch.times[k + 1] - ch.times[k]));
      times.push_back(0.5 * (ch.times[k] + ch.times[k + 1]));
    }
  }
  for (int i = 1; i < 24; ++i) times.push_back(d * i / 23.7);
  std::sort(times.begin(), times.end());
  times.erase(std::unique(times.begin(), times.end()), times.end());
  return times;
}

}  // namespace skinserve::testing
