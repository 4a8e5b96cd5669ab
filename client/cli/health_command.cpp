#include <fmt/format.h>

#include <algorithm>
#include <thread>

#include "commands.h"
#include "skinserve/client/channel.h"

namespace skinserve::cli {

void AddHealthCommand(CLI::App& app, CommonOptions& common) {
  auto* command = app.add_subcommand("health", "exit 0 if the server reports SERVING");
  auto wait_seconds = std::make_shared<double>(0);
  auto service = std::make_shared<std::string>();
  command->add_option("--wait", *wait_seconds, "keep asking for up to this many seconds")
      ->capture_default_str();
  command->add_option("--service", *service,
                      "the health service's name to ask about: empty, the whole server (ready: "
                      "every backend built, not draining), or 'liveness' (serving at all, "
                      "draining included)");
  command->callback([&common, wait_seconds, service] {
    auto channel = common.Channel();
    if (!channel.ok()) {
      common.exit_code = Report(channel.status());
      return;
    }
    // Each ask waits at most 5 s, or --deadline-seconds when that is shorter.
    const double ask_seconds =
        common.deadline_seconds > 0 ? std::min(common.deadline_seconds, 5.0) : 5.0;
    const auto ask = std::chrono::milliseconds(static_cast<int64_t>(ask_seconds * 1000));
    const auto timeout = std::chrono::milliseconds(static_cast<int64_t>(*wait_seconds * 1000));
    Status s = Unavailable("not asked");
    const auto deadline = std::chrono::steady_clock::now() + timeout;
    do {
      s = client::CheckHealth(**channel, ask, *service);
      if (s.ok() || std::chrono::steady_clock::now() >= deadline) break;
      std::this_thread::sleep_for(std::chrono::milliseconds(100));
    } while (true);
    if (s.ok()) fmt::print("SERVING\n");
    common.exit_code = Report(s);
  });
}

}  // namespace skinserve::cli
