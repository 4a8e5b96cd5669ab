// skinserve-cli's subcommands, one file each. Each registers itself on the app and runs
// through the callback it sets; `exit_code` carries the result back to main.
#pragma once

#include <google/protobuf/message.h>
#include <CLI/CLI.hpp>

#include <memory>
#include <string>

#include "connection_flags.h"
#include "skinserve/client/channel.h"
#include "skinserve/client/skin_client.h"
#include "skinserve/model/skinning_method.h"
#include "skinserve/reference/synthetic.h"

namespace skinserve::cli {

// The options before the subcommand: where the server is, how to reach it, how long to wait.
struct CommonOptions {
  std::string target = "127.0.0.1:50051";
  client::ConnectionFlags connection;  // TLS and keepalive
  double deadline_seconds = 30;
  double upload_deadline_seconds = 300;
  double stream_idle_seconds = 30;
  int exit_code = 0;

  // A channel to `target` (TLS when --tls-ca is given); an unreadable file is an error
  // naming its option.
  Result<std::shared_ptr<grpc::Channel>> Channel() const;
  client::CallLimits Limits() const;
};

// --target, --tls-*, --deadline-seconds, ... on the app, each with its environment variable.
void AddCommonOptions(CLI::App& app, CommonOptions& common);

// The synthetic mesh options shared by upload, skin, stream and verify.
struct MeshOptionsCli {
  SyntheticMeshSpec spec{.vertex_count = 100'000, .influences = 2};
  void Add(CLI::App* command);
};

// A client on the command's channel with a synthetic mesh made from `spec` and uploaded:
// what skin, stream and verify start from.
struct SyntheticUpload {
  std::unique_ptr<client::SkinClient> client;
  MeshArrays arrays;
  std::string mesh_id;
};
Result<SyntheticUpload> UploadSynthetic(const CommonOptions& common, const SyntheticMeshSpec& spec);

void AddHealthCommand(CLI::App& app, CommonOptions& common);
void AddBackendsCommand(CLI::App& app, CommonOptions& common);
void AddUploadCommand(CLI::App& app, CommonOptions& common);
void AddSkinCommand(CLI::App& app, CommonOptions& common);
void AddStreamCommand(CLI::App& app, CommonOptions& common);
void AddStatsCommand(CLI::App& app, CommonOptions& common);
void AddVerifyCommand(CLI::App& app, CommonOptions& common);
void AddAnimateCommand(CLI::App& app, CommonOptions& common);
void AddTwistCommand(CLI::App& app, CommonOptions& common);
void AddRegionsCommand(CLI::App& app, CommonOptions& common);
void AddTickCommand(CLI::App& app, CommonOptions& common);

// --method linear|dual-quaternion on `command`, into `method`.
void AddMethodOption(CLI::App* command, SkinningMethod* method);

// Prints `status` to stderr and returns its exit code (0 for OK).
int Report(const Status& status);

// Prints `message` on stdout as one JSON object (protobuf's JSON mapping: the .proto's
// field names, every field even when 0; 64-bit integers as strings) for --json.
int PrintJson(const google::protobuf::Message& message);

}  // namespace skinserve::cli
