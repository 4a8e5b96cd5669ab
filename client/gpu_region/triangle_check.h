// The check of --draw's picture of a mesh with faces (--mesh) against the float64
// reference: the reference's skinned triangles, projected with the draw's transform and
// rasterised here in double, must be what the picture shows.
//  - covered: pixels whose centre lies inside a reference triangle (by 0.05 px: float32
//    rounding; the GPU covers exactly the pixels whose centre a triangle holds) are drawn
//    (a missing triangle set, a wrong pose or a picture of something else leaves some
//    background);
//  - nothing else: drawn pixels have their centre within 0.5 px of a reference triangle;
//  - the vertices: each projected reference vertex is on or next to a drawn pixel;
//  - shading (with normals): where one reference triangle is clearly the nearest (holding
//    the centre by 0.05 px, no other within 0.1% of the depth range there), the pixel has
//    the colour shaders/draw.frag gives the reference's interpolated normal, within 4 of 255
//    per channel (a mirrored picture, or one drawn without the depth test, shows other
//    normals there).
// Pixel centres are sampled as Vulkan does (x right, y down, (i + 0.5) per pixel).
#pragma once

#include <cstdint>
#include <span>
#include <string>

#include "vertex_renderer.h"

namespace skinserve::gpu_region {

struct TrianglePictureCheck {
  uint64_t drawn_pixels = 0;   // not the background
  uint64_t inside_pixels = 0;  // centre inside a reference triangle
  double inside_drawn = 0;     // of those, drawn
  double drawn_near = 0;       // of the drawn pixels, within 0.5 px of a reference triangle
  double points_on_drawn = 0;  // of the projected vertices inside the image
  uint64_t shaded_pixels = 0;  // compared with the reference's shade (0 without normals)
  double shade_matches = 0;    // of those, within 4 of 255 per channel
  bool normals = false;
  bool ok() const;
  std::string ToString() const;
};

// `rgba` as VertexRenderer::Draw returns it; `positions` (and `normals`, empty: none) x y z
// per vertex of the reference, in double; `indices` a triangle list into them.
TrianglePictureCheck CheckTrianglePicture(std::span<const uint8_t> rgba, uint32_t width,
                                          uint32_t height, std::span<const double> positions,
                                          std::span<const double> normals,
                                          std::span<const uint32_t> indices,
                                          const Transform& transform);

// The colour shaders/draw.frag gives normal (x, y, z), 0-255 per channel (its formula,
// restated: the check and the tests compare pictures with it).
std::array<double, 3> ReferenceShade(double x, double y, double z);

}  // namespace skinserve::gpu_region
