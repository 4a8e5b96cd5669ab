#include "tangent_scene.h"

#include <cmath>
#include <cstdint>
#include <cstring>

namespace skinserve::testing {
namespace {

using nlohmann::json;

constexpr int kFloat = 5126, kShort = 5122, kUnsignedByte = 5121, kUnsignedShort = 5123;

template <typename T>
std::vector<uint8_t> Bytes(const std::vector<T>& values) {
  std::vector<uint8_t> bytes(values.size() * sizeof(T));
  std::memcpy(bytes.data(), values.data(), bytes.size());
  return bytes;
}

// Doubles stored as float: the file's values, and the expectation read back from them.
int FloatAccessor(Glb& glb, std::vector<double>& values, const std::string& type,
                  std::size_t count) {
  std::vector<float> stored(values.begin(), values.end());
  for (std::size_t i = 0; i < values.size(); ++i) values[i] = stored[i];
  return AppendAccessor(glb, Bytes(stored), kFloat, type, count);
}

// Doubles in -1..1 stored as normalized shorts; `values` becomes what they decode to.
std::vector<int16_t> Shorts(std::vector<double>& values) {
  std::vector<int16_t> stored(values.size());
  for (std::size_t i = 0; i < values.size(); ++i) {
    stored[i] = static_cast<int16_t>(std::lround(values[i] * 32767.0));
    values[i] = std::max(stored[i] / 32767.0, -1.0);
  }
  return stored;
}

std::vector<double> Unit(std::vector<double> v, std::size_t n) {
  for (std::size_t e = 0; e < v.size() / n; ++e) {
    double length = 0;
    for (std::size_t c = 0; c < n; ++c) length += v[n * e + c] * v[n * e + c];
    for (std::size_t c = 0; c < n; ++c) v[n * e + c] /= std::sqrt(length);
  }
  return v;
}

// The tangent primitives' common attributes: POSITION, NORMAL given, JOINTS_0, WEIGHTS_0.
json Attributes(Glb& glb, TangentScenePrimitive& p) {
  json attributes;
  attributes["POSITION"] = FloatAccessor(glb, p.positions, "VEC3", p.vertex_count);
  std::vector<uint8_t> joints(p.joints.begin(), p.joints.end());
  attributes["JOINTS_0"] = AppendAccessor(glb, joints, kUnsignedByte, "VEC4", p.vertex_count);
  attributes["WEIGHTS_0"] = FloatAccessor(glb, p.weights, "VEC4", p.vertex_count);
  return attributes;
}

TangentScenePrimitive FloatPrimitive(Glb& glb, json* out) {
  TangentScenePrimitive p;
  p.vertex_count = 5;
  p.positions = {0, 0, 0, 1, 0.2, -0.1, 0.5, 1, 0.3, -0.4, 0.7, 1.1, 0.2, -0.6, 0.9};
  p.joints = {0, 1, 0, 0, 0, 1, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 1, 0, 0, 0};
  p.weights = {1, 0, 0, 0, 0.75, 0.25, 0, 0, 1, 0, 0, 0, 0.4, 0.6, 0, 0, 1, 0, 0, 0};
  json attributes = Attributes(glb, p);
  p.normals = Unit({0, 0, 1, 0.3, 0.1, 0.9, -0.5, 0.5, 0.7, 0.2, -0.8, 0.4, 1, 0, 0}, 3);
  attributes["NORMAL"] = p.normal_accessor = FloatAccessor(glb, p.normals, "VEC3", 5);
  // Unit xyz scaled by 1 + {0, 0.004, -0.006, 0.0099, -0.0099}: what exporters' rounding
  // and 8-bit quantization leave; w near +-1 at vertices 2 and 3.
  const std::vector<double> xyz =
      Unit({1, 0, 0, 0.2, 0.9, -0.3, 0.6, -0.6, 0.5, -0.1, 0.3, 0.9, 0, 1, 0.2}, 3);
  const double scale[5] = {1, 1.004, 0.994, 1.0099, 0.9901};
  const double w[5] = {1, -1, 0.9995, -0.995, -1};
  for (std::size_t v = 0; v < 5; ++v) {
    for (int c = 0; c < 3; ++c) p.tangents.push_back(xyz[3 * v + c] * scale[v]);
    p.tangents.push_back(w[v]);
  }
  attributes["TANGENT"] = p.tangent_accessor = FloatAccessor(glb, p.tangents, "VEC4", 5);

  // Target 0 moves vertices 0 and 2 (positions), 2 (normal) and 3 (tangent); target 1
  // vertices 4 (position), 0 and 1 (tangent, as normalized shorts). Vertex 1 moves in
  // target 1 only, vertex 3 in target 0 only.
  p.target_positions = {{0.1, 0, 0, 0, 0, 0, 0, 0.2, -0.1, 0, 0, 0, 0, 0, 0},
                        {0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0.05, 0.05, -0.3}};
  p.target_normals = {{0, 0, 0, 0, 0, 0, 0.1, -0.2, 0.05, 0, 0, 0, 0, 0, 0}, {}};
  p.target_tangents = {{0, 0, 0, 0, 0, 0, 0, 0, 0, 0.3, -0.2, 0.1, 0, 0, 0},
                       {-0.25, 0.5, 0.125, 0.7, -0.05, 0.3, 0, 0, 0, 0, 0, 0, 0, 0, 0}};
  json targets = json::array();
  json t0;
  t0["POSITION"] = FloatAccessor(glb, p.target_positions[0], "VEC3", 5);
  t0["NORMAL"] = FloatAccessor(glb, p.target_normals[0], "VEC3", 5);
  t0["TANGENT"] = FloatAccessor(glb, p.target_tangents[0], "VEC3", 5);
  json t1;
  t1["POSITION"] = FloatAccessor(glb, p.target_positions[1], "VEC3", 5);
  t1["TANGENT"] = AppendAccessor(glb, Bytes(Shorts(p.target_tangents[1])), kShort, "VEC3", 5,
                                 /*normalized=*/true);
  p.target_tangent_accessors = {t0["TANGENT"].get<int>(), t1["TANGENT"].get<int>()};
  targets.push_back(t0);
  targets.push_back(t1);
  const std::vector<uint16_t> indices = {0, 1, 2, 1, 3, 4};
  *out = {{"attributes", attributes},
          {"targets", targets},
          {"indices", AppendAccessor(glb, Bytes(indices), kUnsignedShort, "SCALAR", 6)}};
  return p;
}

TangentScenePrimitive QuantizedPrimitive(Glb& glb, json* out) {
  TangentScenePrimitive p;
  p.vertex_count = 3;
  p.positions = {0, 2, 0, 0.5, 2.5, 0.1, -0.3, 2.2, 0.4};
  p.joints = {1, 0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0};
  p.weights = {1, 0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0};
  json attributes = Attributes(glb, p);
  p.normals = Unit({0, 1, 0, 0.1, 0.9, 0.4, -0.7, 0.7, 0}, 3);
  attributes["NORMAL"] = p.normal_accessor =
      AppendAccessor(glb, Bytes(Shorts(p.normals)), kShort, "VEC3", 3, /*normalized=*/true);
  const std::vector<double> xyz = Unit({1, 0, 0.1, 0.3, -0.2, 0.9, 0.7, 0.7, -0.1}, 3);
  const double w[3] = {-1, 1, -1};
  for (std::size_t v = 0; v < 3; ++v) {
    for (int c = 0; c < 3; ++c) p.tangents.push_back(xyz[3 * v + c]);
    p.tangents.push_back(w[v]);
  }
  std::vector<int16_t> stored = Shorts(p.tangents);
  // Sparse: the base's vertex 1 is all zero (no tangent at all); the sparse part writes it.
  std::vector<int16_t> base = stored;
  std::fill(base.begin() + 4, base.begin() + 8, int16_t{0});
  const int base_view = AppendBufferView(glb, Bytes(base));
  const int indices_view = AppendBufferView(glb, {1});
  const int values_view =
      AppendBufferView(glb, Bytes(std::vector<int16_t>(stored.begin() + 4, stored.begin() + 8)));
  glb.json["accessors"].push_back(
      {{"bufferView", base_view},
       {"componentType", kShort},
       {"type", "VEC4"},
       {"count", 3},
       {"normalized", true},
       {"sparse",
        {{"count", 1},
         {"indices", {{"bufferView", indices_view}, {"componentType", kUnsignedByte}}},
         {"values", {{"bufferView", values_view}}}}}});
  attributes["TANGENT"] = p.tangent_accessor = static_cast<int>(glb.json["accessors"].size()) - 1;
  const std::vector<uint16_t> indices = {0, 1, 2};
  *out = {{"attributes", attributes},
          {"indices", AppendAccessor(glb, Bytes(indices), kUnsignedShort, "SCALAR", 3)}};
  return p;
}

}  // namespace

TangentScene MakeTangentScene() {
  TangentScene s;
  s.glb.json = {{"asset", {{"version", "2.0"}}},
                {"extensionsUsed", {"KHR_mesh_quantization"}},
                {"extensionsRequired", {"KHR_mesh_quantization"}},
                {"buffers", {{{"byteLength", 0}}}},
                {"bufferViews", json::array()},
                {"accessors", json::array()},
                {"scene", 0},
                {"scenes", {{{"nodes", {0, 2, 3}}}}},
                {"nodes",
                 {{{"name", "root"}, {"children", {1}}},
                  {{"name", "tip"}, {"translation", {0, 1, 0}}},
                  {{"name", "body"}, {"mesh", 0}, {"skin", 0}},
                  {{"name", "hat"}, {"mesh", 1}, {"skin", 0}}}},
                {"skins", {{{"joints", {0, 1}}}}}};
  json p0, p1;
  s.primitives.push_back(FloatPrimitive(s.glb, &p0));
  s.primitives.push_back(QuantizedPrimitive(s.glb, &p1));
  // Two meshes: glTF wants every primitive of a mesh to have the same morph targets.
  s.glb.json["meshes"] = {{{"name", "Body"}, {"primitives", {p0}}},
                          {{"name", "Hat"}, {"primitives", {p1}}}};
  // One clip (the load tool needs one): node 1 turns 0.5 rad about z over a second.
  std::vector<double> times = {0, 1};
  const int input = FloatAccessor(s.glb, times, "SCALAR", 2);
  s.glb.json["accessors"][static_cast<std::size_t>(input)]["min"] = {0};
  s.glb.json["accessors"][static_cast<std::size_t>(input)]["max"] = {1};
  std::vector<double> turns = {0, 0, 0, 1, 0, 0, std::sin(0.25), std::cos(0.25)};
  const int output = FloatAccessor(s.glb, turns, "VEC4", 2);
  json sampler = {{"input", input}, {"output", output}, {"interpolation", "LINEAR"}};
  json channel = {{"sampler", 0}, {"target", {{"node", 1}, {"path", "rotation"}}}};
  json animation = {
      {"name", "bend"}, {"samplers", json::array({sampler})}, {"channels", json::array({channel})}};
  s.glb.json["animations"] = json::array({animation});
  return s;
}

}  // namespace skinserve::testing
