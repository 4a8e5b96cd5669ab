#include "skinserve/render/character_camera.h"

#include <vector>

#include "skinserve/core/character/animation.h"
#include "skinserve/core/reference.h"

namespace skinserve::render {

Result<Camera> RestPoseCamera(const Character& character, const SkinnedPrimitive& primitive,
                              int width, int height, const CameraOptions& options) {
  auto palette = SkinPalette(character, RestPose(character), primitive.skin);
  if (!palette.ok()) return palette.status();
  auto mesh = Mesh::Create(primitive.arrays);
  if (!mesh.ok()) return mesh.status();
  const ReferenceFrame rest = ReferenceSkin(**mesh, *palette);
  const std::vector<float> positions(rest.positions.begin(), rest.positions.end());
  auto bounds = BoundsOf(positions);
  if (!bounds.ok()) return bounds.status();
  return Camera::Framing(*bounds, width, height, options);
}

}  // namespace skinserve::render
