// skinserve-cli: talk to a skinserve server from the shell.
#include <CLI/CLI.hpp>

#include "commands.h"
#include "skinserve/cli/version.h"

int main(int argc, char** argv) {
  using namespace skinserve::cli;
  CLI::App app{"skinserve-cli: upload meshes, skin frames and check a skinserve server"};
  CommonOptions common;
  AddCommonOptions(app, common);
  AddVersionFlag(app, "skinserve-cli");
  app.require_subcommand(1);
  AddHealthCommand(app, common);
  AddBackendsCommand(app, common);
  AddUploadCommand(app, common);
  AddSkinCommand(app, common);
  AddStreamCommand(app, common);
  AddStatsCommand(app, common);
  AddVerifyCommand(app, common);
  AddAnimateCommand(app, common);
  AddTwistCommand(app, common);
  AddRegionsCommand(app, common);
  AddTickCommand(app, common);
  CLI11_PARSE(app, argc, argv);
  return common.exit_code;
}
