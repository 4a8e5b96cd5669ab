#include "skinserve/render/mesh_renderer.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <vector>

#include <glm/common.hpp>
#include <glm/geometric.hpp>

#include "cairo_status.h"
#include "depth_raster.h"
#include "triangle_arrays.h"

namespace skinserve::render {
namespace {

glm::vec3 Vec3(std::span<const float> values, uint32_t v) {
  return {values[3 * v], values[3 * v + 1], values[3 * v + 2]};
}

// Draws one part's triangles into `raster`.
void DrawPart(const RenderPart& part, const Camera& camera, const RenderOptions& options,
              const glm::vec3& light, float samples, DepthRaster* raster) {
  const std::size_t vertex_count = part.positions.size() / 3;
  std::vector<Projected> projected(vertex_count);
  for (std::size_t v = 0; v < vertex_count; ++v) {
    projected[v] = camera.Project(Vec3(part.positions, static_cast<uint32_t>(v)));
  }
  const bool smooth = !part.normals.empty();
  auto shade = [&](const glm::vec3& normal) {
    const float lambert = std::max(0.0f, glm::dot(normal, light));
    return glm::min(options.color * (options.ambient + (1.0f - options.ambient) * lambert),
                    glm::vec3(1.0f));
  };
  const auto& indices = part.indices;
  for (std::size_t i = 0; i < indices.size(); i += 3) {
    const uint32_t corner[3] = {indices[i], indices[i + 1], indices[i + 2]};
    if (projected[corner[0]].depth <= 0 || projected[corner[1]].depth <= 0 ||
        projected[corner[2]].depth <= 0) {
      continue;
    }
    const glm::vec3 pa = Vec3(part.positions, corner[0]);
    const glm::vec3 face =
        glm::cross(Vec3(part.positions, corner[1]) - pa, Vec3(part.positions, corner[2]) - pa);
    const float length = glm::length(face);
    if (!(length > 0.0f)) continue;
    // Seen from behind: culled, or lit as its visible side (every normal turned over).
    const bool from_behind = glm::dot(face, camera.eye() - pa) < 0.0f;
    if (from_behind && options.cull_back_faces) continue;
    const float facing = from_behind ? -1.0f : 1.0f;
    RasterVertex r[3];
    for (int k = 0; k < 3; ++k) {
      const Projected& p = projected[corner[k]];
      r[k].x = p.x * samples;
      r[k].y = p.y * samples;
      r[k].depth = p.depth;
      glm::vec3 n = face / length;
      if (smooth) {
        const glm::vec3 vertex_normal = Vec3(part.normals, corner[k]);
        const float n_length = glm::length(vertex_normal);
        if (n_length > 0.0f) n = vertex_normal / n_length;
      }
      r[k].normal = n * facing;
    }
    raster->Triangle(r[0], r[1], r[2], shade);
  }
}

}  // namespace

Status RenderPng(const std::string& path, const Camera& camera, std::span<const RenderPart> parts,
                 const RenderOptions& options) {
  for (std::size_t p = 0; p < parts.size(); ++p) {
    if (Status s = CheckTriangleArrays(parts[p].positions, parts[p].normals, parts[p].indices);
        !s.ok()) {
      if (parts.size() == 1) return s;
      return InvalidArgument(fmt::format("part {}: {}", p, s.message()));
    }
  }
  if (options.samples_per_side < 1 || options.samples_per_side > 4) {
    return InvalidArgument(
        fmt::format("samples_per_side = {} is not within 1..4", options.samples_per_side));
  }
  SurfacePtr surface;
  ContextPtr context;
  if (Status s = CreateCanvas(camera.width(), camera.height(), &surface, &context); !s.ok()) {
    return s;
  }
  // From the viewer, above and a touch to the left: fixed, since the camera is. With the
  // default camera a box's front, side and top get about 0.7, 0.3 and 0.6 of full light,
  // so the shape reads at a glance.
  const glm::vec3 light =
      glm::normalize(-camera.forward() + 0.5f * camera.up() - 0.1f * camera.right());
  const int n = options.samples_per_side;
  DepthRaster raster(camera.width() * n, camera.height() * n, options.background);
  for (const RenderPart& part : parts) {
    DrawPart(part, camera, options, light, static_cast<float>(n), &raster);
  }

  // Each pixel is the mean of its samples, written straight into Cairo's ARGB32 surface.
  cairo_surface_flush(surface.get());
  unsigned char* data = cairo_image_surface_get_data(surface.get());
  const int stride = cairo_image_surface_get_stride(surface.get());
  const float inverse_count = 1.0f / static_cast<float>(n * n);
  for (int y = 0; y < camera.height(); ++y) {
    auto* row = reinterpret_cast<uint32_t*>(data + static_cast<std::size_t>(y) * stride);
    for (int x = 0; x < camera.width(); ++x) {
      glm::vec3 sum(0.0f);
      for (int sy = 0; sy < n; ++sy) {
        for (int sx = 0; sx < n; ++sx) sum += raster.at(x * n + sx, y * n + sy);
      }
      const glm::vec3 rgb = glm::clamp(sum * inverse_count, 0.0f, 1.0f) * 255.0f + 0.5f;
      row[x] = 0xFF000000u | (static_cast<uint32_t>(rgb.r) << 16) |
               (static_cast<uint32_t>(rgb.g) << 8) | static_cast<uint32_t>(rgb.b);
    }
  }
  cairo_surface_mark_dirty(surface.get());

  cairo_t* cr = context.get();
  if (!options.label.empty()) {
    cairo_select_font_face(cr, "sans-serif", CAIRO_FONT_SLANT_NORMAL, CAIRO_FONT_WEIGHT_NORMAL);
    const double size = std::max(10.0, camera.height() / 32.0);
    cairo_set_font_size(cr, size);
    cairo_set_source_rgb(cr, 0.2, 0.2, 0.2);
    cairo_move_to(cr, size * 0.6, size * 1.4);
    cairo_show_text(cr, options.label.c_str());
  }
  return FinishPng(cr, surface.get(), path);
}

Status RenderPng(const std::string& path, const Camera& camera, std::span<const float> positions,
                 std::span<const uint32_t> indices, const RenderOptions& options) {
  const RenderPart part{.positions = positions, .normals = {}, .indices = indices};
  return RenderPng(path, camera, std::span<const RenderPart>(&part, 1), options);
}

}  // namespace skinserve::render
