// The float64 dual-quaternion reference: glm's dual quaternions in double, as plainly as
// possible, sharing no code with the kernels (which convert with their own Shepperd
// method and blend by hand in float).
#define GLM_ENABLE_EXPERIMENTAL
#include <glm/gtc/quaternion.hpp>
#include <glm/gtx/dual_quaternion.hpp>
#include <glm/mat3x3.hpp>
#include <glm/vec3.hpp>
#include <vector>

#include "skinserve/model/palette.h"
#include "skinserve/reference/reference.h"

namespace skinserve {

ReferenceFrame ReferenceSkinDualQuaternion(const Mesh& mesh, std::span<const float> palette,
                                           std::span<const MorphWeight> morph) {
  const ReferenceFrame rest = ReferenceMorph(mesh, morph);
  // Each joint [R | t] as the unit dual quaternion of "rotate by R, then move by t".
  const std::size_t joint_count = palette.size() / kFloatsPerJoint;
  std::vector<glm::tdualquat<double>> joints(joint_count);
  for (std::size_t j = 0; j < joint_count; ++j) {
    const float* m = &palette[kFloatsPerJoint * j];
    glm::dmat3 rotation;  // glm is column-major: rotation[col][row]
    for (int row = 0; row < 3; ++row) {
      for (int col = 0; col < 3; ++col) rotation[col][row] = m[4 * row + col];
    }
    const glm::dquat q = glm::normalize(glm::quat_cast(rotation));
    joints[j] = glm::tdualquat<double>(q, glm::dvec3(m[3], m[7], m[11]));
  }
  const std::size_t v_count = mesh.vertex_count();
  const std::size_t b = mesh.influences();
  ReferenceFrame out;
  out.positions.resize(3 * v_count);
  if (mesh.has_normals()) out.normals.resize(3 * v_count);
  if (mesh.has_tangents()) out.tangents.resize(4 * v_count);
  for (std::size_t v = 0; v < v_count; ++v) {
    const glm::tdualquat<double>& first = joints[mesh.joints()[v * b]];
    glm::tdualquat<double> blend(glm::dquat(0, 0, 0, 0), glm::dquat(0, 0, 0, 0));
    for (std::size_t i = 0; i < b; ++i) {
      const glm::tdualquat<double>& q = joints[mesh.joints()[v * b + i]];
      double w = mesh.weights()[v * b + i];
      if (glm::dot(first.real, q.real) < 0) w = -w;  // the same hemisphere as the first
      blend = blend + q * w;
    }
    blend = glm::normalize(blend);
    const double* p = &rest.positions[3 * v];
    const glm::dvec3 moved = blend * glm::dvec3(p[0], p[1], p[2]);
    for (int k = 0; k < 3; ++k) out.positions[3 * v + k] = moved[k];
    if (mesh.has_normals()) {
      const double* n = &rest.normals[3 * v];
      // Unit, as linear blending's: a morphed normal is not (the rotation keeps its length).
      const glm::dvec3 turned = glm::normalize(blend.real * glm::dvec3(n[0], n[1], n[2]));
      for (int k = 0; k < 3; ++k) out.normals[3 * v + k] = turned[k];
    }
    if (mesh.has_tangents()) {
      const double* t = &rest.tangents[4 * v];
      const glm::dvec3 turned = glm::normalize(blend.real * glm::dvec3(t[0], t[1], t[2]));
      for (int k = 0; k < 3; ++k) out.tangents[4 * v + k] = turned[k];
      out.tangents[4 * v + 3] = t[3];
    }
  }
  return out;
}

}  // namespace skinserve
