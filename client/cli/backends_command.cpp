#include <fmt/format.h>

#include "commands.h"
#include "skinserve/client/channel.h"

namespace skinserve::cli {

void AddBackendsCommand(CLI::App& app, CommonOptions& common) {
  auto* command = app.add_subcommand("backends", "list the server's backends");
  command->callback([&common] {
    client::SkinClient client(client::MakeChannel(common.target));
    auto list = client.ListBackends();
    if (!list.ok()) {
      common.exit_code = Report(list.status());
      return;
    }
    fmt::print("{:<16} {:<9} {:>4} {:>7}  {}\n", "id", "available", "simd", "threads", "device");
    for (const auto& b : list->backends()) {
      fmt::print("{:<16} {:<9} {:>4} {:>7}  {}{}{}\n", b.id(), b.available() ? "yes" : "no",
                 b.simd_width(), b.threads(), b.device(),
                 b.simd_target().empty() ? "" : " [" + b.simd_target() + "]",
                 b.available() ? "" : "  (" + b.unavailable_reason() + ")");
    }
    fmt::print("default: {}\n", list->default_backend());
  });
}

}  // namespace skinserve::cli
