// The rasteriser behind RenderPng: triangles in pixel coordinates into a colour and depth
// buffer, nearest sample wins. Perspective-correct: 1/depth and attribute/depth vary
// linearly across the screen, so depth and normals are interpolated as in 3D.
#pragma once

#include <cstdint>
#include <vector>

#include <glm/vec3.hpp>

namespace skinserve::render {

struct RasterVertex {
  float x = 0.0f, y = 0.0f;  // in samples (pixels * samples per side), y down
  float depth = 0.0f;        // > 0, along the view direction
  glm::vec3 normal{0.0f};    // the shading normal at this corner (unit, facing the viewer)
};

class DepthRaster {
 public:
  DepthRaster(int width, int height, const glm::vec3& background);

  // Fills the samples whose centres lie inside the triangle (edges included) and are
  // nearer than what is there, with colour = shade(interpolated normal).
  template <typename Shade>
  void Triangle(const RasterVertex& a, const RasterVertex& b, const RasterVertex& c,
                const Shade& shade);

  int width() const { return width_; }
  int height() const { return height_; }
  const glm::vec3& at(int x, int y) const { return color_[Index(x, y)]; }

 private:
  std::size_t Index(int x, int y) const {
    return static_cast<std::size_t>(y) * static_cast<std::size_t>(width_) +
           static_cast<std::size_t>(x);
  }
  int width_, height_;
  std::vector<glm::vec3> color_;
  std::vector<float> inverse_depth_;  // 1 / depth; 0 = nothing drawn (infinitely far)
};

}  // namespace skinserve::render

#include "depth_raster_inl.h"
