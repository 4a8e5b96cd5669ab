// A contact sheet: frames already written as PNG, scaled down into one grid image with a
// label under each, to see an animation at a glance.
#pragma once

#include <span>
#include <string>
#include <vector>

#include "skinserve/model/status.h"

namespace skinserve::render {

struct SheetFrame {
  std::string png_path;
  std::string label;  // e.g. "frame 12  t = 0.400 s"
};

struct SheetOptions {
  int columns = 4;
  int width = 1024;       // of the whole sheet; each cell is width / columns wide
  int label_height = 18;  // pixels under each cell for its label
};

// Size of the sheet for `count` frames of `frame_width` x `frame_height`: cells keep the
// frames' aspect ratio, ceil(count / columns) rows of cell height + label height.
struct SheetSize {
  int width = 0;
  int height = 0;
};
SheetSize ContactSheetSize(int count, int frame_width, int frame_height,
                           const SheetOptions& options = {});

// Writes the sheet to `path`, frames left to right, top to bottom, each scaled to its cell
// (the first frame's size sets the cells). INVALID_ARGUMENT for no frame or bad options;
// INTERNAL naming the file when a frame cannot be read or the sheet cannot be written.
Status WriteContactSheet(const std::string& path, std::span<const SheetFrame> frames,
                         const SheetOptions& options = {});

// `count` indices spread evenly over frames 0..total-1 (all of them when total <= count).
std::vector<std::size_t> EvenlySpaced(std::size_t total, std::size_t count);

}  // namespace skinserve::render
