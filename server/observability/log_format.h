// The server's log lines: spdlog's default text, or one JSON object per line for log
// pipelines (Loki, Elasticsearch, Cloud Logging): time (UTC, RFC 3339), level, thread,
// message, each string escaped as JSON requires.
#pragma once

#include <string>

namespace skinserve::server {

// "text" or "json" (the option's check refuses anything else).
void SetLogFormat(const std::string& format);

}  // namespace skinserve::server
