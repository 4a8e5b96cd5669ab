#include <fmt/format.h>

#include "commands.h"
#include "skinserve/client/channel.h"

namespace skinserve::cli {

void AddRegionsCommand(CLI::App& app, CommonOptions& common) {
  auto* command = app.add_subcommand(
      "regions",
      "this process's shared-memory regions (the server shows each client its own), and the "
      "server's limits");
  command->callback([&common] {
    auto channel = common.Channel();
    if (!channel.ok()) {
      common.exit_code = Report(channel.status());
      return;
    }
    client::SkinClient client(*channel, common.Limits());
    auto list = client.ListRegions();
    if (!list.ok()) {
      common.exit_code = Report(list.status());
      return;
    }
    fmt::print("{:<24} {:<32} {:>14} {:>10} {:>8}\n", "name", "key", "bytes", "frames", "idle s");
    for (const auto& r : list->regions()) {
      fmt::print("{:<24} {:<32} {:>14} {:>10} {:>8.1f}\n", r.name(), r.key(), r.byte_size(),
                 r.frames_written(), r.idle_seconds());
    }
    fmt::print(
        "{} regions of this client; all clients' regions map {} of {} bytes in {}; at most {} "
        "({} per client); dropped after {} s unused\n",
        list->regions_size(), list->mapped_bytes(), list->budget_bytes(), list->shm_dir(),
        list->max_regions(), list->max_regions_per_connection(), list->idle_limit_seconds());
  });
}

}  // namespace skinserve::cli
