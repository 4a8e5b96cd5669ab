#include "report_files.h"

#include <gtest/gtest.h>

#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <set>
#include <sstream>

namespace skinserve::load {
namespace {

// Splits CSV text (RFC 4180 quoting) into rows of cells.
std::vector<std::vector<std::string>> ReadCsv(const std::string& text) {
  std::vector<std::vector<std::string>> rows(1);
  std::string cell;
  bool quoted = false;
  for (std::size_t i = 0; i < text.size(); ++i) {
    const char c = text[i];
    if (quoted) {
      if (c == '"' && i + 1 < text.size() && text[i + 1] == '"') {
        cell += '"';
        ++i;
      } else if (c == '"') {
        quoted = false;
      } else {
        cell += c;
      }
    } else if (c == '"') {
      quoted = true;
    } else if (c == ',') {
      rows.back().push_back(cell);
      cell.clear();
    } else if (c == '\n') {
      rows.back().push_back(cell);
      cell.clear();
      rows.emplace_back();
    } else {
      cell += c;
    }
  }
  if (rows.back().empty()) rows.pop_back();
  return rows;
}

// JSON leaves by dotted path; the objects of a map-valued column (errors, deltas) are leaves.
void Flatten(const nlohmann::json& value, const std::string& path,
             std::map<std::string, nlohmann::json>* out) {
  static const std::set<std::string> maps = {"errors", "server_metrics.deltas"};
  if (value.is_object() && !maps.count(path)) {
    for (const auto& [key, v] : value.items())
      Flatten(v, path.empty() ? key : path + "." + key, out);
  } else {
    (*out)[path] = value;
  }
}

}  // namespace

void ExpectCsvMatchesJson(const std::string& csv_path, const std::string& json_path) {
  std::ifstream csv_in(csv_path), json_in(json_path);
  std::stringstream csv_text;
  csv_text << csv_in.rdbuf();
  const auto rows = ReadCsv(csv_text.str());
  nlohmann::json doc;
  json_in >> doc;
  ASSERT_EQ(rows.size(), doc["results"].size() + 1);
  for (std::size_t r = 0; r < doc["results"].size(); ++r) {
    std::map<std::string, nlohmann::json> leaves;
    Flatten(doc["results"][r], "", &leaves);
    ASSERT_EQ(rows[r + 1].size(), rows[0].size());
    std::set<std::string> header(rows[0].begin(), rows[0].end());
    for (const auto& [path, value] : leaves)
      EXPECT_TRUE(header.count(path)) << path << " not in CSV";
    for (std::size_t c = 0; c < rows[0].size(); ++c) {
      const std::string& name = rows[0][c];
      const std::string& cell = rows[r + 1][c];
      ASSERT_TRUE(leaves.count(name)) << name << " not in JSON";
      const nlohmann::json& v = leaves[name];
      if (v.is_null()) {
        EXPECT_EQ(cell, "") << name;
      } else if (v.is_number()) {
        EXPECT_DOUBLE_EQ(std::stod(cell), v.get<double>()) << name;
      } else if (v.is_boolean()) {
        EXPECT_EQ(cell, v.get<bool>() ? "true" : "false") << name;
      } else if (v.is_string()) {
        EXPECT_EQ(cell, v.get<std::string>()) << name;
      } else {  // a map: KEY=VALUE;...
        std::map<std::string, double> parsed;
        std::stringstream items(cell);
        for (std::string item; std::getline(items, item, ';');) {
          const std::size_t eq = item.rfind('=');
          parsed[item.substr(0, eq)] = std::stod(item.substr(eq + 1));
        }
        EXPECT_EQ(parsed.size(), v.size()) << name << ": " << cell;
        for (const auto& [key, n] : v.items())
          EXPECT_DOUBLE_EQ(parsed[key], n.get<double>()) << key;
      }
    }
  }
}

}  // namespace skinserve::load
