#include "skinserve/reference/twist_cylinder.h"

#include <algorithm>
#include <cmath>
#include <numbers>

namespace skinserve {

TwistCylinder MakeTwistCylinder(uint32_t rings, uint32_t segments) {
  TwistCylinder c;
  c.length = 4.0f;
  c.radius = 0.5f;
  c.rings = rings;
  c.segments = segments;
  MeshArrays& m = c.mesh;
  m.vertex_count = rings * segments + 2;
  m.influences = 2;
  m.joint_count = 2;
  auto add = [&m](double x, double y, double z, double nx, double ny, double nz, double top) {
    for (double value : {x, y, z}) m.positions.push_back(static_cast<float>(value));
    for (double value : {nx, ny, nz}) m.normals.push_back(static_cast<float>(value));
    m.joints.insert(m.joints.end(), {0, 1});
    m.weights.push_back(static_cast<float>(1 - top));
    m.weights.push_back(static_cast<float>(top));
  };
  for (uint32_t i = 0; i < rings; ++i) {
    const double y = c.length * i / (rings - 1);
    const double s = std::clamp((y - 1.0) / 2.0, 0.0, 1.0);
    const double top = s * s * (3 - 2 * s);  // smoothstep: 1/2 exactly in the middle
    for (uint32_t k = 0; k < segments; ++k) {
      const double phi = 2 * std::numbers::pi * k / segments;
      add(c.radius * std::sin(phi), y, c.radius * std::cos(phi), std::sin(phi), 0, std::cos(phi),
          top);
    }
  }
  const uint32_t bottom = rings * segments, top_centre = bottom + 1;
  add(0, 0, 0, 0, -1, 0, 0);
  add(0, c.length, 0, 0, 1, 0, 1);
  for (uint32_t i = 0; i + 1 < rings; ++i) {
    for (uint32_t k = 0; k < segments; ++k) {
      const uint32_t a = i * segments + k, b = i * segments + (k + 1) % segments;
      const uint32_t d = a + segments, e = b + segments;
      c.triangles.insert(c.triangles.end(), {a, b, e, a, e, d});
    }
  }
  const uint32_t last = (rings - 1) * segments;
  for (uint32_t k = 0; k < segments; ++k) {
    const uint32_t next = (k + 1) % segments;
    c.triangles.insert(c.triangles.end(), {bottom, next, k});
    c.triangles.insert(c.triangles.end(), {top_centre, last + k, last + next});
  }
  return c;
}

std::vector<float> MakeTwistPalette(double degrees) {
  const double angle = degrees * std::numbers::pi / 180;
  const float c = static_cast<float>(std::cos(angle)), s = static_cast<float>(std::sin(angle));
  return {1, 0, 0, 0, 0, 1, 0, 0, 0,  0, 1, 0,   // joint 0: the identity
          c, 0, s, 0, 0, 1, 0, 0, -s, 0, c, 0};  // joint 1: about +y
}

}  // namespace skinserve
