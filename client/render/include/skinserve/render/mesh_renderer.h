// Off-screen images of a deformed frame: Cairo fills the triangles (no rasteriser of our
// own), sorted back to front (painter's algorithm), each flat-shaded by Lambert's law
// from its own normal and a light fixed to the camera.
#pragma once

#include <cstdint>
#include <span>
#include <string>

#include <glm/vec3.hpp>

#include "skinserve/core/status.h"
#include "skinserve/render/camera.h"

namespace skinserve::render {

struct RenderOptions {
  glm::vec3 background{0.95f, 0.95f, 0.93f};  // RGB, 0..1
  glm::vec3 color{0.85f, 0.60f, 0.40f};       // the surface's albedo
  float ambient = 0.3f;                       // light that reaches faces turned away
  // Skip triangles seen from behind (glTF's front faces wind counter-clockwise): fewer
  // to sort, and none of the painter's algorithm's mistakes on the far side.
  bool cull_back_faces = true;
  std::string label;  // drawn in the top-left corner when not empty
};

// Renders the triangles `indices` over `positions` (x y z per vertex) from `camera` into
// a camera.width() x camera.height() PNG at `path`. Triangles with a corner at or behind
// the eye, or with no area, are skipped. INVALID_ARGUMENT for arrays that disagree or a
// position that is not finite; INTERNAL with Cairo's reason when drawing or writing fails.
Status RenderPng(const std::string& path, const Camera& camera, std::span<const float> positions,
                 std::span<const uint32_t> indices, const RenderOptions& options = {});

}  // namespace skinserve::render
