#include "gltf_test_support.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <iterator>
#include <stdexcept>

namespace skinserve::testing {
namespace {

using nlohmann::json;

void PutU32(std::vector<uint8_t>& b, uint32_t v) {
  const auto* p = reinterpret_cast<const uint8_t*>(&v);
  b.insert(b.end(), p, p + 4);
}

}  // namespace

std::string AssetPath(const std::string& file) {
  return std::string(SKINSERVE_TEST_ASSETS_DIR) + "/" + file;
}

bool AssetExists(const std::string& file) { return std::filesystem::exists(AssetPath(file)); }

std::vector<uint8_t> ReadBytes(const std::string& path) {
  std::ifstream f(path, std::ios::binary);
  return {std::istreambuf_iterator<char>(f), std::istreambuf_iterator<char>()};
}

std::vector<uint8_t> BuildGlb(const Glb& glb) {
  std::string text = glb.json.dump();
  while (text.size() % 4 != 0) text += ' ';
  std::vector<uint8_t> bin = glb.bin;
  while (bin.size() % 4 != 0) bin.push_back(0);
  std::vector<uint8_t> out;
  out.insert(out.end(), {'g', 'l', 'T', 'F'});
  PutU32(out, 2);
  PutU32(out, static_cast<uint32_t>(12 + 8 + text.size() + (bin.empty() ? 0 : 8 + bin.size())));
  PutU32(out, static_cast<uint32_t>(text.size()));
  PutU32(out, 0x4E4F534A);
  out.insert(out.end(), text.begin(), text.end());
  if (!bin.empty()) {
    PutU32(out, static_cast<uint32_t>(bin.size()));
    PutU32(out, 0x004E4942);
    out.insert(out.end(), bin.begin(), bin.end());
  }
  return out;
}

int AppendBufferView(Glb& glb, const std::vector<uint8_t>& bytes) {
  while (glb.bin.size() % 4 != 0) glb.bin.push_back(0);
  const std::size_t offset = glb.bin.size();
  glb.bin.insert(glb.bin.end(), bytes.begin(), bytes.end());
  while (glb.bin.size() % 4 != 0) glb.bin.push_back(0);
  glb.json["buffers"][0]["byteLength"] = glb.bin.size();
  glb.json["bufferViews"].push_back(
      {{"buffer", 0}, {"byteOffset", offset}, {"byteLength", bytes.size()}});
  return static_cast<int>(glb.json["bufferViews"].size()) - 1;
}

int AppendAccessor(Glb& glb, const std::vector<uint8_t>& bytes, int component_type,
                   const std::string& type, std::size_t count, bool normalized) {
  const int view = AppendBufferView(glb, bytes);
  json a = {
      {"bufferView", view}, {"componentType", component_type}, {"type", type}, {"count", count}};
  if (normalized) a["normalized"] = true;
  glb.json["accessors"].push_back(a);
  return static_cast<int>(glb.json["accessors"].size()) - 1;
}

double QuatDistance(const double a[4], const double b[4]) {
  double plus = 0, minus = 0;
  for (int c = 0; c < 4; ++c) {
    plus = std::max(plus, std::fabs(a[c] - b[c]));
    minus = std::max(minus, std::fabs(a[c] + b[c]));
  }
  return std::min(plus, minus);
}

}  // namespace skinserve::testing
