// The check of --draw's picture against the float64 reference: the reference's skinned
// positions projected with the draw's transform must each land on or next to a drawn
// pixel, and the
// drawn pixels must lie near a projected position (a picture of something else, an empty
// one or one of a stale buffer fails).
#pragma once

#include <cstdint>
#include <span>
#include <string>

#include "skinserve/model/status.h"
#include "vertex_renderer.h"

namespace skinserve::gpu_region {

struct PictureCheck {
  uint64_t drawn_pixels = 0;     // not the background
  double points_on_drawn = 0;    // of the projected positions inside the image
  double drawn_near_points = 0;  // of the drawn pixels, within `radius` of one
  bool ok() const {
    return drawn_pixels > 0 && points_on_drawn >= 0.99 && drawn_near_points >= 0.99;
  }
  std::string ToString() const;
};

// `rgba` as VertexRenderer::Draw returns it; `positions` x y z per vertex, in double;
// `radius` in pixels (the point size and rounding).
PictureCheck CheckPicture(std::span<const uint8_t> rgba, uint32_t width, uint32_t height,
                          std::span<const double> positions, const Transform& transform,
                          int radius = 2);

// --draw's verdict on a picture of the reference (`normals` empty: none): with `indices`
// (triangles) CheckTrianglePicture, without them (points) CheckPicture. The summary is
// the check's ToString.
struct PictureVerdict {
  bool ok = false;
  std::string summary;
};
PictureVerdict JudgePicture(std::span<const uint8_t> rgba, uint32_t width, uint32_t height,
                            std::span<const double> positions, std::span<const double> normals,
                            std::span<const uint32_t> indices, const Transform& transform);

}  // namespace skinserve::gpu_region
