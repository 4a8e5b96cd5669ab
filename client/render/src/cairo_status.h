// Cairo reports errors as a sticky status on surfaces and contexts; these turn it into a
// Status naming what was being done, so no failed draw or write passes silently.
#pragma once

#include <cairo.h>

#include <memory>
#include <string>

#include "skinserve/model/status.h"

namespace skinserve::render {

struct SurfaceDeleter {
  void operator()(cairo_surface_t* s) const { cairo_surface_destroy(s); }
};
struct ContextDeleter {
  void operator()(cairo_t* c) const { cairo_destroy(c); }
};
using SurfacePtr = std::unique_ptr<cairo_surface_t, SurfaceDeleter>;
using ContextPtr = std::unique_ptr<cairo_t, ContextDeleter>;

// OK for CAIRO_STATUS_SUCCESS, else INTERNAL "<what>: <cairo's message>".
Status CairoStatus(cairo_status_t status, const std::string& what);

// A width x height ARGB32 surface and a context on it, both checked.
Status CreateCanvas(int width, int height, SurfacePtr* surface, ContextPtr* context);

// Checks the context's drawing, flushes the surface and writes it as PNG to `path`.
Status FinishPng(cairo_t* context, cairo_surface_t* surface, const std::string& path);

}  // namespace skinserve::render
