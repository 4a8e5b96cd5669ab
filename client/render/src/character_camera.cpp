#include "skinserve/render/character_camera.h"

#include <limits>

#include <glm/common.hpp>

#include "skinserve/model/palette.h"
#include "skinserve/render/contact_sheet.h"

namespace skinserve::render {

Result<Camera> CharacterCamera(const Character& character, std::span<const CharacterMesh> meshes,
                               std::span<const Pose> poses, int width, int height,
                               const CameraOptions& options) {
  if (meshes.empty() || poses.empty()) {
    return InvalidArgument("camera: a character's camera needs a mesh and a pose");
  }
  glm::dvec3 lo(std::numeric_limits<double>::max()), hi(-std::numeric_limits<double>::max());
  for (const Pose& pose : poses) {
    for (const CharacterMesh& mesh : meshes) {
      auto palette = MeshPalette(character, pose, mesh);
      if (!palette.ok()) return palette.status();
      const MeshArrays& a = mesh.arrays;
      const std::size_t b = a.influences;
      // Linear blend skinning of positions, as the server does it (palette.h: row-major 3x4).
      for (std::size_t v = 0; v < a.vertex_count; ++v) {
        glm::dvec3 q(0.0);
        for (std::size_t i = 0; i < b; ++i) {
          const double w = a.weights[v * b + i];
          if (w == 0.0) continue;
          const float* m = &(*palette)[kFloatsPerJoint * a.joints[v * b + i]];
          for (int r = 0; r < 3; ++r) {
            q[r] += w * (m[4 * r] * double{a.positions[3 * v]} +
                         m[4 * r + 1] * double{a.positions[3 * v + 1]} +
                         m[4 * r + 2] * double{a.positions[3 * v + 2]} + m[4 * r + 3]);
          }
        }
        lo = glm::min(lo, q);
        hi = glm::max(hi, q);
      }
    }
  }
  if (!(lo.x <= hi.x)) return InvalidArgument("camera: the character has no vertex");
  return Camera::Framing(Bounds{glm::vec3(lo), glm::vec3(hi)}, width, height, options);
}

std::vector<Pose> ClipPoses(const Character& character, const AnimationClip& clip, double fps,
                            uint64_t frames, std::size_t count) {
  std::vector<std::size_t> picked = EvenlySpaced(frames, count > 1 ? count - 1 : 1);
  if (frames > 0 && (picked.empty() || picked.back() != frames - 1)) picked.push_back(frames - 1);
  std::vector<Pose> poses;
  for (std::size_t f : picked) {
    poses.push_back(SampleClip(character, clip, static_cast<double>(f) / fps));
  }
  return poses;
}

}  // namespace skinserve::render
