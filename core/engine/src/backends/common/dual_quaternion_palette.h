// The frame's palette as unit dual quaternions, for the dual-quaternion kernels (scalar,
// SSE, Highway and OpenCL): each rigid joint matrix [R | t] converted once per frame, J
// conversions, so no vertex converts a matrix. Per joint 8 floats, 32-byte aligned: the rotation q
// = (x, y, z, w), then the dual part d = 0.5 * (t, 0) * q, also (x, y, z, w). The palette must have
// passed ValidateRigidPalette (SkinFrame::Validate does it).
#pragma once

#include <cmath>
#include <cstddef>
#include <span>

#include "skinserve/model/aligned_buffer.h"

namespace skinserve {

class DualQuaternionPalette {
 public:
  static constexpr std::size_t kFloatsPerJoint = 8;

  // Builds into this thread's buffer (grown, never shrunk), like sse::ColumnPalette: one
  // frame at a time per thread, OpenMP workers only read it.
  explicit DualQuaternionPalette(std::span<const float> palette) {
    thread_local AlignedBuffer<float> buffer;
    const std::size_t joints = palette.size() / 12;
    if (buffer.size() < joints * kFloatsPerJoint) {
      buffer = AlignedBuffer<float>(joints * kFloatsPerJoint);
    }
    quaternions_ = buffer.data();
    joints_ = joints;
    for (std::size_t j = 0; j < joints; ++j) {
      Convert(palette.data() + 12 * j, quaternions_ + kFloatsPerJoint * j);
    }
  }
  DualQuaternionPalette(const DualQuaternionPalette&) = delete;
  DualQuaternionPalette& operator=(const DualQuaternionPalette&) = delete;

  // Joint j's real part (x, y, z, w) followed by its dual part, 32-byte aligned.
  const float* joint(std::size_t j) const { return quaternions_ + kFloatsPerJoint * j; }
  // Every joint's 8 floats, for a device to copy or wrap.
  std::span<const float> floats() const { return {quaternions_, kFloatsPerJoint * joints_}; }

 private:
  // One row-major 3x4 matrix m to a unit dual quaternion, in double: the rotation by
  // Shepperd's method (the largest of w, x, y, z is found first, so no division by a
  // small number), normalised; then d = 0.5 * t * q.
  static void Convert(const float* m, float* out) {
    const double m00 = m[0], m01 = m[1], m02 = m[2], m10 = m[4], m11 = m[5], m12 = m[6];
    const double m20 = m[8], m21 = m[9], m22 = m[10];
    const double trace = m00 + m11 + m22;
    double x, y, z, w;
    if (trace >= m00 && trace >= m11 && trace >= m22) {
      const double s = 2 * std::sqrt(1 + trace);  // 4w
      w = 0.25 * s, x = (m21 - m12) / s, y = (m02 - m20) / s, z = (m10 - m01) / s;
    } else if (m00 >= m11 && m00 >= m22) {
      const double s = 2 * std::sqrt(1 + m00 - m11 - m22);  // 4x
      w = (m21 - m12) / s, x = 0.25 * s, y = (m01 + m10) / s, z = (m02 + m20) / s;
    } else if (m11 >= m22) {
      const double s = 2 * std::sqrt(1 - m00 + m11 - m22);  // 4y
      w = (m02 - m20) / s, x = (m01 + m10) / s, y = 0.25 * s, z = (m12 + m21) / s;
    } else {
      const double s = 2 * std::sqrt(1 - m00 - m11 + m22);  // 4z
      w = (m10 - m01) / s, x = (m02 + m20) / s, y = (m12 + m21) / s, z = 0.25 * s;
    }
    const double inverse = 1 / std::sqrt(x * x + y * y + z * z + w * w);
    x *= inverse, y *= inverse, z *= inverse, w *= inverse;
    const double tx = m[3], ty = m[7], tz = m[11];
    // d = 0.5 * (tx, ty, tz, 0) * (x, y, z, w), the Hamilton product.
    out[0] = static_cast<float>(x), out[1] = static_cast<float>(y);
    out[2] = static_cast<float>(z), out[3] = static_cast<float>(w);
    out[4] = static_cast<float>(0.5 * (tx * w + ty * z - tz * y));
    out[5] = static_cast<float>(0.5 * (-tx * z + ty * w + tz * x));
    out[6] = static_cast<float>(0.5 * (tx * y - ty * x + tz * w));
    out[7] = static_cast<float>(-0.5 * (tx * x + ty * y + tz * z));
  }

  float* quaternions_ = nullptr;
  std::size_t joints_ = 0;
};

}  // namespace skinserve
