// skinserve-cli's subcommands, one file each. Each registers itself on the app and runs
// through the callback it sets; `exit_code` carries the result back to main.
#pragma once

#include <CLI/CLI.hpp>

#include <string>

#include "skinserve/client/skin_client.h"
#include "skinserve/model/skinning_method.h"
#include "skinserve/reference/synthetic.h"

namespace skinserve::cli {

struct CommonOptions {
  std::string target = "127.0.0.1:50051";
  int exit_code = 0;
};

// The synthetic mesh options shared by upload, skin, stream and verify.
struct MeshOptionsCli {
  SyntheticMeshSpec spec{.vertex_count = 100'000, .influences = 2};
  void Add(CLI::App* command);
};

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

// --method linear|dual-quaternion on `command`, into `method`.
void AddMethodOption(CLI::App* command, SkinningMethod* method);

// Prints `status` to stderr and returns its exit code (0 for OK).
int Report(const Status& status);

}  // namespace skinserve::cli
