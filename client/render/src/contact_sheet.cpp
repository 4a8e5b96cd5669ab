#include "skinserve/render/contact_sheet.h"

#include <fmt/format.h>

#include <algorithm>

#include "cairo_status.h"

namespace skinserve::render {
namespace {

Result<SurfacePtr> ReadPng(const std::string& path) {
  SurfacePtr png(cairo_image_surface_create_from_png(path.c_str()));
  if (Status s = CairoStatus(cairo_surface_status(png.get()), "reading " + path); !s.ok()) {
    return s;
  }
  return png;
}

}  // namespace

SheetSize ContactSheetSize(int count, int frame_width, int frame_height,
                           const SheetOptions& options) {
  const int cell_width = options.width / options.columns;
  const int cell_height = static_cast<int>(static_cast<long long>(cell_width) * frame_height /
                                           std::max(frame_width, 1));
  const int rows = (count + options.columns - 1) / options.columns;
  return {cell_width * options.columns, rows * (cell_height + options.label_height)};
}

Status WriteContactSheet(const std::string& path, std::span<const SheetFrame> frames,
                         const SheetOptions& options) {
  if (frames.empty()) return InvalidArgument("contact sheet: no frames");
  if (options.columns < 1 || options.width < options.columns || options.label_height < 0) {
    return InvalidArgument(fmt::format(
        "contact sheet: columns = {} must be >= 1 and width = {} >= columns, label_height = {} "
        ">= 0",
        options.columns, options.width, options.label_height));
  }
  auto first = ReadPng(frames[0].png_path);
  if (!first.ok()) return first.status();
  const int frame_width = cairo_image_surface_get_width(first->get());
  const int frame_height = cairo_image_surface_get_height(first->get());
  const SheetSize size =
      ContactSheetSize(static_cast<int>(frames.size()), frame_width, frame_height, options);
  const int cell_width = size.width / options.columns;
  const int rows = (static_cast<int>(frames.size()) + options.columns - 1) / options.columns;
  const int cell_height = size.height / rows - options.label_height;

  SurfacePtr surface;
  ContextPtr context;
  if (Status s = CreateCanvas(size.width, size.height, &surface, &context); !s.ok()) return s;
  cairo_t* cr = context.get();
  cairo_set_source_rgb(cr, 1, 1, 1);
  cairo_paint(cr);
  cairo_select_font_face(cr, "sans-serif", CAIRO_FONT_SLANT_NORMAL, CAIRO_FONT_WEIGHT_NORMAL);
  cairo_set_font_size(cr, std::max(8.0, options.label_height * 0.65));
  for (std::size_t i = 0; i < frames.size(); ++i) {
    SurfacePtr png;
    if (i == 0) {
      png = std::move(*first);
    } else {
      auto read = ReadPng(frames[i].png_path);
      if (!read.ok()) return read.status();
      png = std::move(*read);
    }
    const double x = static_cast<double>(i % options.columns) * cell_width;
    const double y =
        static_cast<double>(i / options.columns) * (cell_height + options.label_height);
    cairo_save(cr);
    cairo_rectangle(cr, x, y, cell_width, cell_height);
    cairo_clip(cr);
    cairo_translate(cr, x, y);
    // Each frame fills its cell's width; a frame of another size keeps its aspect ratio.
    const double own_scale =
        static_cast<double>(cell_width) / std::max(cairo_image_surface_get_width(png.get()), 1);
    cairo_scale(cr, own_scale, own_scale);
    cairo_set_source_surface(cr, png.get(), 0, 0);
    // GOOD filtering averages the pixels a cell pixel covers: no aliasing when shrinking.
    cairo_pattern_set_filter(cairo_get_source(cr), CAIRO_FILTER_GOOD);
    cairo_paint(cr);
    cairo_restore(cr);
    // A hairline frame between cells.
    cairo_set_source_rgb(cr, 0.75, 0.75, 0.75);
    cairo_set_line_width(cr, 1.0);
    cairo_rectangle(cr, x + 0.5, y + 0.5, cell_width - 1.0, cell_height - 1.0);
    cairo_stroke(cr);
    if (!frames[i].label.empty() && options.label_height > 0) {
      cairo_set_source_rgb(cr, 0.15, 0.15, 0.15);
      cairo_move_to(cr, x + 4.0, y + cell_height + options.label_height * 0.75);
      cairo_show_text(cr, frames[i].label.c_str());
    }
    if (Status s = CairoStatus(cairo_status(cr), "drawing " + frames[i].png_path + " into " + path);
        !s.ok()) {
      return s;
    }
  }
  return FinishPng(cr, surface.get(), path);
}

std::vector<std::size_t> EvenlySpaced(std::size_t total, std::size_t count) {
  std::vector<std::size_t> picked;
  if (total <= count) {
    for (std::size_t i = 0; i < total; ++i) picked.push_back(i);
    return picked;
  }
  for (std::size_t k = 0; k < count; ++k) picked.push_back(k * total / count);
  return picked;
}

}  // namespace skinserve::render
