#include "server_metrics.h"

#include <fmt/format.h>
#include <httplib.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <set>
#include <sstream>
#include <utility>
#include <vector>

namespace skinserve::load {
namespace {

bool IsNameChar(char c, bool first) {
  return std::isalpha(static_cast<unsigned char>(c)) || c == '_' || c == ':' ||
         (!first && std::isdigit(static_cast<unsigned char>(c)));
}

// A sample value: a float, NaN, +Inf or -Inf.
bool ParseValue(const std::string& token, double* value) {
  if (token == "NaN") return *value = std::nan(""), true;
  if (token == "+Inf" || token == "Inf") return *value = INFINITY, true;
  if (token == "-Inf") return *value = -INFINITY, true;
  if (token.empty()) return false;
  char* end = nullptr;
  *value = std::strtod(token.c_str(), &end);
  return end == token.c_str() + token.size();
}

// The family a series belongs to for # TYPE: a histogram's or summary's name without
// its _bucket, _sum or _count.
std::string FamilyOf(const std::string& name, const std::map<std::string, std::string>& types) {
  for (const char* suffix : {"_bucket", "_sum", "_count"}) {
    const std::string s = suffix;
    if (name.size() > s.size() && name.ends_with(s)) {
      const std::string base = name.substr(0, name.size() - s.size());
      if (types.count(base)) return base;
    }
  }
  return name;
}

}  // namespace

Result<MetricSamples> ParseMetricsText(const std::string& text) {
  MetricSamples samples;
  std::map<std::string, std::string> types;  // family -> counter, gauge, histogram, ...
  std::istringstream in(text);
  int number = 0;
  for (std::string line; std::getline(in, line);) {
    ++number;
    if (!line.empty() && line.back() == '\r') line.pop_back();
    const auto bad = [&](const std::string& why) {
      return InvalidArgument(fmt::format("metrics line {}: {}: '{}'", number, why, line));
    };
    std::size_t i = line.find_first_not_of(" \t");
    if (i == std::string::npos) continue;
    if (line[i] == '#') {
      std::istringstream comment(line.substr(i + 1));
      std::string keyword, family, type;
      comment >> keyword >> family >> type;
      if (keyword == "TYPE") types[family] = type;
      continue;
    }
    const std::size_t name_start = i;
    if (!IsNameChar(line[i], true)) return bad("a sample must start with a metric name");
    while (i < line.size() && IsNameChar(line[i], false)) ++i;
    const std::string name = line.substr(name_start, i - name_start);
    std::vector<std::pair<std::string, std::string>> labels;
    if (i < line.size() && line[i] == '{') {
      ++i;
      while (true) {
        while (i < line.size() && (line[i] == ' ' || line[i] == ',')) ++i;
        if (i >= line.size()) return bad("labels without their closing '}'");
        if (line[i] == '}') {
          ++i;
          break;
        }
        const std::size_t label_start = i;
        while (i < line.size() && IsNameChar(line[i], i == label_start)) ++i;
        const std::string label = line.substr(label_start, i - label_start);
        if (label.empty() || i >= line.size() || line[i] != '=') {
          return bad("a label must be NAME=\"VALUE\"");
        }
        if (++i >= line.size() || line[i] != '"') return bad("a label value must be quoted");
        std::string value;  // kept escaped, as the series key writes it
        for (++i; i < line.size() && line[i] != '"'; ++i) {
          if (line[i] == '\\' && i + 1 < line.size()) value += line[i++];
          value += line[i];
        }
        if (i >= line.size()) return bad("a label value without its closing quote");
        ++i;
        labels.emplace_back(label, value);
      }
    }
    std::istringstream rest(line.substr(i));
    std::string value_text;
    rest >> value_text;
    double value = 0;
    if (!ParseValue(value_text, &value)) return bad("the value is not a number");
    std::sort(labels.begin(), labels.end());
    std::string key = name;
    if (!labels.empty()) {
      key += '{';
      for (std::size_t l = 0; l < labels.size(); ++l) {
        key += fmt::format("{}{}=\"{}\"", l ? "," : "", labels[l].first, labels[l].second);
      }
      key += '}';
    }
    const std::string family = FamilyOf(name, types);
    const auto type = types.find(family);
    // A histogram's buckets would bury the report in dozens of series per backend: its
    // _sum and _count say what a row needs.
    const bool cumulative = type == types.end() || type->second == "counter" ||
                            type->second == "untyped" ||
                            ((type->second == "histogram" || type->second == "summary") &&
                             name != family && !name.ends_with("_bucket"));
    if (cumulative) samples[key] = value;
  }
  return samples;
}

Result<MetricSamples> ScrapeMetrics(const std::string& url, double timeout_seconds) {
  const std::string scheme = "http://";
  if (!url.starts_with(scheme)) {
    return InvalidArgument(
        fmt::format("--metrics-url '{}': expected http://HOST[:PORT][/PATH]", url));
  }
  const std::size_t slash = url.find('/', scheme.size());
  const std::string authority = url.substr(scheme.size(), slash - scheme.size());
  const std::string path = slash == std::string::npos ? "/metrics" : url.substr(slash);
  std::string host = authority;
  int port = 80;
  if (const std::size_t colon = authority.rfind(':');
      colon != std::string::npos && authority.find(']', colon) == std::string::npos) {
    host = authority.substr(0, colon);
    const std::string digits = authority.substr(colon + 1);
    if (digits.empty() || digits.size() > 5 ||
        digits.find_first_not_of("0123456789") != std::string::npos || std::stoi(digits) > 65535) {
      return InvalidArgument(
          fmt::format("--metrics-url '{}': the port must be a number 0..65535", url));
    }
    port = std::stoi(digits);
  }
  if (host.size() > 2 && host.front() == '[' && host.back() == ']') {
    host = host.substr(1, host.size() - 2);
  }
  if (host.empty()) return InvalidArgument(fmt::format("--metrics-url '{}': no host", url));
  httplib::Client http(host, port);
  const auto timeout = std::chrono::duration<double>(timeout_seconds);
  http.set_connection_timeout(std::chrono::duration_cast<std::chrono::microseconds>(timeout));
  http.set_read_timeout(std::chrono::duration_cast<std::chrono::microseconds>(timeout));
  const httplib::Result response = http.Get(path);
  if (!response) {
    return Unavailable(
        fmt::format("--metrics-url {}: {}", url, httplib::to_string(response.error())));
  }
  if (response->status != 200) {
    return Unavailable(fmt::format("--metrics-url {}: HTTP status {}", url, response->status));
  }
  auto samples = ParseMetricsText(response->body);
  if (!samples.ok()) {
    return InvalidArgument(fmt::format("--metrics-url {}: {}", url, samples.status().message()));
  }
  return samples;
}

MetricSamples MetricDeltas(const MetricSamples& before, const MetricSamples& after) {
  MetricSamples deltas;
  for (const auto& [series, value] : after) {
    const auto was = before.find(series);
    double delta = was == before.end() ? value : value - was->second;
    if (delta < 0) delta = value;  // reset: counted from 0 again
    if (delta != 0 && !std::isnan(delta)) deltas[series] = delta;
  }
  return deltas;
}

std::optional<double> CpuSecondsBetween(const MetricSamples& before, const MetricSamples& after) {
  const std::string series = "process_cpu_seconds_total";
  const auto was = before.find(series), is = after.find(series);
  if (was == before.end() || is == after.end()) return std::nullopt;
  const double spent = is->second - was->second;
  if (!(spent >= 0)) return std::nullopt;  // a restart, or NaN
  return spent;
}

double SumSeries(const MetricSamples& samples, const std::string& name,
                 const std::vector<std::string>& labels) {
  double sum = 0;
  for (const auto& [series, value] : samples) {
    if (!series.starts_with(name)) continue;
    if (series.size() != name.size() && series[name.size()] != '{') continue;
    const bool all = std::all_of(labels.begin(), labels.end(), [&](const std::string& label) {
      const std::size_t at = series.find(label);
      return at != std::string::npos && (series[at - 1] == '{' || series[at - 1] == ',');
    });
    if (all) sum += value;
  }
  return sum;
}

}  // namespace skinserve::load
