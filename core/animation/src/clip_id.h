// A compact clip's id: SHA-256 of its canonical bytes, lowercase hex (as mesh ids are),
// so the same clip built twice is one clip.
#pragma once

#include <cstdint>
#include <span>
#include <string>

namespace skinserve::animation {

std::string ClipId(std::span<const uint8_t> bytes);

}  // namespace skinserve::animation
