// A fixed perspective camera that frames a bounding box: every frame of an animation is
// drawn with one camera (character_camera.h: the box over the whole clip), so motion shows
// as motion, not as reframing.
#pragma once

#include <glm/vec3.hpp>

#include "skinserve/render/bounds.h"

namespace skinserve::render {

struct CameraOptions {
  // Direction to the camera, from the box's centre: around +Y (glTF's up) from +Z (the
  // side a glTF character faces), then above the horizon.
  float azimuth_degrees = 30.0f;
  float elevation_degrees = 12.0f;
  float field_of_view_degrees = 30.0f;
  // Space left on every side of the projected box, as a fraction of the image: room for
  // poses between the sampled ones that reach past the box.
  float margin = 0.1f;
};

// A point projected to the image: pixels (y down) and its distance along the view
// direction (larger is farther; <= 0 is behind the camera).
struct Projected {
  float x = 0.0f;
  float y = 0.0f;
  float depth = 0.0f;
};

class Camera {
 public:
  // Looks at the centre of `box` from far enough that its bounding sphere is in view, then
  // scales and centres the projection of its 8 corners to fill width x height less the
  // margin. width and height must be positive.
  static Camera Framing(const Bounds& box, int width, int height,
                        const CameraOptions& options = {});

  Projected Project(const glm::vec3& p) const;
  int width() const { return width_; }
  int height() const { return height_; }
  const glm::vec3& eye() const { return eye_; }
  const glm::vec3& forward() const { return forward_; }
  const glm::vec3& right() const { return right_; }
  const glm::vec3& up() const { return up_; }

 private:
  // x / depth and y / depth in the view's axes, and depth.
  glm::vec3 View(const glm::vec3& p) const;

  glm::vec3 eye_{0.0f}, forward_{0.0f, 0.0f, -1.0f}, right_{1.0f, 0.0f, 0.0f},
      up_{0.0f, 1.0f, 0.0f};
  // Image x = centre_x + (view x / depth - offset_x) * scale; y likewise, flipped.
  float scale_ = 1.0f;
  float offset_x_ = 0.0f, offset_y_ = 0.0f;
  float centre_x_ = 0.0f, centre_y_ = 0.0f;
  int width_ = 1, height_ = 1;
};

}  // namespace skinserve::render
