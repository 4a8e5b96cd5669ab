#include "observability/metrics_request.h"

#include <fmt/format.h>

namespace skinserve::server {

namespace {

constexpr std::string_view kExpositionType = "text/plain; version=0.0.4; charset=utf-8";

std::string Answer(int code, std::string_view reason, std::string_view extra_headers,
                   std::string_view content_type, std::string_view body, bool with_body) {
  // Connection: close on every answer: one request per connection, so a body that follows
  // a head is never read and a kept-alive connection never holds a slot.
  std::string out = fmt::format(
      "HTTP/1.1 {} {}\r\n{}Content-Type: {}\r\nContent-Length: {}\r\nConnection: close\r\n\r\n",
      code, reason, extra_headers, content_type, body.size());
  if (with_body) out.append(body);
  return out;
}

}  // namespace

std::size_t RequestHeadEnd(std::string_view received, std::size_t searched_up_to) {
  const std::size_t from = searched_up_to >= 3 ? searched_up_to - 3 : 0;
  for (std::size_t i = received.find('\n', from); i != std::string_view::npos;
       i = received.find('\n', i + 1)) {
    if (i + 1 < received.size() && received[i + 1] == '\n') return i + 2;
    if (i + 2 < received.size() && received[i + 1] == '\r' && received[i + 2] == '\n') {
      return i + 3;
    }
  }
  return std::string_view::npos;
}

MetricsRequest JudgeRequestHead(std::string_view head) {
  // RFC 9112 2.2: empty lines before the request line are ignored.
  while (!head.empty() && (head.front() == '\r' || head.front() == '\n')) head.remove_prefix(1);
  std::string_view line = head.substr(0, head.find('\n'));
  if (!line.empty() && line.back() == '\r') line.remove_suffix(1);
  const std::size_t first = line.find(' ');
  const std::size_t second = first == std::string_view::npos ? first : line.find(' ', first + 1);
  if (first == 0 || second == std::string_view::npos || second == first + 1 ||
      line.find(' ', second + 1) != std::string_view::npos) {
    return MetricsRequest::kBadRequest;
  }
  const std::string_view method = line.substr(0, first);
  const std::string_view target = line.substr(first + 1, second - first - 1);
  const std::string_view version = line.substr(second + 1);
  if (version != "HTTP/1.1" && version != "HTTP/1.0") return MetricsRequest::kBadRequest;
  const bool head_only = method == "HEAD";
  if (method != "GET" && !head_only) return MetricsRequest::kMethodNotAllowed;
  if (target.substr(0, target.find('?')) != "/metrics") return MetricsRequest::kNotFound;
  return head_only ? MetricsRequest::kScrapeHead : MetricsRequest::kScrape;
}

std::string ScrapeAnswer(const std::string& exposition, bool with_body) {
  return Answer(200, "OK", "", kExpositionType, exposition, with_body);
}

std::string RefusalAnswer(MetricsRefusal refusal) {
  constexpr std::string_view kText = "text/plain; charset=utf-8";
  switch (refusal) {
    case MetricsRefusal::kBadRequest:
      return Answer(400, "Bad Request", "", kText, "not an HTTP/1.0 or HTTP/1.1 request line\n",
                    true);
    case MetricsRefusal::kNotFound:
      return Answer(404, "Not Found", "", kText, "this port serves GET /metrics only\n", true);
    case MetricsRefusal::kMethodNotAllowed:
      return Answer(405, "Method Not Allowed", "Allow: GET, HEAD\r\n", kText,
                    "this port serves GET /metrics only; request bodies are not read\n", true);
    case MetricsRefusal::kTimeout:
      return Answer(408, "Request Timeout", "", kText,
                    fmt::format("the request line and headers must arrive within {} s\n",
                                metrics_port::kRequestTimeout.count()),
                    true);
    case MetricsRefusal::kHeadTooLong:
      return Answer(431, "Request Header Fields Too Large", "", kText,
                    fmt::format("the request line and headers exceed {} bytes\n",
                                metrics_port::kMaxRequestHeadBytes),
                    true);
    case MetricsRefusal::kRenderFailed:
      break;
  }
  return Answer(500, "Internal Server Error", "", kText, "the metrics could not be rendered\n",
                true);
}

}  // namespace skinserve::server
