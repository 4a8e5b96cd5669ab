#include "skinserve/render/mesh_renderer.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <vector>

#include <glm/common.hpp>
#include <glm/geometric.hpp>

#include "cairo_status.h"
#include "triangle_arrays.h"

namespace skinserve::render {
namespace {

struct Triangle {
  float depth;  // of its centroid: the painter's sort key
  uint32_t first_index;
  float shade;  // Lambert factor, ambient included
};

glm::vec3 Vertex(std::span<const float> positions, uint32_t v) {
  return {positions[3 * v], positions[3 * v + 1], positions[3 * v + 2]};
}

}  // namespace

Status RenderPng(const std::string& path, const Camera& camera, std::span<const float> positions,
                 std::span<const uint32_t> indices, const RenderOptions& options) {
  if (Status s = CheckTriangleArrays(positions, {}, indices); !s.ok()) return s;
  const std::size_t vertex_count = positions.size() / 3;
  std::vector<Projected> projected(vertex_count);
  for (std::size_t v = 0; v < vertex_count; ++v) {
    projected[v] = camera.Project(Vertex(positions, static_cast<uint32_t>(v)));
  }
  // From the viewer, above and a touch to the left: fixed, since the camera is. With the
  // default camera a box's front, side and top get about 0.7, 0.3 and 0.6 of full light,
  // so the shape reads at a glance.
  const glm::vec3 light =
      glm::normalize(-camera.forward() + 0.5f * camera.up() - 0.1f * camera.right());

  std::vector<Triangle> triangles;
  triangles.reserve(indices.size() / 3);
  for (std::size_t i = 0; i < indices.size(); i += 3) {
    const uint32_t a = indices[i], b = indices[i + 1], c = indices[i + 2];
    if (projected[a].depth <= 0 || projected[b].depth <= 0 || projected[c].depth <= 0) continue;
    const glm::vec3 pa = Vertex(positions, a), pb = Vertex(positions, b), pc = Vertex(positions, c);
    glm::vec3 normal = glm::cross(pb - pa, pc - pa);
    const float length = glm::length(normal);
    if (!(length > 0.0f)) continue;
    normal /= length;
    if (glm::dot(normal, camera.eye() - pa) < 0.0f) {
      if (options.cull_back_faces) continue;
      normal = -normal;  // seen from behind: lit as its visible side
    }
    const float lambert = std::max(0.0f, glm::dot(normal, light));
    triangles.push_back({(projected[a].depth + projected[b].depth + projected[c].depth) / 3.0f,
                         static_cast<uint32_t>(i),
                         options.ambient + (1.0f - options.ambient) * lambert});
  }
  std::sort(triangles.begin(), triangles.end(),
            [](const Triangle& x, const Triangle& y) { return x.depth > y.depth; });

  SurfacePtr surface;
  ContextPtr context;
  if (Status s = CreateCanvas(camera.width(), camera.height(), &surface, &context); !s.ok()) {
    return s;
  }
  cairo_t* cr = context.get();
  cairo_set_source_rgb(cr, options.background.r, options.background.g, options.background.b);
  cairo_paint(cr);
  // Each triangle is stroked in its own colour as well as filled: antialiased edges of
  // neighbours would otherwise let the background show through as hairline seams.
  cairo_set_line_width(cr, 0.75);
  cairo_set_line_join(cr, CAIRO_LINE_JOIN_ROUND);
  for (const Triangle& t : triangles) {
    const Projected& a = projected[indices[t.first_index]];
    const Projected& b = projected[indices[t.first_index + 1]];
    const Projected& c = projected[indices[t.first_index + 2]];
    cairo_move_to(cr, a.x, a.y);
    cairo_line_to(cr, b.x, b.y);
    cairo_line_to(cr, c.x, c.y);
    cairo_close_path(cr);
    const glm::vec3 rgb = glm::min(options.color * t.shade, glm::vec3(1.0f));
    cairo_set_source_rgb(cr, rgb.r, rgb.g, rgb.b);
    cairo_fill_preserve(cr);
    cairo_stroke(cr);
  }
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

}  // namespace skinserve::render
