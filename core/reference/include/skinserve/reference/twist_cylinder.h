// The twisted cylinder: the classic case that separates linear blend skinning from
// dual-quaternion skinning. Two joints; joint 0 holds the bottom half, joint 1 turns the
// top about the cylinder's axis. Linear blending averages the two matrices and the
// middle of the tube shrinks to a radius of cos(angle / 2), collapsing at 180 degrees
// (the "candy wrapper"); dual quaternions blend the rotations and keep the radius.
// Used by the tests and by `skinserve-cli twist`, which draws the picture on
// docs/backends/dual-quaternion.md.
#pragma once

#include <cstdint>
#include <vector>

#include "skinserve/model/mesh.h"

namespace skinserve {

struct TwistCylinder {
  MeshArrays mesh;                  // 2 influences, 2 joints, with normals
  std::vector<uint32_t> triangles;  // 3 indices each, counter-clockwise seen from outside
  float length = 0;                 // along +y, from y = 0
  float radius = 0;
  uint32_t rings = 0;  // of `segments` vertices each; ring i sits at y = length * i / (rings - 1)
  uint32_t segments = 0;  // the two cap centres follow the rings' vertices
};

// A tube of radius 1/2 and length 4 along +y with capped ends. Joint 1's weight rises
// smoothly from 0 at y = 1 to 1 at y = 3, so the middle ring (rings odd) is weighted
// 1/2 and 1/2. rings >= 3 and odd, segments >= 3.
TwistCylinder MakeTwistCylinder(uint32_t rings = 33, uint32_t segments = 24);

// Joint 0 the identity, joint 1 a rotation of `degrees` about the cylinder's axis (+y).
std::vector<float> MakeTwistPalette(double degrees);

}  // namespace skinserve
