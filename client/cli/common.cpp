#include <fmt/format.h>
#include <google/protobuf/util/json_util.h>

#include <map>

#include "commands.h"

namespace skinserve::cli {

using client::FlagMilliseconds;

Result<std::shared_ptr<grpc::Channel>> CommonOptions::Channel() const {
  auto options = connection.ToChannelOptions();
  if (!options.ok()) return options.status();
  return client::MakeChannel(target, *options);
}

client::CallLimits CommonOptions::Limits() const {
  return {.deadline = FlagMilliseconds(deadline_seconds),
          .upload_deadline = FlagMilliseconds(upload_deadline_seconds),
          .stream_idle = FlagMilliseconds(stream_idle_seconds)};
}

void AddCommonOptions(CLI::App& app, CommonOptions& common) {
  app.add_option("--target", common.target,
                 "gRPC target of the server(s), e.g. 127.0.0.1:50051, "
                 "ipv4:127.0.0.1:50051,127.0.0.1:50052 (round_robin) or unix:PATH")
      ->envname("SKINSERVE_TARGET")
      ->capture_default_str();
  client::AddConnectionFlags(app, common.connection);
  app.add_option("--deadline-seconds", common.deadline_seconds,
                 "deadline of each call and each single frame (0: none)")
      ->check(CLI::NonNegativeNumber)
      ->capture_default_str();
  app.add_option("--upload-deadline-seconds", common.upload_deadline_seconds,
                 "deadline of each mesh upload, whole (0: none)")
      ->check(CLI::NonNegativeNumber)
      ->capture_default_str();
  app.add_option("--stream-idle-seconds", common.stream_idle_seconds,
                 "a stream with frames in flight and no answer for this long is ended "
                 "(DEADLINE_EXCEEDED) and the next one opened (0: wait for ever)")
      ->check(CLI::NonNegativeNumber)
      ->capture_default_str();
}

Result<SyntheticUpload> UploadSynthetic(const CommonOptions& common,
                                        const SyntheticMeshSpec& spec) {
  auto channel = common.Channel();
  if (!channel.ok()) return channel.status();
  SyntheticUpload upload{.client = std::make_unique<client::SkinClient>(*channel, common.Limits()),
                         .arrays = MakeSyntheticMesh(spec),
                         .mesh_id = ""};
  auto info = upload.client->Upload(upload.arrays);
  if (!info.ok()) return info.status();
  upload.mesh_id = info->mesh_id();
  return upload;
}

void MeshOptionsCli::Add(CLI::App* command) {
  command->add_option("--vertices", spec.vertex_count, "synthetic mesh: vertex count")
      ->capture_default_str();
  command->add_option("--bones", spec.influences, "synthetic mesh: influences per vertex (1..8)")
      ->capture_default_str();
  command->add_option("--joints", spec.joint_count, "synthetic mesh: joint count")
      ->capture_default_str();
  command->add_flag("--normals", spec.normals, "synthetic mesh: with normals");
  command->add_flag("--tangents", spec.tangents,
                    "synthetic mesh: with tangents too (needs --normals), asked for back "
                    "(want_tangents)");
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
  if (const std::string hint = client::ConnectionHint(status); !hint.empty()) {
    fmt::print(stderr, "hint: {}\n", hint);
  }
  return 1;
}

int PrintJson(const google::protobuf::Message& message) {
  google::protobuf::util::JsonPrintOptions options;
  options.always_print_primitive_fields = true;
  options.preserve_proto_field_names = true;
  std::string text;
  if (const auto status = google::protobuf::util::MessageToJsonString(message, &text, options);
      !status.ok()) {
    return Report(Internal(fmt::format("--json: {}", status.ToString())));
  }
  fmt::print("{}\n", text);
  return 0;
}

}  // namespace skinserve::cli
