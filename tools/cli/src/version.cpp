#include "skinserve/cli/version.h"

namespace skinserve::cli {

const char* VersionString() { return SKINSERVE_VERSION_STRING; }

void AddVersionFlag(CLI::App& app, const std::string& program) {
  app.set_version_flag("--version", program + " " + VersionString(), "print the version and exit");
}

}  // namespace skinserve::cli
