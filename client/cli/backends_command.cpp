#include <fmt/format.h>

#include "commands.h"
#include "skinserve/client/channel.h"
#include "skinserve/encoding/vertex_encoding.h"
#include "skinserve/wire/conversions.h"

namespace skinserve::cli {

void AddBackendsCommand(CLI::App& app, CommonOptions& common) {
  auto* command = app.add_subcommand("backends", "list the server's backends");
  auto json = std::make_shared<bool>(false);
  command->add_flag("--json", *json,
                    "print ListBackends' answer as one JSON object (the .proto's field names)");
  command->callback([&common, json] {
    auto channel = common.Channel();
    if (!channel.ok()) {
      common.exit_code = Report(channel.status());
      return;
    }
    client::SkinClient client(*channel, common.Limits());
    auto list = client.ListBackends();
    if (!list.ok()) {
      common.exit_code = Report(list.status());
      return;
    }
    if (*json) {
      common.exit_code = PrintJson(*list);
      return;
    }
    // encodes: the encodings the backend writes itself (BackendInfo.encoded_outputs; the
    // OpenCL ones on the device); "-": the server encodes every encoding after skinning.
    fmt::print("{:<16} {:<9} {:>4} {:>7}  {:<23}  {:<15}  {}\n", "id", "available", "simd",
               "threads", "methods", "encodes", "device");
    for (const auto& b : list->backends()) {
      std::string methods;
      for (int m : b.methods()) {
        if (!methods.empty()) methods += ',';
        methods += m == v1::SKINNING_METHOD_DUAL_QUATERNION ? "dual-quaternion" : "linear";
      }
      std::string encodes;
      for (int e : b.encoded_outputs()) {
        if (!encodes.empty()) encodes += ',';
        auto known = wire::FromWire(static_cast<v1::Encoding>(e));
        encodes += known.ok() ? std::string(VertexEncodingName(*known)) : std::to_string(e);
      }
      if (encodes.empty()) encodes = "-";
      fmt::print("{:<16} {:<9} {:>4} {:>7}  {:<23}  {:<15}  {}{}{}\n", b.id(),
                 b.available() ? "yes" : "no", b.simd_width(), b.threads(), methods, encodes,
                 b.device(), b.simd_target().empty() ? "" : " [" + b.simd_target() + "]",
                 b.available() ? "" : "  (" + b.unavailable_reason() + ")");
    }
    fmt::print("default: {}\n", list->default_backend());
  });
}

}  // namespace skinserve::cli
