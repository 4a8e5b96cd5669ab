#include <fmt/format.h>

#include "commands.h"
#include "skinserve/client/channel.h"

namespace skinserve::cli {

void AddStatsCommand(CLI::App& app, CommonOptions& common) {
  auto* command = app.add_subcommand("stats", "the server's counters per backend");
  auto frames_only = std::make_shared<bool>(false);
  auto json = std::make_shared<bool>(false);
  auto* frames_flag = command->add_flag("--frames-only", *frames_only,
                                        "print only the total frames served (for scripts)");
  command
      ->add_flag("--json", *json,
                 "print GetServerStats' answer as one JSON object (the .proto's field names)")
      ->excludes(frames_flag);
  command->callback([&common, frames_only, json] {
    auto channel = common.Channel();
    if (!channel.ok()) {
      common.exit_code = Report(channel.status());
      return;
    }
    client::SkinClient client(*channel, common.Limits());
    auto stats = client.GetServerStats();
    if (!stats.ok()) {
      common.exit_code = Report(stats.status());
      return;
    }
    if (*json) {
      common.exit_code = PrintJson(*stats);
      return;
    }
    uint64_t total = 0;
    for (const auto& b : stats->backends()) total += b.frames();
    if (*frames_only) {
      fmt::print("{}\n", total);
      return;
    }
    fmt::print("{:<16} {:>10} {:>14} {:>8} {:>12}\n", "backend", "frames", "vertices", "errors",
               "compute ms");
    for (const auto& b : stats->backends()) {
      fmt::print("{:<16} {:>10} {:>14} {:>8} {:>12.1f}\n", b.id(), b.frames(), b.vertices(),
                 b.errors(), b.compute_ns_total() / 1e6);
    }
    fmt::print("total frames {}; queue {}/{}; compute threads {}; open streams {}\n", total,
               stats->queue_depth(), stats->queue_capacity(), stats->compute_threads(),
               stats->open_streams());
    fmt::print("meshes {} using {} of {} bytes; evictions {}; frames refused (queue full) {}\n",
               stats->meshes(), stats->mesh_bytes(), stats->mesh_budget_bytes(), stats->evictions(),
               stats->rejected_queue_full());
    fmt::print(
        "shared-memory regions {} mapping {} of {} bytes; frames written into them {}; "
        "registrations refused {}\n",
        stats->regions(), stats->region_bytes(), stats->region_budget_bytes(),
        stats->region_frames(), stats->rejected_regions());
    fmt::print("animation: skeletons {} and clips {} using {} of {} bytes\n", stats->skeletons(),
               stats->clips(), stats->clip_bytes(), stats->clip_budget_bytes());
  });
}

}  // namespace skinserve::cli
