// Off-screen images of a deformed frame. Our own small rasteriser with a per-pixel depth
// buffer (Cairo cannot depth-test): every triangle is drawn whatever the order, and where
// triangles overlap or cross the nearer surface wins pixel by pixel. Shading is Lambert
// with a light fixed to the camera: smooth (per pixel, from the vertex normals) when a part
// has normals, flat from each triangle's own normal otherwise. 2 x 2 samples per pixel
// smooth the edges; Cairo writes the PNG and draws the label.
#pragma once

#include <cstdint>
#include <span>
#include <string>

#include <glm/vec3.hpp>

#include "skinserve/model/status.h"
#include "skinserve/render/camera.h"

namespace skinserve::render {

struct RenderOptions {
  glm::vec3 background{0.95f, 0.95f, 0.93f};  // RGB, 0..1
  glm::vec3 color{0.85f, 0.60f, 0.40f};       // the surface's albedo
  float ambient = 0.3f;                       // light that reaches faces turned away
  // Skip triangles seen from behind (glTF's front faces wind counter-clockwise). Off by
  // default: the depth buffer hides a closed mesh's far side anyway, and an open one (a
  // cape, a single-sided sheet) stays visible from behind, lit as its visible side.
  bool cull_back_faces = false;
  int samples_per_side = 2;  // supersampling: samples_per_side^2 depth samples per pixel
  std::string label;         // drawn in the top-left corner when not empty
};

// One mesh of a frame: x y z per vertex, normals empty or x y z per vertex, triangles.
struct RenderPart {
  std::span<const float> positions;
  std::span<const float> normals;
  std::span<const uint32_t> indices;
};

// Renders every part's triangles from `camera` into one camera.width() x camera.height()
// PNG at `path`, sharing one depth buffer. Triangles with a corner at or behind the eye, or
// with no area, are skipped. INVALID_ARGUMENT for arrays that disagree (naming the part
// when there are several) or a position that is not finite, or samples_per_side outside
// 1..4; INTERNAL with Cairo's reason when writing fails.
Status RenderPng(const std::string& path, const Camera& camera, std::span<const RenderPart> parts,
                 const RenderOptions& options = {});

// One part without normals (flat shading).
Status RenderPng(const std::string& path, const Camera& camera, std::span<const float> positions,
                 std::span<const uint32_t> indices, const RenderOptions& options = {});

}  // namespace skinserve::render
