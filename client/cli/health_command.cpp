#include <fmt/format.h>

#include "commands.h"
#include "skinserve/client/channel.h"

namespace skinserve::cli {

void AddHealthCommand(CLI::App& app, CommonOptions& common) {
  auto* command = app.add_subcommand("health", "exit 0 if the server reports SERVING");
  auto wait_seconds = std::make_shared<double>(0);
  command->add_option("--wait", *wait_seconds, "keep asking for up to this many seconds")
      ->capture_default_str();
  command->callback([&common, wait_seconds] {
    auto channel = client::MakeChannel(common.target);
    const auto timeout = std::chrono::milliseconds(static_cast<int64_t>(*wait_seconds * 1000));
    Status s = *wait_seconds > 0 ? client::WaitUntilServing(*channel, timeout)
                                 : client::CheckHealth(*channel, std::chrono::seconds(5));
    if (s.ok()) fmt::print("SERVING\n");
    common.exit_code = Report(s);
  });
}

}  // namespace skinserve::cli
