// Reads a PNG back with Cairo for the render tests: its size and its pixels as RGB.
#pragma once

#include <cairo.h>

#include <cstdint>
#include <string>
#include <vector>

namespace skinserve::testing {

struct Pixels {
  int width = 0;
  int height = 0;
  std::vector<uint32_t> rgb;  // 0xRRGGBB, row-major; empty when the file could not be read
  uint32_t at(int x, int y) const { return rgb[static_cast<std::size_t>(y) * width + x]; }
};

inline Pixels ReadPng(const std::string& path) {
  Pixels p;
  cairo_surface_t* s = cairo_image_surface_create_from_png(path.c_str());
  if (cairo_surface_status(s) == CAIRO_STATUS_SUCCESS) {
    cairo_surface_flush(s);
    p.width = cairo_image_surface_get_width(s);
    p.height = cairo_image_surface_get_height(s);
    const int stride = cairo_image_surface_get_stride(s);
    const unsigned char* data = cairo_image_surface_get_data(s);
    for (int y = 0; y < p.height; ++y) {
      const auto* row =
          reinterpret_cast<const uint32_t*>(data + static_cast<std::size_t>(y) * stride);
      for (int x = 0; x < p.width; ++x) p.rgb.push_back(row[x] & 0xFFFFFFu);
    }
  }
  cairo_surface_destroy(s);
  return p;
}

}  // namespace skinserve::testing
