#include <fmt/format.h>

#include <map>

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

void AddMethodOption(CLI::App* command, SkinningMethod* method) {
  command
      ->add_option("--method", *method,
                   "skinning method: linear (default), or dual-quaternion (rigid joints only)")
      ->transform(CLI::CheckedTransformer(
          std::map<std::string, SkinningMethod>{
              {"linear", SkinningMethod::kLinear},
              {"dual-quaternion", SkinningMethod::kDualQuaternion}},
          CLI::ignore_case));
}

int Report(const Status& status) {
  if (status.ok()) return 0;
  fmt::print(stderr, "error: {}\n", status.ToString());
  return 1;
}

}  // namespace skinserve::cli
