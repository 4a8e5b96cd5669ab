#include "skinserve/reference/synthetic.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <numbers>
#include <numeric>

#include "skinserve/model/palette.h"
#include "splitmix_random.h"

namespace skinserve {
namespace {

using synthetic::Random;

using Vec3 = std::array<double, 3>;

// A branching skeleton: joint j hangs off joint (j - 1) / 2 with a bone of 0.3..0.6.
std::vector<Vec3> MakeSkeleton(uint32_t joint_count, Random& random) {
  std::vector<Vec3> joints(joint_count, Vec3{0, 0, 0});
  for (uint32_t j = 1; j < joint_count; ++j) {
    const Vec3& parent = joints[(j - 1) / 2];
    const Vec3 dir = random.UnitVector();
    const double length = random.Uniform(0.3, 0.6);
    for (int k = 0; k < 3; ++k) joints[j][k] = parent[k] + length * dir[k];
  }
  return joints;
}

// Reorders the vertices (every per-vertex array alike) by their joint lists, compared
// lexicographically; ties keep their order. The mesh has no morph targets yet.
void SortByJoints(MeshArrays* mesh) {
  const uint32_t b = mesh->influences;
  std::vector<uint32_t> order(mesh->vertex_count);
  std::iota(order.begin(), order.end(), 0u);
  std::stable_sort(order.begin(), order.end(), [&](uint32_t l, uint32_t r) {
    return std::lexicographical_compare(
        mesh->joints.begin() + std::size_t{l} * b, mesh->joints.begin() + std::size_t{l + 1} * b,
        mesh->joints.begin() + std::size_t{r} * b, mesh->joints.begin() + std::size_t{r + 1} * b);
  });
  auto permute = [&order](auto& values, std::size_t per_vertex) {
    if (values.empty()) return;
    auto sorted = values;
    for (std::size_t v = 0; v < order.size(); ++v) {
      std::copy_n(values.begin() + order[v] * per_vertex, per_vertex,
                  sorted.begin() + v * per_vertex);
    }
    values = std::move(sorted);
  };
  permute(mesh->positions, 3);
  permute(mesh->normals, 3);
  permute(mesh->tangents, 4);
  permute(mesh->joints, b);
  permute(mesh->weights, b);
}

}  // namespace

MeshArrays MakeSyntheticMesh(const SyntheticMeshSpec& spec) {
  Random random(spec.seed);
  const uint32_t v_count = spec.vertex_count;
  const uint32_t b = spec.influences;
  const uint32_t j_count = std::max<uint32_t>(spec.joint_count, 1);
  const std::vector<Vec3> skeleton = MakeSkeleton(j_count, random);

  MeshArrays mesh;
  mesh.vertex_count = v_count;
  mesh.influences = b;
  mesh.joint_count = j_count;
  mesh.positions.resize(3ull * v_count);
  if (spec.normals) mesh.normals.resize(3ull * v_count);
  const bool tangents = spec.normals && spec.tangents;
  if (tangents) mesh.tangents.resize(4ull * v_count);
  mesh.joints.resize(static_cast<std::size_t>(b) * v_count);
  mesh.weights.resize(static_cast<std::size_t>(b) * v_count);

  constexpr double kFalloff = 0.25;  // distance over which a joint's influence fades
  std::vector<std::pair<double, uint32_t>> nearest(j_count);
  for (uint32_t v = 0; v < v_count; ++v) {
    // A point on the "skin" around a random bone: along the bone, offset radially.
    const uint32_t j = static_cast<uint32_t>(random.Next() % j_count);
    const Vec3& child = skeleton[j];
    const Vec3& parent = skeleton[j == 0 ? 0 : (j - 1) / 2];
    const double t = random.Uniform();
    const Vec3 radial = random.UnitVector();
    const double radius = random.Uniform(0.05, 0.15);
    Vec3 p;
    for (int k = 0; k < 3; ++k) {
      p[k] = parent[k] + t * (child[k] - parent[k]) + radius * radial[k];
      mesh.positions[3ull * v + k] = static_cast<float>(p[k]);
      if (spec.normals) mesh.normals[3ull * v + k] = static_cast<float>(radial[k]);
    }
    if (tangents) {  // radial x axis, the axis least aligned with the normal
      const Vec3 axis = std::fabs(radial[2]) < 0.9 ? Vec3{0, 0, 1} : Vec3{1, 0, 0};
      const Vec3 c = {radial[1] * axis[2] - radial[2] * axis[1],
                      radial[2] * axis[0] - radial[0] * axis[2],
                      radial[0] * axis[1] - radial[1] * axis[0]};
      const double length = std::sqrt(c[0] * c[0] + c[1] * c[1] + c[2] * c[2]);
      for (int k = 0; k < 3; ++k) mesh.tangents[4ull * v + k] = static_cast<float>(c[k] / length);
      mesh.tangents[4ull * v + 3] = v % 3 == 0 ? -1.0f : 1.0f;
    }
    // Smooth weights: a Gaussian falloff over the B nearest joints.
    for (uint32_t k = 0; k < j_count; ++k) {
      const Vec3& q = skeleton[k];
      const double d2 = (p[0] - q[0]) * (p[0] - q[0]) + (p[1] - q[1]) * (p[1] - q[1]) +
                        (p[2] - q[2]) * (p[2] - q[2]);
      nearest[k] = {d2, k};
    }
    const uint32_t used = std::min(b, j_count);
    std::partial_sort(nearest.begin(), nearest.begin() + used, nearest.end());
    double raw[kMaxInfluences] = {};
    double sum = 0;
    for (uint32_t i = 0; i < used; ++i) {
      raw[i] = std::exp(-(nearest[i].first - nearest[0].first) / (2 * kFalloff * kFalloff));
      sum += raw[i];
    }
    for (uint32_t i = 0; i < b; ++i) {
      const std::size_t slot = static_cast<std::size_t>(v) * b + i;
      mesh.joints[slot] = static_cast<uint16_t>(i < used ? nearest[i].second : 0);
      mesh.weights[slot] = static_cast<float>(i < used ? raw[i] / sum : 0.0);
    }
  }
  if (spec.sorted_by_joints) SortByJoints(&mesh);
  return mesh;
}

std::vector<float> MakeSyntheticPalette(uint32_t joint_count, uint64_t seed, uint64_t frame) {
  std::vector<float> palette(kFloatsPerJoint * joint_count);
  Random random(seed ^ 0x5eedf00dull);
  const double time = static_cast<double>(frame) / 30.0;  // as if played at 30 fps
  for (uint32_t j = 0; j < joint_count; ++j) {
    const Vec3 axis = random.UnitVector();
    const double amplitude = random.Uniform(0, std::numbers::pi / 3);
    const double speed = random.Uniform(0.5, 3.0);
    const double phase = random.Uniform(0, 2 * std::numbers::pi);
    const Vec3 offset = random.UnitVector();
    const double wave = std::sin(speed * time + phase);
    const double angle = amplitude * wave;
    const double scale = 1.0 + 0.1 * std::cos(speed * time + phase);
    // Rodrigues: R = I cos + (1 - cos) a a^T + sin [a]x, scaled; then a small translation.
    const double c = std::cos(angle), s = std::sin(angle), x = axis[0], y = axis[1], z = axis[2];
    const double r[3][3] = {
        {c + x * x * (1 - c), x * y * (1 - c) - z * s, x * z * (1 - c) + y * s},
        {y * x * (1 - c) + z * s, c + y * y * (1 - c), y * z * (1 - c) - x * s},
        {z * x * (1 - c) - y * s, z * y * (1 - c) + x * s, c + z * z * (1 - c)}};
    float* m = &palette[kFloatsPerJoint * j];
    for (int row = 0; row < 3; ++row) {
      for (int col = 0; col < 3; ++col) m[4 * row + col] = static_cast<float>(scale * r[row][col]);
      m[4 * row + 3] = static_cast<float>(0.2 * wave * offset[row]);
    }
  }
  return palette;
}

std::vector<float> MakeRigidPalette(uint32_t joint_count, uint64_t seed, uint64_t frame) {
  std::vector<float> palette(kFloatsPerJoint * joint_count);
  Random random((seed ^ 0x71d1dull) + 0x9e37ull * frame);
  for (uint32_t j = 0; j < joint_count; ++j) {
    // Shoemake's uniform random unit quaternion (w, x, y, z), then its rotation matrix.
    const double u1 = random.Uniform(), u2 = random.Uniform(0, 2 * std::numbers::pi),
                 u3 = random.Uniform(0, 2 * std::numbers::pi);
    const double a = std::sqrt(1 - u1), b = std::sqrt(u1);
    const double x = a * std::sin(u2), y = a * std::cos(u2), z = b * std::sin(u3),
                 w = b * std::cos(u3);
    const double r[3][3] = {{1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)},
                            {2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)},
                            {2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)}};
    float* m = &palette[kFloatsPerJoint * j];
    for (int row = 0; row < 3; ++row) {
      for (int col = 0; col < 3; ++col) m[4 * row + col] = static_cast<float>(r[row][col]);
      m[4 * row + 3] = static_cast<float>(random.Uniform(-2, 2));
    }
  }
  return palette;
}

std::vector<float> MakeIdentityPalette(uint32_t joint_count) {
  std::vector<float> palette(kFloatsPerJoint * joint_count, 0.0f);
  for (uint32_t j = 0; j < joint_count; ++j) {
    for (int d = 0; d < 3; ++d) palette[kFloatsPerJoint * j + 5 * d] = 1.0f;
  }
  return palette;
}

}  // namespace skinserve
