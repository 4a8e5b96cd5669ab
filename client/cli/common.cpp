#include <fmt/format.h>

#include "commands.h"

namespace skinserve::cli {

void MeshOptionsCli::Add(CLI::App* command) {
  command->add_option("--vertices", spec.vertex_count, "synthetic mesh: vertex count")
      ->capture_default_str();
  command->add_option("--bones", spec.influences, "synthetic mesh: influences per vertex (1..8)")
      ->capture_default_str();
  command->add_option("--joints", spec.joint_count, "synthetic mesh: joint count")
      ->capture_default_str();
  command->add_flag("--normals", spec.normals, "synthetic mesh: with normals");
  command->add_option("--seed", spec.seed, "synthetic mesh: seed")->capture_default_str();
}

int Report(const Status& status) {
  if (status.ok()) return 0;
  fmt::print(stderr, "error: {}\n", status.ToString());
  return 1;
}

}  // namespace skinserve::cli
