// RGBA8 pixels to a PNG file with libpng (--draw's picture).
#pragma once

#include <cstdint>
#include <span>
#include <string>

#include "skinserve/model/status.h"

namespace skinserve::gpu_region {

// `rgba` holds width * height * 4 bytes, rows from the top. UNAVAILABLE naming the path
// when it cannot be written.
Status WritePng(const std::string& path, std::span<const uint8_t> rgba, uint32_t width,
                uint32_t height);

}  // namespace skinserve::gpu_region
