// skin-one-frame TARGET: uploads a small mesh to a skinserve server, skins one frame and
// checks every skinned position against its own float64 linear blend skinning. Exits 0
// when all agree within 1e-5 (absolute, plus 1e-6 of the coordinate's size), 1 otherwise.
#include <skinserve/client/channel.h>
#include <skinserve/client/skin_client.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <vector>

namespace {

// 4 vertices, 2 influences each, 3 joints.
skinserve::MeshArrays SmallMesh() {
  skinserve::MeshArrays mesh;
  mesh.vertex_count = 4;
  mesh.influences = 2;
  mesh.joint_count = 3;
  mesh.positions = {0, 0, 0, 1, 0, 0, 0, 2, 0, 0.5f, 0.5f, 3};
  mesh.joints = {0, 1, 1, 2, 0, 2, 2, 1};
  mesh.weights = {0.25f, 0.75f, 0.5f, 0.5f, 1, 0, 0.125f, 0.875f};
  return mesh;
}

// Joint j: a rotation of 0.3 * (j + 1) rad about z, a uniform scale and a translation;
// 3x4 row-major, 12 floats per joint.
std::vector<float> Palette(uint32_t joints) {
  std::vector<float> palette;
  for (uint32_t j = 0; j < joints; ++j) {
    const double angle = 0.3 * (j + 1), scale = 1.0 + 0.1 * j;
    const double c = std::cos(angle) * scale, s = std::sin(angle) * scale;
    const double rows[12] = {c, -s, 0, 1.0 + j, s, c, 0, -0.5 * j, 0, 0, scale, 2.0};
    for (double value : rows) palette.push_back(static_cast<float>(value));
  }
  return palette;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc != 2) {
    std::fprintf(stderr, "usage: %s HOST:PORT\n", argv[0]);
    return 2;
  }
  auto channel = skinserve::client::MakeChannel(argv[1]);
  if (auto s = skinserve::client::WaitUntilServing(*channel, std::chrono::seconds(20)); !s.ok()) {
    std::fprintf(stderr, "server not serving: %s\n", s.ToString().c_str());
    return 1;
  }
  skinserve::client::SkinClient client(channel);
  const skinserve::MeshArrays mesh = SmallMesh();
  auto info = client.Upload(mesh);
  if (!info.ok()) {
    std::fprintf(stderr, "upload: %s\n", info.status().ToString().c_str());
    return 1;
  }
  const std::vector<float> palette = Palette(mesh.joint_count);
  skinserve::client::FrameResult result;
  if (auto s = client.Skin(info->mesh_id(), "", palette, 0, false, &result); !s.ok()) {
    std::fprintf(stderr, "skin: %s\n", s.ToString().c_str());
    return 1;
  }
  if (result.positions.size() != 3 * mesh.vertex_count) {
    std::fprintf(stderr, "skin: %zu floats, expected %u\n", result.positions.size(),
                 3 * mesh.vertex_count);
    return 1;
  }
  // float64 reference: sum over influences of weight * (M_joint * [p, 1]).
  int mismatches = 0;
  double worst = 0;
  for (uint32_t v = 0; v < mesh.vertex_count; ++v) {
    for (int row = 0; row < 3; ++row) {
      double want = 0;
      for (uint32_t i = 0; i < mesh.influences; ++i) {
        const uint32_t k = v * mesh.influences + i;
        const float* m = &palette[12 * mesh.joints[k] + 4 * row];
        double sum = m[3];
        for (int col = 0; col < 3; ++col) sum += double{m[col]} * mesh.positions[3 * v + col];
        want += double{mesh.weights[k]} * sum;
      }
      const double got = result.positions[3 * v + row];
      const double error = std::fabs(got - want);
      worst = std::fmax(worst, error);
      if (error > 1e-5 + 1e-6 * std::fabs(want)) {
        std::fprintf(stderr, "vertex %u row %d: got %.9g, float64 reference %.9g\n", v, row, got,
                     want);
        ++mismatches;
      }
    }
  }
  std::printf("mesh %s: %u vertices skinned, largest error %.3g: %s\n", info->mesh_id().c_str(),
              mesh.vertex_count, worst, mismatches == 0 ? "OK" : "MISMATCH");
  return mismatches == 0 ? 0 : 1;
}
