#include "cairo_status.h"

#include <fmt/format.h>

namespace skinserve::render {

Status CairoStatus(cairo_status_t status, const std::string& what) {
  if (status == CAIRO_STATUS_SUCCESS) return Status::Ok();
  return Internal(fmt::format("{}: {}", what, cairo_status_to_string(status)));
}

Status CreateCanvas(int width, int height, SurfacePtr* surface, ContextPtr* context) {
  // Cairo's image surfaces are limited to 32767 pixels a side.
  if (width <= 0 || height <= 0 || width > 32767 || height > 32767) {
    return InvalidArgument(
        fmt::format("image size {}x{} is not within 1..32767 per side", width, height));
  }
  surface->reset(cairo_image_surface_create(CAIRO_FORMAT_ARGB32, width, height));
  if (Status s = CairoStatus(cairo_surface_status(surface->get()),
                             fmt::format("cairo_image_surface_create {}x{}", width, height));
      !s.ok()) {
    return s;
  }
  context->reset(cairo_create(surface->get()));
  return CairoStatus(cairo_status(context->get()), "cairo_create");
}

Status FinishPng(cairo_t* context, cairo_surface_t* surface, const std::string& path) {
  if (Status s = CairoStatus(cairo_status(context), "drawing " + path); !s.ok()) return s;
  cairo_surface_flush(surface);
  if (Status s = CairoStatus(cairo_surface_status(surface), "flushing " + path); !s.ok()) {
    return s;
  }
  return CairoStatus(cairo_surface_write_to_png(surface, path.c_str()), "writing " + path);
}

}  // namespace skinserve::render
