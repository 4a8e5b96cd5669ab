// The paper's synthetic workload: V vertices, B bones per vertex, 77 joints by default.
// Deterministic from a seed on every platform (no std:: distributions).
#pragma once

#include <cstdint>
#include <vector>

#include "skinserve/model/mesh.h"

namespace skinserve {

struct SyntheticMeshSpec {
  uint32_t vertex_count = 100'000;
  uint32_t influences = 2;
  uint32_t joint_count = 77;
  bool normals = false;
  // Tangents too (with normals only): each normal's cross product with a fixed axis, w -1
  // on every third vertex, else +1. They draw nothing from the seed's stream, so a mesh
  // keeps its positions, normals and weights with or without them.
  bool tangents = false;
  uint64_t seed = 1;
  // The paper's order leaves each vertex on a random bone, so neighbouring vertices share
  // no joints. Sorted: the same vertices ordered by their joints (first joint, then the
  // next...), as a mesh optimiser's clustering leaves a real character, where a GPU's
  // neighbouring work-items read the same palette records.
  bool sorted_by_joints = false;
};

// Joints sit along a branching chain; each vertex lies near the skeleton and is weighted
// to its B nearest joints with a smooth distance falloff, so weights vary smoothly over
// the surface as in a real rig. Weights sum to 1; B > joint_count pads with weight 0.
MeshArrays MakeSyntheticMesh(const SyntheticMeshSpec& spec);

// A plausible pose: per joint a rotation (up to ~60 degrees), a translation and a mild
// scale (0.9..1.1), varying smoothly with `frame`. 12 * joint_count floats, row-major 3x4.
std::vector<float> MakeSyntheticPalette(uint32_t joint_count, uint64_t seed, uint64_t frame);

// A rigid palette for dual-quaternion skinning: per joint a uniformly random rotation (any
// angle, so neighbouring joints often sit in opposite quaternion hemispheres) and a
// translation of up to 2 along each axis. Deterministic from seed and frame.
std::vector<float> MakeRigidPalette(uint32_t joint_count, uint64_t seed, uint64_t frame);

// The identity palette: skinning with it returns the rest pose.
std::vector<float> MakeIdentityPalette(uint32_t joint_count);

}  // namespace skinserve
