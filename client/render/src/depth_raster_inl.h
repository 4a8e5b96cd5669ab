// DepthRaster::Triangle, a template on the shading function (inlined per caller).
#pragma once

#include <algorithm>
#include <cmath>

#include <glm/geometric.hpp>

namespace skinserve::render {

inline DepthRaster::DepthRaster(int width, int height, const glm::vec3& background)
    : width_(width),
      height_(height),
      color_(static_cast<std::size_t>(width) * static_cast<std::size_t>(height), background),
      inverse_depth_(color_.size(), 0.0f) {}

template <typename Shade>
void DepthRaster::Triangle(const RasterVertex& a, const RasterVertex& b, const RasterVertex& c,
                           const Shade& shade) {
  // Twice the signed area; the sign is the winding on screen, which only orients the edge
  // tests here (facing was decided in 3D by the caller).
  const float area = (b.x - a.x) * (c.y - a.y) - (b.y - a.y) * (c.x - a.x);
  if (!(std::fabs(area) > 0.0f)) return;
  const float inverse_area = 1.0f / area;
  const int x0 = std::max(0, static_cast<int>(std::floor(std::min({a.x, b.x, c.x}))));
  const int x1 = std::min(width_ - 1, static_cast<int>(std::ceil(std::max({a.x, b.x, c.x}))));
  const int y0 = std::max(0, static_cast<int>(std::floor(std::min({a.y, b.y, c.y}))));
  const int y1 = std::min(height_ - 1, static_cast<int>(std::ceil(std::max({a.y, b.y, c.y}))));
  const float iza = 1.0f / a.depth, izb = 1.0f / b.depth, izc = 1.0f / c.depth;
  for (int y = y0; y <= y1; ++y) {
    const float py = static_cast<float>(y) + 0.5f;
    for (int x = x0; x <= x1; ++x) {
      const float px = static_cast<float>(x) + 0.5f;
      // Barycentric weights of the sample: each edge function over the whole area.
      const float wa = ((b.x - px) * (c.y - py) - (b.y - py) * (c.x - px)) * inverse_area;
      const float wb = ((c.x - px) * (a.y - py) - (c.y - py) * (a.x - px)) * inverse_area;
      const float wc = ((a.x - px) * (b.y - py) - (a.y - py) * (b.x - px)) * inverse_area;
      if (wa < 0.0f || wb < 0.0f || wc < 0.0f) continue;
      const float inverse_depth = wa * iza + wb * izb + wc * izc;
      const std::size_t i = Index(x, y);
      if (!(inverse_depth > inverse_depth_[i])) continue;  // farther than what is there
      inverse_depth_[i] = inverse_depth;
      const glm::vec3 normal =
          (a.normal * (wa * iza) + b.normal * (wb * izb) + c.normal * (wc * izc)) / inverse_depth;
      const float length = glm::length(normal);
      color_[i] = shade(length > 0.0f ? normal / length : a.normal);
    }
  }
}

}  // namespace skinserve::render
