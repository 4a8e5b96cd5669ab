#include "draw_check.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <vector>

#include "triangle_check.h"

namespace skinserve::gpu_region {

std::string PictureCheck::ToString() const {
  return fmt::format(
      "{} pixels drawn; {:.2f}% of the reference's projected positions on or next to a drawn "
      "pixel, "
      "{:.2f}% of the drawn pixels near one (each must be >= 99%)",
      drawn_pixels, 100 * points_on_drawn, 100 * drawn_near_points);
}

PictureCheck CheckPicture(std::span<const uint8_t> rgba, uint32_t width, uint32_t height,
                          std::span<const double> positions, const Transform& t, int radius) {
  const auto drawn = [&](int64_t x, int64_t y) {
    const uint8_t* p = rgba.data() + 4 * (static_cast<std::size_t>(y) * width + x);
    return !std::equal(p, p + 3, VertexRenderer::kBackground.begin());
  };
  std::vector<uint8_t> near(static_cast<std::size_t>(width) * height, 0);
  uint64_t inside = 0, on_drawn = 0;
  for (std::size_t v = 0; v + 2 < positions.size(); v += 3) {
    const double x = positions[v], y = positions[v + 1], z = positions[v + 2];
    // Clip space by the column-major transform, then pixel centres (Vulkan: y down).
    const double cx = t[0] * x + t[4] * y + t[8] * z + t[12];
    const double cy = t[1] * x + t[5] * y + t[9] * z + t[13];
    const double cw = t[3] * x + t[7] * y + t[11] * z + t[15];
    const int64_t px = static_cast<int64_t>(std::floor((cx / cw + 1) / 2 * width));
    const int64_t py = static_cast<int64_t>(std::floor((cy / cw + 1) / 2 * height));
    if (px < 0 || py < 0 || px >= width || py >= height) continue;
    ++inside;
    // A position on a pixel's edge may be rasterised into its neighbour.
    bool hit = false;
    for (int64_t y0 = std::max<int64_t>(0, py - 1); y0 <= std::min<int64_t>(height - 1, py + 1);
         ++y0) {
      for (int64_t x0 = std::max<int64_t>(0, px - 1); x0 <= std::min<int64_t>(width - 1, px + 1);
           ++x0) {
        hit = hit || drawn(x0, y0);
      }
    }
    if (hit) ++on_drawn;
    for (int64_t y0 = std::max<int64_t>(0, py - radius);
         y0 <= std::min<int64_t>(height - 1, py + radius); ++y0) {
      for (int64_t x0 = std::max<int64_t>(0, px - radius);
           x0 <= std::min<int64_t>(width - 1, px + radius); ++x0) {
        near[y0 * width + x0] = 1;
      }
    }
  }
  PictureCheck check;
  uint64_t drawn_near = 0;
  for (uint32_t y = 0; y < height; ++y) {
    for (uint32_t x = 0; x < width; ++x) {
      if (!drawn(x, y)) continue;
      ++check.drawn_pixels;
      if (near[static_cast<std::size_t>(y) * width + x]) ++drawn_near;
    }
  }
  check.points_on_drawn = inside > 0 ? static_cast<double>(on_drawn) / inside : 0;
  check.drawn_near_points =
      check.drawn_pixels > 0 ? static_cast<double>(drawn_near) / check.drawn_pixels : 0;
  return check;
}

PictureVerdict JudgePicture(std::span<const uint8_t> rgba, uint32_t width, uint32_t height,
                            std::span<const double> positions, std::span<const double> normals,
                            std::span<const uint32_t> indices, const Transform& transform) {
  if (indices.empty()) {
    const PictureCheck c = CheckPicture(rgba, width, height, positions, transform);
    return {c.ok(), c.ToString()};
  }
  const TrianglePictureCheck c =
      CheckTrianglePicture(rgba, width, height, positions, normals, indices, transform);
  return {c.ok(), c.ToString()};
}

}  // namespace skinserve::gpu_region
