#include "skinserve/render/camera.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include <glm/geometric.hpp>
#include <glm/trigonometric.hpp>

namespace skinserve::render {

Camera Camera::Framing(const Bounds& box, int width, int height, const CameraOptions& options) {
  Camera c;
  c.width_ = width;
  c.height_ = height;
  const glm::vec3 centre = (box.min + box.max) * 0.5f;
  // A flat or single-point box still gets a camera at a sensible distance.
  const float radius = std::max(glm::length(box.max - box.min) * 0.5f, 1e-3f);
  const float azimuth = glm::radians(options.azimuth_degrees);
  const float elevation = glm::radians(options.elevation_degrees);
  const glm::vec3 to_eye(std::sin(azimuth) * std::cos(elevation), std::sin(elevation),
                         std::cos(azimuth) * std::cos(elevation));
  const float distance = radius / std::sin(glm::radians(options.field_of_view_degrees) * 0.5f);
  c.eye_ = centre + to_eye * distance;
  c.forward_ = -to_eye;
  c.right_ = glm::normalize(glm::cross(c.forward_, glm::vec3(0.0f, 1.0f, 0.0f)));
  c.up_ = glm::cross(c.right_, c.forward_);

  // Fit the corners' projections into the image.
  float min_x = std::numeric_limits<float>::max(), max_x = -min_x;
  float min_y = min_x, max_y = -min_x;
  for (int corner = 0; corner < 8; ++corner) {
    const glm::vec3 p((corner & 1) ? box.max.x : box.min.x, (corner & 2) ? box.max.y : box.min.y,
                      (corner & 4) ? box.max.z : box.min.z);
    const glm::vec3 q = c.View(p);
    min_x = std::min(min_x, q.x), max_x = std::max(max_x, q.x);
    min_y = std::min(min_y, q.y), max_y = std::max(max_y, q.y);
  }
  const float usable_w = static_cast<float>(width) * (1.0f - 2.0f * options.margin);
  const float usable_h = static_cast<float>(height) * (1.0f - 2.0f * options.margin);
  c.scale_ = std::min(usable_w / std::max(max_x - min_x, 1e-6f),
                      usable_h / std::max(max_y - min_y, 1e-6f));
  c.offset_x_ = (min_x + max_x) * 0.5f;
  c.offset_y_ = (min_y + max_y) * 0.5f;
  c.centre_x_ = static_cast<float>(width) * 0.5f;
  c.centre_y_ = static_cast<float>(height) * 0.5f;
  return c;
}

glm::vec3 Camera::View(const glm::vec3& p) const {
  const glm::vec3 v = p - eye_;
  const float depth = glm::dot(v, forward_);
  // Guards the division only; the renderer drops triangles at or behind the eye.
  const float inverse = depth > 1e-12f ? 1.0f / depth : 0.0f;
  return {glm::dot(v, right_) * inverse, glm::dot(v, up_) * inverse, depth};
}

Projected Camera::Project(const glm::vec3& p) const {
  const glm::vec3 v = View(p);
  // Image y grows downwards, view y upwards.
  return {centre_x_ + (v.x - offset_x_) * scale_, centre_y_ - (v.y - offset_y_) * scale_, v.z};
}

}  // namespace skinserve::render
