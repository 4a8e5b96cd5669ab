#include "triangle_check.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <vector>

namespace skinserve::gpu_region {
namespace {

constexpr double kInside = 0.05;  // px: a centre this far inside a triangle is covered
constexpr double kNear = 0.5;     // px: a drawn centre this near a triangle is the reference's
constexpr double kInf = std::numeric_limits<double>::infinity();

struct Point {
  double x = 0, y = 0, depth = 0;  // pixels (y down) and Vulkan depth (smaller: nearer)
};

Point Project(const Transform& t, const double* p) {
  const double cx = t[0] * p[0] + t[4] * p[1] + t[8] * p[2] + t[12];
  const double cy = t[1] * p[0] + t[5] * p[1] + t[9] * p[2] + t[13];
  const double cz = t[2] * p[0] + t[6] * p[1] + t[10] * p[2] + t[14];
  const double cw = t[3] * p[0] + t[7] * p[1] + t[11] * p[2] + t[15];
  return {cx / cw, cy / cw, cz / cw};
}

double SegmentDistance(double x, double y, const Point& p, const Point& q) {
  const double ex = q.x - p.x, ey = q.y - p.y, len2 = ex * ex + ey * ey;
  const double s = len2 > 0 ? std::clamp(((x - p.x) * ex + (y - p.y) * ey) / len2, 0.0, 1.0) : 0;
  return std::hypot(x - p.x - s * ex, y - p.y - s * ey);
}

// One projected triangle: the signed distance in pixels from a point to it (> 0 inside:
// to the nearest edge; < 0 outside: to the triangle) and barycentric weights.
struct Triangle {
  Point v[3];
  double area2 = 0;  // twice the signed area

  double Distance(double x, double y) const {
    double inside = kInf;
    for (int i = 0; i < 3; ++i) {
      const Point &p = v[i], &q = v[(i + 1) % 3];
      const double ex = q.x - p.x, ey = q.y - p.y;
      const double cross = ex * (y - p.y) - ey * (x - p.x);
      inside = std::min(inside, (area2 > 0 ? cross : -cross) / std::hypot(ex, ey));
    }
    if (inside >= 0) return inside;
    double outside = kInf;
    for (int i = 0; i < 3; ++i)
      outside = std::min(outside, SegmentDistance(x, y, v[i], v[(i + 1) % 3]));
    return -outside;
  }
  std::array<double, 3> Barycentric(double x, double y) const {
    std::array<double, 3> w;
    for (int i = 0; i < 3; ++i) {
      const Point &b = v[(i + 1) % 3], &c = v[(i + 2) % 3];
      w[i] = ((b.x - x) * (c.y - y) - (b.y - y) * (c.x - x)) / area2;
    }
    return w;
  }
};

// Per pixel: the largest signed distance to any reference triangle (-inf: more than 2 px
// away from all), and the nearest two triangles covering its centre.
struct Coverage {
  uint32_t width, height;
  std::vector<double> distance, front_depth, second_depth, front_margin;
  std::vector<int64_t> front;  // triangle index, -1: none

  Coverage(uint32_t w, uint32_t h)
      : width(w),
        height(h),
        distance(std::size_t{w} * h, -kInf),
        front_depth(distance.size(), kInf),
        second_depth(distance.size(), kInf),
        front_margin(distance.size(), 0),
        front(distance.size(), -1) {}

