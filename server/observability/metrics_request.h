// What the metrics port makes of one request head (request line and headers), and the
// answers it sends: GET or HEAD of /metrics is a scrape, everything else a refusal that
// says why. No body is ever read (every answer closes the connection), so a request is
// judged by its head alone. Kept apart from the sockets (metrics_server.cpp).
#pragma once

#include <cstddef>
#include <string>
#include <string_view>

#include "observability/metrics_port_limits.h"

namespace skinserve::server {

enum class MetricsRequest {
  kScrape,            // GET /metrics
  kScrapeHead,        // HEAD /metrics: the scrape's headers, no body
  kBadRequest,        // 400: not an HTTP/1.0 or 1.1 request line
  kNotFound,          // 404: a path other than /metrics
  kMethodNotAllowed,  // 405: a method other than GET and HEAD
};

// Where a request head ends in `received` (just past its empty line: "\r\n\r\n", or "\n\n"
// from lenient clients), or npos. `searched_up_to` bytes were searched before: only what
// came after them (and the 3 bytes before, where an end may straddle) is searched again.
std::size_t RequestHeadEnd(std::string_view received, std::size_t searched_up_to);

// The request line decides; headers are not needed and not looked at.
MetricsRequest JudgeRequestHead(std::string_view head);

// The whole answer to a scrape: status line, headers, and `exposition` unless it is HEAD.
std::string ScrapeAnswer(const std::string& exposition, bool with_body);

// A refusal: 400, 404, 405, 408 (head not complete in time), 431 (head too long) or 500
// (the exposition could not be rendered), with a one-line body that names the rule.
enum class MetricsRefusal {
  kBadRequest,
  kNotFound,
  kMethodNotAllowed,
  kTimeout,
  kHeadTooLong,
  kRenderFailed
};
std::string RefusalAnswer(MetricsRefusal refusal);

}  // namespace skinserve::server
