// Animations: translation, rotation, scale and weights channels with their samplers' keys.
#include <fmt/format.h>
#include <algorithm>
#include <cmath>
#include <cstddef>

#include "gltf_accessor.h"
#include "gltf_parts.h"

namespace skinserve::gltf {
namespace {

Result<Interpolation> ParseInterpolation(const std::string& name, const std::string& what) {
  if (name.empty() || name == "LINEAR") return Interpolation::kLinear;  // the spec's default
  if (name == "STEP") return Interpolation::kStep;
  if (name == "CUBICSPLINE") return Interpolation::kCubicSpline;
  return InvalidArgument(
      fmt::format("{}.interpolation is \"{}\"; expected LINEAR, STEP or CUBICSPLINE", what, name));
}

Status ReadTimes(const tinygltf::Model& model, int accessor, const std::string& what,
                 std::vector<float>* times) {
  auto input = AccessorReader::Open(model, accessor, what, TINYGLTF_TYPE_SCALAR,
                                    {TINYGLTF_COMPONENT_TYPE_FLOAT});
  if (!input.ok()) return input.status();
  times->resize(input->count());
  for (std::size_t k = 0; k < input->count(); ++k) {
    const float t = input->Normalized(k, 0);
    if (!std::isfinite(t) || t < 0.0f) {
      return InvalidArgument(
          fmt::format("{}: key {} is at {} s; key times must be finite and >= 0", what, k, t));
    }
    if (k > 0 && !(t > (*times)[k - 1])) {
      return InvalidArgument(fmt::format(
          "{}: key {} is at {} s, not after key {} at {} s; key times must strictly increase", what,
          k, t, k - 1, (*times)[k - 1]));
    }
    (*times)[k] = t;
  }
  return Status::Ok();
}

Status ReadValues(const tinygltf::Model& model, int accessor, const std::string& what,
                  ChannelPath path, std::size_t expected_count, std::vector<float>* values) {
  // Rotations and weights may be stored as normalized integers (spec, "Animations"); the
  // accessor converts them to floats per the spec's formulas.
  const bool rotation = path == ChannelPath::kRotation;
  auto output = path == ChannelPath::kWeights
                    ? AccessorReader::Open(
                          model, accessor, what, TINYGLTF_TYPE_SCALAR,
                          {TINYGLTF_COMPONENT_TYPE_FLOAT, TINYGLTF_COMPONENT_TYPE_BYTE,
                           TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE, TINYGLTF_COMPONENT_TYPE_SHORT,
                           TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT})
                : rotation
                    ? AccessorReader::Open(
                          model, accessor, what, TINYGLTF_TYPE_VEC4,
                          {TINYGLTF_COMPONENT_TYPE_FLOAT, TINYGLTF_COMPONENT_TYPE_BYTE,
                           TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE, TINYGLTF_COMPONENT_TYPE_SHORT,
                           TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT})
                    : AccessorReader::Open(model, accessor, what, TINYGLTF_TYPE_VEC3,
                                           {TINYGLTF_COMPONENT_TYPE_FLOAT});
  if (!output.ok()) return output.status();
  if (output->count() != expected_count) {
    return InvalidArgument(fmt::format("{}: accessor {} has {} values; the sampler needs {}", what,
                                       accessor, output->count(), expected_count));
  }
  const int components = output->components();
  values->resize(output->count() * static_cast<std::size_t>(components));
  for (std::size_t k = 0; k < output->count(); ++k) {
    for (int c = 0; c < components; ++c) {
      const float v = output->Normalized(k, c);
      if (!std::isfinite(v)) {
        return InvalidArgument(fmt::format("{}: value {} component {} is not finite", what, k, c));
      }
      (*values)[k * static_cast<std::size_t>(components) + static_cast<std::size_t>(c)] = v;
    }
  }
  return Status::Ok();
}

Result<AnimationClip> ImportClip(const tinygltf::Model& model, std::size_t index,
                                 const std::vector<CharacterNode>& nodes) {
  const tinygltf::Animation& animation = model.animations[index];
  const std::string what = fmt::format("animations[{}]", index);
  AnimationClip clip;
  clip.name = animation.name;
  for (std::size_t c = 0; c < animation.channels.size(); ++c) {
    const tinygltf::AnimationChannel& in = animation.channels[c];
    const std::string channel_what = fmt::format("{}.channels[{}]", what, c);
    AnimationChannel channel;
    if (in.target_path == "weights") {
      channel.path = ChannelPath::kWeights;
    } else if (in.target_path == "translation") {
      channel.path = ChannelPath::kTranslation;
    } else if (in.target_path == "rotation") {
      channel.path = ChannelPath::kRotation;
    } else if (in.target_path == "scale") {
      channel.path = ChannelPath::kScale;
    } else {
      return InvalidArgument(
          fmt::format("{}.target.path is \"{}\"; expected translation, rotation, scale or weights",
                      channel_what, in.target_path));
    }
    // The spec lets an extension name the target instead of target.node; none that this
    // importer knows does, so such a channel animates nothing here.
    if (in.target_node < 0) continue;
    if (static_cast<std::size_t>(in.target_node) >= model.nodes.size()) {
      return InvalidArgument(fmt::format("{}.target.node = {} is not a node (the file has {})",
                                         channel_what, in.target_node, model.nodes.size()));
    }
    channel.node = in.target_node;
    // Weights: one value per morph target of the node's mesh, per key.
    const std::size_t per_key =
        channel.path == ChannelPath::kWeights
            ? (static_cast<std::size_t>(in.target_node) < nodes.size()
                   ? nodes[static_cast<std::size_t>(in.target_node)].weights.size()
                   : 0)
            : 1;
    // A weights channel of a node whose mesh has no targets animates nothing (exporters
    // write such channels): skipped, as before morph targets were imported.
    if (per_key == 0) continue;
    if (in.sampler < 0 || static_cast<std::size_t>(in.sampler) >= animation.samplers.size()) {
      return InvalidArgument(fmt::format("{}.sampler = {} is not a sampler of {} (it has {})",
                                         channel_what, in.sampler, what,
                                         animation.samplers.size()));
    }
    const tinygltf::AnimationSampler& sampler =
        animation.samplers[static_cast<std::size_t>(in.sampler)];
    const std::string sampler_what = fmt::format("{}.samplers[{}]", what, in.sampler);
    auto interpolation = ParseInterpolation(sampler.interpolation, sampler_what);
    if (!interpolation.ok()) return interpolation.status();
    channel.interpolation = *interpolation;
    if (Status s = ReadTimes(model, sampler.input, sampler_what + ".input", &channel.times);
        !s.ok()) {
      return s;
    }
    const bool cubic = channel.interpolation == Interpolation::kCubicSpline;
    if (cubic && channel.times.size() < 2) {
      return InvalidArgument(fmt::format("{}.input: CUBICSPLINE needs at least 2 keys; it has {}",
                                         sampler_what, channel.times.size()));
    }
    const std::size_t expected = channel.times.size() * (cubic ? 3 : 1) * per_key;
    if (Status s = ReadValues(model, sampler.output, sampler_what + ".output", channel.path,
                              expected, &channel.values);
        !s.ok()) {
      return s;
    }
    clip.duration = std::max(clip.duration, channel.times.back());
    clip.channels.push_back(std::move(channel));
  }
  return clip;
}

}  // namespace

Result<std::vector<AnimationClip>> ImportClips(const tinygltf::Model& model,
                                               const std::vector<CharacterNode>& nodes) {
  std::vector<AnimationClip> clips;
  for (std::size_t i = 0; i < model.animations.size(); ++i) {
    auto clip = ImportClip(model, i, nodes);
    if (!clip.ok()) return clip.status();
    clips.push_back(std::move(clip).value());
  }
  return clips;
}

}  // namespace skinserve::gltf