  void Add(const Triangle& t, int64_t index) {
    constexpr double kReach = 2;  // pixels past the triangle whose distance matters
    const auto range = [&](double a, double b, double c, uint32_t size, int64_t* lo, int64_t* hi) {
      *lo = std::max<int64_t>(0, static_cast<int64_t>(std::floor(std::min({a, b, c}) - kReach)));
      *hi = std::min<int64_t>(size - 1,
                              static_cast<int64_t>(std::ceil(std::max({a, b, c}) + kReach)));
    };
    int64_t x0, x1, y0, y1;
    range(t.v[0].x, t.v[1].x, t.v[2].x, width, &x0, &x1);
    range(t.v[0].y, t.v[1].y, t.v[2].y, height, &y0, &y1);
    for (int64_t y = y0; y <= y1; ++y) {
      for (int64_t x = x0; x <= x1; ++x) {
        const std::size_t p = static_cast<std::size_t>(y) * width + x;
        const double d = t.Distance(x + 0.5, y + 0.5);
        distance[p] = std::max(distance[p], d);
        if (d < 0) continue;
        const auto w = t.Barycentric(x + 0.5, y + 0.5);
        const double depth = w[0] * t.v[0].depth + w[1] * t.v[1].depth + w[2] * t.v[2].depth;
        if (depth < front_depth[p]) {
          second_depth[p] = front_depth[p];
          front_depth[p] = depth, front[p] = index, front_margin[p] = d;
        } else {
          second_depth[p] = std::min(second_depth[p], depth);
        }
      }
    }
  }
};

bool Background(const uint8_t* p) {
  return std::equal(p, p + 3, VertexRenderer::kBackground.begin());
}

}  // namespace

std::array<double, 3> ReferenceShade(double x, double y, double z) {
  const double l = std::sqrt(0.16 + 0.36 + 0.49), n = std::sqrt(x * x + y * y + z * z);
  const double s = 0.35 + 0.65 * std::abs((-0.4 * x + 0.6 * y + 0.7 * z) / (l * n));
  return {0.90 * s * 255, 0.62 * s * 255, 0.36 * s * 255};
}

bool TrianglePictureCheck::ok() const {
  return drawn_pixels > 0 && inside_pixels > 0 && inside_drawn >= 0.99 && drawn_near >= 0.99 &&
         points_on_drawn >= 0.99 && (!normals || (shaded_pixels > 0 && shade_matches >= 0.97));
}

std::string TrianglePictureCheck::ToString() const {
  std::string s = fmt::format(
      "{} pixels drawn; {:.2f}% of the {} pixels inside the reference's triangles drawn (>= 99%), "
      "{:.2f}% of the drawn pixels within 0.5 px of one (>= 99%), {:.2f}% of the reference's "
      "projected vertices on or next to a drawn pixel (>= 99%)",
      drawn_pixels, 100 * inside_drawn, inside_pixels, 100 * drawn_near, 100 * points_on_drawn);
  if (normals) {
    s += fmt::format(", {:.2f}% of {} pixels shaded as the reference's nearest normal (>= 97%)",
                     100 * shade_matches, shaded_pixels);
  }
  return s;
}

namespace {

// The reference's vertices in pixels and depth.
std::vector<Point> ProjectAll(std::span<const double> positions, const Transform& t, uint32_t width,
                              uint32_t height) {
  std::vector<Point> points(positions.size() / 3);
  for (std::size_t v = 0; v < points.size(); ++v) {
    const Point c = Project(t, positions.data() + 3 * v);
    points[v] = {(c.x + 1) / 2 * width, (c.y + 1) / 2 * height, c.depth};
  }
  return points;
}

// The fraction of the projected vertices inside the image with a drawn pixel in their 3x3
// neighbourhood (a vertex on a pixel's edge may be rasterised into its neighbour).
double VerticesOnDrawn(std::span<const uint8_t> rgba, uint32_t width, uint32_t height,
                       const std::vector<Point>& points) {
  uint64_t inside = 0, hit = 0;
  for (const Point& p : points) {
    const auto px = static_cast<int64_t>(std::floor(p.x)),
               py = static_cast<int64_t>(std::floor(p.y));
    if (px < 0 || py < 0 || px >= width || py >= height) continue;
    ++inside;
    bool drawn = false;
    for (int64_t y = std::max<int64_t>(0, py - 1); y <= std::min<int64_t>(height - 1, py + 1);
         ++y) {
      for (int64_t x = std::max<int64_t>(0, px - 1); x <= std::min<int64_t>(width - 1, px + 1);
           ++x) {
        drawn = drawn || !Background(rgba.data() + 4 * (static_cast<std::size_t>(y) * width + x));
      }
    }
    hit += drawn ? 1 : 0;
  }
  return inside > 0 ? static_cast<double>(hit) / inside : 0;
}

// Pixels whose nearest reference triangle is clear: their colour against the reference's
// interpolated normal there.
void CompareShading(std::span<const uint8_t> rgba, const Coverage& c,
                    const std::vector<Triangle>& triangles, std::span<const double> normals,
                    std::span<const uint32_t> indices, TrianglePictureCheck* check) {
  uint64_t compared = 0, matching = 0;
  for (uint32_t y = 0; y < c.height; ++y) {
    for (uint32_t x = 0; x < c.width; ++x) {
      const std::size_t p = static_cast<std::size_t>(y) * c.width + x;
      if (c.front[p] < 0 || c.front_margin[p] < kInside ||
          c.second_depth[p] - c.front_depth[p] < 1e-3) {
        continue;
      }
      const Triangle& t = triangles[c.front[p]];
      const auto w = t.Barycentric(x + 0.5, y + 0.5);
      double n[3] = {0, 0, 0};
      for (int k = 0; k < 3; ++k) {
        const double* vn = normals.data() + 3ull * indices[3 * c.front[p] + k];
        for (int i = 0; i < 3; ++i) n[i] += w[k] * vn[i];
      }
      const auto want = ReferenceShade(n[0], n[1], n[2]);
      const uint8_t* got = rgba.data() + 4 * p;
      bool same = true;
      for (int i = 0; i < 3; ++i) same = same && std::abs(got[i] - want[i]) <= 4;
      ++compared;
      matching += same ? 1 : 0;
    }
  }
  check->shaded_pixels = compared;
  check->shade_matches = compared > 0 ? static_cast<double>(matching) / compared : 0;
}

}  // namespace

TrianglePictureCheck CheckTrianglePicture(std::span<const uint8_t> rgba, uint32_t width,
                                          uint32_t height, std::span<const double> positions,
                                          std::span<const double> normals,
                                          std::span<const uint32_t> indices,
                                          const Transform& transform) {
  const std::vector<Point> points = ProjectAll(positions, transform, width, height);
  Coverage coverage(width, height);
  std::vector<Triangle> triangles(indices.size() / 3);
  for (std::size_t i = 0; i < triangles.size(); ++i) {
    Triangle& t = triangles[i];
    for (int k = 0; k < 3; ++k) t.v[k] = points.at(indices[3 * i + k]);
    t.area2 = (t.v[1].x - t.v[0].x) * (t.v[2].y - t.v[0].y) -
              (t.v[1].y - t.v[0].y) * (t.v[2].x - t.v[0].x);
    if (std::abs(t.area2) > 1e-12) coverage.Add(t, static_cast<int64_t>(i));  // else no pixels
  }
  TrianglePictureCheck check;
  uint64_t inside_drawn = 0, drawn_near = 0;
  for (std::size_t p = 0; p < coverage.distance.size(); ++p) {
    const bool drawn = !Background(rgba.data() + 4 * p);
    const double d = coverage.distance[p];
    if (d >= kInside) {
      ++check.inside_pixels;
      inside_drawn += drawn ? 1 : 0;
    }
    if (!drawn) continue;
    ++check.drawn_pixels;
    drawn_near += d >= -kNear ? 1 : 0;
  }
  check.inside_drawn =
      check.inside_pixels > 0 ? static_cast<double>(inside_drawn) / check.inside_pixels : 0;
  check.drawn_near =
      check.drawn_pixels > 0 ? static_cast<double>(drawn_near) / check.drawn_pixels : 0;
  check.points_on_drawn = VerticesOnDrawn(rgba, width, height, points);
  check.normals = !normals.empty();
  if (check.normals) CompareShading(rgba, coverage, triangles, normals, indices, &check);
  return check;
}

}  // namespace skinserve::gpu_region
