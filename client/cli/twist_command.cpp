// skinserve-cli twist: the picture on docs/backends/dual-quaternion.md of linear blend against
// dual-quaternion skinning. The twisted cylinder (core/twist_cylinder.h) is skinned by the server
// at each angle under both methods, every frame checked against its float64 reference, drawn by the
// project's renderer and gathered into one sheet: linear on the top row, dual-quaternion below.
#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <filesystem>

#include "commands.h"
#include "skinserve/client/channel.h"
#include "skinserve/reference/reference.h"
#include "skinserve/reference/twist_cylinder.h"
#include "skinserve/render/bounds.h"
#include "skinserve/render/camera.h"
#include "skinserve/render/contact_sheet.h"
#include "skinserve/render/mesh_renderer.h"

namespace skinserve::cli {
namespace {

struct TwistOptions {
  std::string out;
  std::string backend = "sse-openmp";
  std::vector<double> angles = {0, 45, 90, 135, 180};
  int width = 240, height = 400;  // of each frame
};

// The middle ring's smallest distance from the axis: where linear skinning collapses.
double MiddleRingRadius(const TwistCylinder& c, std::span<const float> positions) {
  double radius = INFINITY;
  for (uint32_t k = 0; k < c.segments; ++k) {
    const float* p = &positions[3 * ((c.rings / 2) * c.segments + k)];
    radius = std::min(radius, std::hypot(double{p[0]}, double{p[2]}));
  }
  return radius;
}

int Twist(const CommonOptions& common, const TwistOptions& o) {
  if (o.angles.empty()) return Report(InvalidArgument("--angles: give at least one"));
  std::error_code error;
  std::filesystem::create_directories(o.out, error);
  if (error) {
    return Report(Internal(fmt::format("--out {}: cannot create: {}", o.out, error.message())));
  }
  const TwistCylinder cylinder = MakeTwistCylinder();
  const auto local = Mesh::Create(cylinder.mesh);
  if (!local.ok()) return Report(local.status());
  auto channel = common.Channel();
  if (!channel.ok()) return Report(channel.status());
  client::SkinClient client(*channel, common.Limits());
  auto info = client.Upload(cylinder.mesh);
  if (!info.ok()) return Report(info.status());
  // One camera for every frame: the rest pose, with room for nothing to leave it.
  auto box = render::BoundsOf(cylinder.mesh.positions);
  if (!box.ok()) return Report(box.status());
  const render::Camera camera =
      render::Camera::Framing(*box, o.width, o.height, {.elevation_degrees = 20.0f});

  std::vector<render::SheetFrame> sheet;
  uint64_t frame = 0;
  for (SkinningMethod method : {SkinningMethod::kLinear, SkinningMethod::kDualQuaternion}) {
    for (double degrees : o.angles) {
      const std::vector<float> palette = MakeTwistPalette(degrees);
      client::FrameResult result;
      Status s = client.Skin(info->mesh_id(), o.backend, palette, frame, true, &result, method);
      if (!s.ok()) return Report(s);
      const Deviation d =
          CompareWithReference(**local, palette, result.positions, result.normals, method);
      if (!d.within_tolerance()) {
        return Report(Internal(fmt::format(
            "{} at {} degrees: position error {:.3g} over the tolerance {:.3g} (normals {:.3g})",
            MethodName(method), degrees, d.max_position_error, d.position_tolerance,
            d.max_normal_error)));
      }
      const std::string path =
          fmt::format("{}/{}-{:03.0f}.png", o.out, MethodName(method), degrees);
      if (Status r = render::RenderPng(path, camera, result.positions, cylinder.triangles);
          !r.ok()) {
        return Report(r);
      }
      const double radius = MiddleRingRadius(cylinder, result.positions);
      fmt::print("{:<16} {:>5.1f} degrees: middle ring radius {:.4f} (rest {:.4f})\n",
                 MethodName(method), degrees, radius, cylinder.radius);
      sheet.push_back({path, fmt::format("{} {:.0f} deg", MethodName(method), degrees)});
      ++frame;
    }
  }
  const std::string path = o.out + "/twist.png";
  const render::SheetOptions options{.columns = static_cast<int>(o.angles.size()),
                                     .width = static_cast<int>(o.angles.size()) * o.width};
  if (Status s = render::WriteContactSheet(path, sheet, options); !s.ok()) return Report(s);
  fmt::print("wrote {} (top: linear, bottom: dual-quaternion; backend {})\n", path, o.backend);
  return 0;
}

}  // namespace

void AddTwistCommand(CLI::App& app, CommonOptions& common) {
  auto* command = app.add_subcommand(
      "twist",
      "skin a cylinder twisted 0..180 degrees with linear and dual-quaternion skinning on the "
      "server; draw DIR/twist.png (top row linear, bottom dual-quaternion)");
  auto o = std::make_shared<TwistOptions>();
  command->add_option("--out", o->out, "output directory (created if missing)")->required();
  command->add_option("--backend", o->backend, "a backend that implements both methods")
      ->capture_default_str();
  command->add_option("--angles", o->angles, "twist angles in degrees, one column each")
      ->delimiter(',')
      ->check(CLI::Range(-720.0, 720.0));
  command->add_option("--width", o->width, "width of each frame")
      ->check(CLI::Range(16, 2048))
      ->capture_default_str();
  command->add_option("--height", o->height, "height of each frame")
      ->check(CLI::Range(16, 2048))
      ->capture_default_str();
  command->callback([&common, o] { common.exit_code = Twist(common, *o); });
}

}  // namespace skinserve::cli
