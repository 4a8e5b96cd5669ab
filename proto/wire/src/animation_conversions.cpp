#include "skinserve/wire/animation_conversions.h"

#include <fmt/format.h>

#include <algorithm>
#include <cstring>

namespace skinserve::wire {
namespace {

using animation::Interpolation;
using animation::TrackPath;

// Little-endian bytes of `field` into `count` values of T; INVALID_ARGUMENT naming the
// field when the byte count is not count values.
template <typename T>
Status DecodeExactly(const std::string& bytes, const std::string& field, std::size_t count,
                     const char* what, T* out) {
  if (bytes.size() != count * sizeof(T)) {
    return InvalidArgument(fmt::format("{} holds {} bytes; {} takes {} ({} values of {} bytes)",
                                       field, bytes.size(), what, count * sizeof(T), count,
                                       sizeof(T)));
  }
  if (count > 0) std::memcpy(out, bytes.data(), bytes.size());
  return Status::Ok();
}

template <typename T>
void Encode(const T* values, std::size_t count, std::string* bytes) {
  bytes->assign(reinterpret_cast<const char*>(values), count * sizeof(T));
}

Result<TrackPath> PathFromWire(v1::ClipPath path, const std::string& field) {
  switch (path) {
    case v1::CLIP_PATH_TRANSLATION:
      return TrackPath::kTranslation;
    case v1::CLIP_PATH_ROTATION:
      return TrackPath::kRotation;
    case v1::CLIP_PATH_SCALE:
      return TrackPath::kScale;
    case v1::CLIP_PATH_WEIGHTS:
      return TrackPath::kWeights;
    default:
      return InvalidArgument(fmt::format(
          "{} = {} is unknown; known: 0 (translation), 1 (rotation), 2 (scale), 3 (weights)", field,
          static_cast<int>(path)));
  }
}

Result<Interpolation> InterpolationFromWire(v1::ClipInterpolation interpolation,
                                            const std::string& field) {
  switch (interpolation) {
    case v1::CLIP_INTERPOLATION_LINEAR:
      return Interpolation::kLinear;
    case v1::CLIP_INTERPOLATION_STEP:
      return Interpolation::kStep;
    case v1::CLIP_INTERPOLATION_CUBICSPLINE:
      return Interpolation::kCubicSpline;
    default:
      return InvalidArgument(
          fmt::format("{} = {} is unknown; known: 0 (linear), 1 (step), 2 (cubicspline)", field,
                      static_cast<int>(interpolation)));
  }
}

Status TrackFromWire(const v1::ClipTrack& wire, int index, animation::RawTrack* track) {
  const std::string name = fmt::format("tracks[{}]", index);
  Result<TrackPath> path = PathFromWire(wire.path(), name + ".path");
  if (!path.ok()) return path.status();
  Result<Interpolation> interpolation =
      InterpolationFromWire(wire.interpolation(), name + ".interpolation");
  if (!interpolation.ok()) return interpolation.status();
  track->path = *path;
  track->interpolation = *interpolation;
  track->target = wire.target();
  track->width = wire.width();
  for (const auto& [bytes, field, out] :
       {std::tuple{&wire.times(), name + ".times", &track->times},
        std::tuple{&wire.values(), name + ".values", &track->values}}) {
    if (bytes->size() % sizeof(float) != 0) {
      return InvalidArgument(fmt::format("{} holds {} bytes, not a whole number of float32 values",
                                         field, bytes->size()));
    }
    out->resize(bytes->size() / sizeof(float));
    if (!bytes->empty()) std::memcpy(out->data(), bytes->data(), bytes->size());
  }
  return Status::Ok();
}

v1::ClipPath PathToWire(TrackPath path) {
  switch (path) {
    case TrackPath::kRotation:
      return v1::CLIP_PATH_ROTATION;
    case TrackPath::kScale:
      return v1::CLIP_PATH_SCALE;
    case TrackPath::kWeights:
      return v1::CLIP_PATH_WEIGHTS;
    default:
      return v1::CLIP_PATH_TRANSLATION;
  }
}

v1::ClipInterpolation InterpolationToWire(Interpolation interpolation) {
  switch (interpolation) {
    case Interpolation::kStep:
      return v1::CLIP_INTERPOLATION_STEP;
    case Interpolation::kCubicSpline:
      return v1::CLIP_INTERPOLATION_CUBICSPLINE;
    default:
      return v1::CLIP_INTERPOLATION_LINEAR;
  }
}

}  // namespace

Result<animation::Skeleton> SkeletonFromWire(const v1::UploadSkeletonRequest& request) {
  animation::Skeleton s;
  const std::size_t joints = request.parents().size() / sizeof(int16_t);
  if (request.parents().size() % sizeof(int16_t) != 0 || joints == 0 ||
      joints > animation::kMaxSkeletonJoints) {
    return InvalidArgument(
        fmt::format("parents holds {} bytes; 1..{} joints of 2 bytes (int16) are supported",
                    request.parents().size(), animation::kMaxSkeletonJoints));
  }
  s.parents.resize(joints);
  s.rest.resize(joints);
  static_assert(sizeof(animation::Transform) == 10 * sizeof(float));
  if (Status st = DecodeExactly(request.parents(), "parents", joints, "parents", s.parents.data());
      !st.ok()) {
    return st;
  }
  if (Status st = DecodeExactly(request.rest(), "rest", joints * 10,
                                "10 float32 a joint (translation, rotation, scale)",
                                reinterpret_cast<float*>(s.rest.data()));
      !st.ok()) {
    return st;
  }
  if (request.names_size() != 0 && static_cast<std::size_t>(request.names_size()) != joints) {
    return InvalidArgument(fmt::format("names has {} entries for {} joints (none, or one a joint)",
                                       request.names_size(), joints));
  }
  s.names.assign(request.names().begin(), request.names().end());
  const std::size_t entries = request.palette_joints().size() / sizeof(uint16_t);
  if (request.palette_joints().size() % sizeof(uint16_t) != 0 || entries == 0) {
    return InvalidArgument(
        fmt::format("palette_joints holds {} bytes; at least one palette entry of 2 bytes (uint16)",
                    request.palette_joints().size()));
  }
  s.palette_joints.resize(entries);
  s.inverse_bind.resize(entries);
  std::memcpy(s.palette_joints.data(), request.palette_joints().data(), entries * 2);
  static_assert(sizeof(animation::Affine) == 12 * sizeof(float));
  if (Status st = DecodeExactly(request.inverse_bind(), "inverse_bind", entries * 12,
                                "12 float32 a palette entry",
                                reinterpret_cast<float*>(s.inverse_bind.data()));
      !st.ok()) {
    return st;
  }
  return s;
}

void SkeletonToWire(const animation::Skeleton& s, v1::UploadSkeletonRequest* request) {
  Encode(s.parents.data(), s.parents.size(), request->mutable_parents());
  Encode(reinterpret_cast<const float*>(s.rest.data()), s.rest.size() * 10,
         request->mutable_rest());
  request->mutable_names()->Assign(s.names.begin(), s.names.end());
  Encode(s.palette_joints.data(), s.palette_joints.size(), request->mutable_palette_joints());
  Encode(reinterpret_cast<const float*>(s.inverse_bind.data()), s.inverse_bind.size() * 12,
         request->mutable_inverse_bind());
}

Result<animation::RawClip> ClipFromWire(const v1::UploadClipRequest& request) {
  if (request.tracks_size() == 0 || request.tracks_size() > kMaxClipTracks) {
    return InvalidArgument(fmt::format("tracks has {} entries; 1..{} are supported",
                                       request.tracks_size(), kMaxClipTracks));
  }
  animation::RawClip clip;
  clip.name = request.name();
  clip.tracks.resize(static_cast<std::size_t>(request.tracks_size()));
  float last = 0;
  for (int i = 0; i < request.tracks_size(); ++i) {
    animation::RawTrack& track = clip.tracks[static_cast<std::size_t>(i)];
    if (Status s = TrackFromWire(request.tracks(i), i, &track); !s.ok()) return s;
    if (!track.times.empty()) last = std::max(last, track.times.back());
  }
  clip.duration = request.duration() == 0 ? last : request.duration();
  return clip;
}

void ClipToWire(const animation::RawClip& clip, const std::string& skeleton_id,
                v1::UploadClipRequest* request) {
  request->set_skeleton_id(skeleton_id);
  request->set_name(clip.name);
  request->set_duration(clip.duration);
  request->clear_tracks();
  for (const animation::RawTrack& t : clip.tracks) {
    v1::ClipTrack* track = request->add_tracks();
    track->set_path(PathToWire(t.path));
    track->set_interpolation(InterpolationToWire(t.interpolation));
    track->set_target(t.target);
    track->set_width(t.width);
    Encode(t.times.data(), t.times.size(), track->mutable_times());
    Encode(t.values.data(), t.values.size(), track->mutable_values());
  }
}

}  // namespace skinserve::wire
