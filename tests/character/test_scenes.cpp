#include "test_scenes.h"

#include <cmath>
#include <cstring>
#include <functional>
#include <numbers>

namespace skinserve::testing {
namespace {

using nlohmann::json;

template <typename T>
std::vector<uint8_t> Bytes(const std::vector<T>& values) {
  std::vector<uint8_t> out(values.size() * sizeof(T));
  if (!out.empty()) std::memcpy(out.data(), values.data(), out.size());
  return out;
}

Mat4 Mul(const Mat4& a, const Mat4& b) {
  Mat4 m{};
  for (int c = 0; c < 4; ++c)
    for (int r = 0; r < 4; ++r)
      for (int k = 0; k < 4; ++k) m[4 * c + r] += a[4 * k + r] * b[4 * c + k];
  return m;
}

// Inverse of an affine matrix whose 3x3 part is a rotation (the scenes' joints are rigid).
Mat4 RigidInverse(const Mat4& m) {
  Mat4 inv{};
  for (int c = 0; c < 3; ++c)
    for (int r = 0; r < 3; ++r) inv[4 * c + r] = m[4 * r + c];
  for (int r = 0; r < 3; ++r) {
    inv[12 + r] = -(inv[r] * m[12] + inv[4 + r] * m[13] + inv[8 + r] * m[14]);
  }
  inv[15] = 1;
  return inv;
}

std::vector<RefNode> RefNodes(const Scene& scene) {
  std::vector<RefNode> nodes(scene.nodes.size());
  for (std::size_t i = 0; i < scene.nodes.size(); ++i) {
    const SceneNode& n = scene.nodes[i];
    std::copy(n.t, n.t + 3, nodes[i].t);
    std::copy(n.r, n.r + 4, nodes[i].r);
    std::copy(n.s, n.s + 3, nodes[i].s);
    for (int child : n.children)
      nodes[static_cast<std::size_t>(child)].parent = static_cast<int>(i);
  }
  return nodes;
}

// Every node's world matrix at rest (no clip), for inverse bind matrices.
Mat4 RestWorld(const Scene& scene, int node) {
  const std::vector<RefNode> nodes = RefNodes(scene);
  Mat4 m = Compose(nodes[static_cast<std::size_t>(node)].t, nodes[static_cast<std::size_t>(node)].r,
                   nodes[static_cast<std::size_t>(node)].s);
  for (int p = nodes[static_cast<std::size_t>(node)].parent; p >= 0;
       p = nodes[static_cast<std::size_t>(p)].parent) {
    const RefNode& n = nodes[static_cast<std::size_t>(p)];
    m = Mul(Compose(n.t, n.r, n.s), m);
  }
  return m;
}

void BindSkins(Scene* scene) {
  for (SceneSkin& skin : scene->skins) {
    skin.inverse_bind.clear();
    for (int j : skin.joints) skin.inverse_bind.push_back(RigidInverse(RestWorld(*scene, j)));
  }
}

// A strip of quads standing along y from `base` up `height`, two vertices per row, bent by
// joints a (bottom) and b (top): weight of b grows with height. `width` along x; normals
// +z when `normals`. `rows` >= 2.
ScenePrimitive Strip(const double base[3], double width, double height, int rows, uint8_t a,
                     uint8_t b, bool normals) {
  ScenePrimitive p;
  for (int row = 0; row < rows; ++row) {
    const double u = static_cast<double>(row) / (rows - 1);
    for (int side = 0; side < 2; ++side) {
      p.positions.insert(p.positions.end(),
                         {static_cast<float>(base[0] + side * width),
                          static_cast<float>(base[1] + u * height), static_cast<float>(base[2])});
      if (normals) p.normals.insert(p.normals.end(), {0.0f, 0.0f, 1.0f});
      p.joints.insert(p.joints.end(), {a, b, 0, 0});
      p.weights.insert(p.weights.end(),
                       {static_cast<float>(1 - u), static_cast<float>(u), 0.0f, 0.0f});
    }
  }
  for (int row = 0; row + 1 < rows; ++row) {
    const auto v = static_cast<uint16_t>(2 * row);
    p.indices.insert(p.indices.end(),
                     {v, static_cast<uint16_t>(v + 1), static_cast<uint16_t>(v + 3), v,
                      static_cast<uint16_t>(v + 3), static_cast<uint16_t>(v + 2)});
  }
  return p;
}

// An axis-angle rotation as x y z w.
std::vector<double> Quat(double x, double y, double z, double degrees) {
  const double half = degrees * std::numbers::pi / 360.0;
  const double n = std::sqrt(x * x + y * y + z * z);
  return {x / n * std::sin(half), y / n * std::sin(half), z / n * std::sin(half), std::cos(half)};
}

RefChannel Rotation(int node, std::vector<double> times, std::vector<std::vector<double>> keys) {
  RefChannel ch{.node = node, .path = "rotation", .interpolation = "LINEAR", .times = times};
  for (const auto& k : keys) ch.values.insert(ch.values.end(), k.begin(), k.end());
  return ch;
}

RefChannel Translation(int node, std::vector<double> times, std::vector<double> values) {
  return {.node = node,
          .path = "translation",
          .interpolation = "LINEAR",
          .times = times,
          .values = values};
}

void SetRotation(SceneNode* n, const std::vector<double>& q) {
  std::copy(q.begin(), q.end(), n->r);
}

void Finish(Scene* scene) {
  BindSkins(scene);
  scene->clip.name = "Move";
  scene->clip.duration = 0;
  for (const RefChannel& ch : scene->clip.channels) {
    scene->clip.duration = std::max(scene->clip.duration, ch.times.back());
  }
}

// Weights channel `ch` at `t`, n values, per glTF's Appendix C (clamped to the keys).
std::vector<double> SampleWeights(const SceneWeightsChannel& ch, std::size_t n, double t) {
  const bool cubic = ch.interpolation == "CUBICSPLINE";
  auto key = [&](std::size_t k, std::size_t part) {  // part: 0 in-tangent, 1 value, 2 out
    const std::size_t at = (cubic ? 3 * k + part : k) * n;
    return std::vector<double>(ch.values.begin() + static_cast<std::ptrdiff_t>(at),
                               ch.values.begin() + static_cast<std::ptrdiff_t>(at + n));
  };
  if (t <= ch.times.front()) return key(0, 1);
  if (t >= ch.times.back()) return key(ch.times.size() - 1, 1);
  std::size_t k = 0;
  while (!(ch.times[k] <= t && t < ch.times[k + 1])) ++k;
  const double d = ch.times[k + 1] - ch.times[k], u = (t - ch.times[k]) / d;
  const std::vector<double> a = key(k, 1), b = key(k + 1, 1);
  if (ch.interpolation == "STEP") return a;
  std::vector<double> out(n);
  for (std::size_t c = 0; c < n; ++c) {
    if (cubic) {
      out[c] = (2 * u * u * u - 3 * u * u + 1) * a[c] +
               (u * u * u - 2 * u * u + u) * d * key(k, 2)[c] +
               (-2 * u * u * u + 3 * u * u) * b[c] + (u * u * u - u * u) * d * key(k + 1, 0)[c];
    } else {
      out[c] = a[c] + u * (b[c] - a[c]);
    }
  }
  return out;
}

// A target over `p`'s vertices: position delta (dx, dy, dz) * (1 + row) on the vertices
// whose index modulo `every` is `phase`, zero elsewhere; normal deltas (0.3, 0, -0.2) on
// the same vertices when `normals`.
void AddTarget(ScenePrimitive* p, int every, int phase, double dx, double dy, double dz,
               bool normals) {
  const std::size_t v_count = p->positions.size() / 3;
  std::vector<float> dp(3 * v_count, 0.0f), dn(normals ? 3 * v_count : 0, 0.0f);
  for (std::size_t v = 0; v < v_count; ++v) {
    if (static_cast<int>(v) % every != phase) continue;
    const double scale = 1.0 + static_cast<double>(v / 2);
    dp[3 * v] = static_cast<float>(dx * scale);
    dp[3 * v + 1] = static_cast<float>(dy * scale);
    dp[3 * v + 2] = static_cast<float>(dz * scale);
    if (normals) dn[3 * v] = 0.3f, dn[3 * v + 2] = -0.2f;
  }
  p->target_positions.push_back(std::move(dp));
  p->target_normals.push_back(std::move(dn));
}

}  // namespace

Scene MorphFace(const std::string& interpolation) {
  Scene s;
  // 0 Root -> 1 Jaw -> 2 Head; 3 FaceNode (mesh 0), 4 BrowNode (mesh 1), both skin 0.
  s.nodes.resize(5);
  s.nodes[0] = {.name = "Root", .children = {1, 3, 4}};
  s.nodes[1] = {.name = "Jaw", .children = {2}};
  s.nodes[2] = {.name = "Head"};
  s.nodes[2].t[1] = 0.8;
  s.nodes[3] = {.name = "FaceNode", .mesh = 0, .skin = 0};
  s.nodes[4] = {.name = "BrowNode", .mesh = 1, .skin = 0};
  s.skins.push_back({.joints = {1, 2}, .inverse_bind = {}});
  const double a[3] = {-0.3, 0.0, 0.1}, b[3] = {0.2, 0.4, 0.0}, top[3] = {-0.2, 1.2, 0.2};
  ScenePrimitive face0 = Strip(a, 0.4, 1.2, 5, 0, 1, true);
  ScenePrimitive face1 = Strip(b, 0.3, 0.6, 3, 1, 0, true);
  ScenePrimitive brow = Strip(top, 0.5, 0.2, 2, 1, 1, true);
  for (ScenePrimitive* p : {&face0, &face1}) {
    AddTarget(p, 2, 0, 0.05, 0.0, 0.02, false);  // positions only
    AddTarget(p, 3, 1, -0.03, 0.04, 0.0, true);
    AddTarget(p, 1, 0, 0.0, -0.02, 0.06, true);  // every vertex
  }
  AddTarget(&brow, 2, 1, 0.0, 0.05, 0.0, true);
  AddTarget(&brow, 1, 0, 0.02, 0.0, 0.0, false);
  s.meshes.push_back({"Face", {face0, face1}, {0.25, 0.0, -0.5}});
  s.meshes.push_back({"Brow", {brow}, {0.5, 1.0}});
  // Face's weights over 2 s: 3 keys of 3 weights (negative and beyond 1 included).
  // Key times exact in float, as the file stores them (a STEP key is taken from its time on).
  SceneWeightsChannel ch{.node = 3, .interpolation = interpolation, .times = {0, 0.75, 2}};
  const std::vector<double> keys = {0.0, 1.0, 0.2, 1.0, -0.5, 0.7, 0.3, 1.4, 0.0};
  if (interpolation == "CUBICSPLINE") {
    const std::vector<double> tangents = {0.5, -1.0, 0.25, 2.0, 0.0, -0.75, -0.4, 0.6, 1.0};
    for (std::size_t k = 0; k < 3; ++k) {
      for (std::size_t c = 0; c < 3; ++c) ch.values.push_back(tangents[3 * k + c]);  // in
      for (std::size_t c = 0; c < 3; ++c) ch.values.push_back(keys[3 * k + c]);
      for (std::size_t c = 0; c < 3; ++c) ch.values.push_back(-tangents[3 * k + c]);  // out
    }
  } else {
    ch.values = keys;
  }
  s.weights_channels.push_back(ch);
  s.clip.channels.push_back(Rotation(2, {0, 2}, {Quat(0, 0, 1, 0), Quat(1, 0, 1, 50)}));
  Finish(&s);
  return s;
}

Scene SeveralPrimitivesOneSkin() {
  Scene s;
  // 0 Root -> 1 Hip -> 2 Knee; 3 BodyNode (mesh 0), 4 HatNode (mesh 1), both skin 0.
  s.nodes.resize(5);
  s.nodes[0] = {.name = "Root", .children = {1, 3, 4}};
  s.nodes[1] = {.name = "Hip", .children = {2}};
  s.nodes[1].t[1] = 0.5;
  s.nodes[2] = {.name = "Knee"};
  s.nodes[2].t[1] = 1.0;
  SetRotation(&s.nodes[2], Quat(0, 0, 1, 10));
  s.nodes[3] = {.name = "BodyNode", .mesh = 0, .skin = 0};
  s.nodes[3].t[0] = 5.0;  // ignored for a skinned mesh: must not move anything
  SetRotation(&s.nodes[3], Quat(1, 0, 0, 70));
  s.nodes[4] = {.name = "HatNode", .mesh = 1, .skin = 0};
  s.nodes[4].s[0] = s.nodes[4].s[1] = s.nodes[4].s[2] = 3.0;  // ignored too
  s.skins.push_back({.joints = {1, 2}, .inverse_bind = {}});
  const double a[3] = {-0.6, 0.5, 0.0}, b[3] = {0.1, 0.5, 0.1}, c[3] = {0.4, 0.5, -0.2},
               d[3] = {-0.2, 1.9, 0.05};
  s.meshes.push_back({"Body",
                      {Strip(a, 0.3, 2.0, 6, 0, 1, true), Strip(b, 0.2, 1.5, 4, 0, 1, true),
                       Strip(c, 0.25, 1.0, 3, 1, 0, true)}});
  s.meshes.push_back({"Hat", {Strip(d, 0.4, 0.3, 2, 1, 1, true)}});
  s.clip.channels.push_back(
      Rotation(1, {0, 1, 2}, {Quat(0, 0, 1, 0), Quat(0, 0, 1, 40), Quat(0, 1, 1, 20)}));
  s.clip.channels.push_back(Rotation(2, {0, 2}, {Quat(0, 0, 1, 10), Quat(1, 0, 0, 80)}));
  Finish(&s);
  return s;
}

Scene TwoSkins() {
  Scene s;
  // 0 Root -> 1 ArmA0 -> 2 ArmA1, 3 ArmB0 -> 4 ArmB1; 5 MeshA (mesh 0, skin 0),
  // 6 MeshB (mesh 1, skin 1).
  s.nodes.resize(7);
  s.nodes[0] = {.name = "Root", .children = {1, 3, 5, 6}};
  s.nodes[1] = {.name = "ArmA0", .children = {2}};
  s.nodes[1].t[0] = -1.0;
  s.nodes[2] = {.name = "ArmA1"};
  s.nodes[2].t[1] = 1.0;
  s.nodes[3] = {.name = "ArmB0", .children = {4}};
  s.nodes[3].t[0] = 1.0;
  SetRotation(&s.nodes[3], Quat(0, 1, 0, 30));
  s.nodes[4] = {.name = "ArmB1"};
  s.nodes[4].t[1] = 0.8;
  s.nodes[5] = {.name = "MeshA", .mesh = 0, .skin = 0};
  s.nodes[6] = {.name = "MeshB", .mesh = 1, .skin = 1};
  s.nodes[6].t[2] = -4.0;  // ignored
  s.skins.push_back({.joints = {1, 2}, .inverse_bind = {}});
  s.skins.push_back({.joints = {4, 3}, .inverse_bind = {}});  // palette order != node order
  const double a[3] = {-1.1, 0.0, 0.0}, b[3] = {-0.8, 0.2, 0.1}, c[3] = {0.9, 0.0, 0.0};
  s.meshes.push_back({"A", {Strip(a, 0.2, 1.8, 5, 0, 1, true), Strip(b, 0.1, 1.0, 3, 0, 1, true)}});
  s.meshes.push_back({"B", {Strip(c, 0.2, 1.6, 4, 1, 0, true)}});
  s.clip.channels.push_back(Rotation(2, {0, 1}, {Quat(1, 0, 0, 0), Quat(1, 0, 0, 90)}));
  s.clip.channels.push_back(Rotation(4, {0, 1.5}, {Quat(0, 0, 1, 0), Quat(0, 0, 1, -60)}));
  s.clip.channels.push_back(Translation(3, {0, 1.5}, {1, 0, 0, 1.5, 0.5, 0}));
  Finish(&s);
  return s;
}

Scene MovingParent() {
  Scene s;
  // 0 Mover -> 1 Bone0 -> 2 Bone1, and 3 MeshNode (mesh 0, skin 0) under Mover too, with
  // a transform of its own that glTF says to ignore. Only Mover is animated.
  s.nodes.resize(4);
  s.nodes[0] = {.name = "Mover", .children = {1, 3}};
  s.nodes[0].t[0] = 0.5;
  SetRotation(&s.nodes[0], Quat(0, 1, 0, 15));
  s.nodes[1] = {.name = "Bone0", .children = {2}};
  s.nodes[2] = {.name = "Bone1"};
  s.nodes[2].t[1] = 1.0;
  SetRotation(&s.nodes[2], Quat(0, 0, 1, 25));
  s.nodes[3] = {.name = "MeshNode", .mesh = 0, .skin = 0};
  s.nodes[3].t[1] = 2.0;
  SetRotation(&s.nodes[3], Quat(0, 0, 1, 90));
  s.skins.push_back({.joints = {1, 2}, .inverse_bind = {}});
  const double a[3] = {0.0, 0.0, 0.0}, b[3] = {0.3, 0.4, 0.2};
  s.meshes.push_back(
      {"Body", {Strip(a, 0.3, 2.0, 5, 0, 1, true), Strip(b, 0.2, 1.0, 3, 1, 0, true)}});
  s.clip.channels.push_back(Translation(0, {0, 1, 2}, {0.5, 0, 0, 2.5, 1, -1, 0.5, 3, 0}));
  s.clip.channels.push_back(Rotation(0, {0, 2}, {Quat(0, 1, 0, 15), Quat(1, 1, 0, 120)}));
  Finish(&s);
  return s;
}

std::vector<uint8_t> WriteGlb(const Scene& scene) {
  Glb glb;
  json& j = glb.json;
  j["asset"] = {{"version", "2.0"}, {"generator", "skinserve tests"}};
  j["buffers"] = json::array({{{"byteLength", 0}}});
  j["bufferViews"] = json::array();
  j["accessors"] = json::array();
  std::vector<int> roots;
  std::vector<bool> is_child(scene.nodes.size(), false);
  for (const SceneNode& n : scene.nodes)
    for (int c : n.children) is_child[static_cast<std::size_t>(c)] = true;
  for (std::size_t i = 0; i < scene.nodes.size(); ++i) {
    const SceneNode& n = scene.nodes[i];
    if (!is_child[i]) roots.push_back(static_cast<int>(i));
    json node = {{"name", n.name},
                 {"translation", {n.t[0], n.t[1], n.t[2]}},
                 {"rotation", {n.r[0], n.r[1], n.r[2], n.r[3]}},
                 {"scale", {n.s[0], n.s[1], n.s[2]}}};
    if (!n.children.empty()) node["children"] = n.children;
    if (n.mesh >= 0) node["mesh"] = n.mesh;
    if (n.skin >= 0) node["skin"] = n.skin;
    j["nodes"].push_back(node);
  }
  j["scene"] = 0;
  j["scenes"] = json::array({{{"nodes", roots}}});
  for (const SceneMesh& mesh : scene.meshes) {
    json primitives = json::array();
    for (const ScenePrimitive& p : mesh.primitives) {
      const std::size_t v = p.positions.size() / 3;
      json attributes;
      attributes["POSITION"] = AppendAccessor(glb, Bytes(p.positions), 5126, "VEC3", v);
      std::vector<float> lo(3, 1e30f), hi(3, -1e30f);
      for (std::size_t i = 0; i < p.positions.size(); ++i) {
        lo[i % 3] = std::min(lo[i % 3], p.positions[i]);
        hi[i % 3] = std::max(hi[i % 3], p.positions[i]);
      }
      j["accessors"].back()["min"] = lo;
      j["accessors"].back()["max"] = hi;
      if (!p.normals.empty()) {
        attributes["NORMAL"] = AppendAccessor(glb, Bytes(p.normals), 5126, "VEC3", v);
      }
      attributes["JOINTS_0"] = AppendAccessor(glb, Bytes(p.joints), 5121, "VEC4", v);
      attributes["WEIGHTS_0"] = AppendAccessor(glb, Bytes(p.weights), 5126, "VEC4", v);
      const int indices = AppendAccessor(glb, Bytes(p.indices), 5123, "SCALAR", p.indices.size());
      json primitive = {{"attributes", attributes}, {"indices", indices}, {"mode", 4}};
      for (std::size_t t = 0; t < p.target_positions.size(); ++t) {
        json target;
        target["POSITION"] = AppendAccessor(glb, Bytes(p.target_positions[t]), 5126, "VEC3", v);
        if (!p.target_normals[t].empty()) {
          target["NORMAL"] = AppendAccessor(glb, Bytes(p.target_normals[t]), 5126, "VEC3", v);
        }
        primitive["targets"].push_back(target);
      }
      primitives.push_back(primitive);
    }
    json out_mesh = {{"name", mesh.name}, {"primitives", primitives}};
    if (!mesh.weights.empty()) out_mesh["weights"] = mesh.weights;
    j["meshes"].push_back(out_mesh);
  }
  for (const SceneSkin& skin : scene.skins) {
    std::vector<float> ibm;
    for (const Mat4& m : skin.inverse_bind)
      for (double x : m) ibm.push_back(static_cast<float>(x));
    const int accessor = AppendAccessor(glb, Bytes(ibm), 5126, "MAT4", skin.joints.size());
    j["skins"].push_back({{"joints", skin.joints}, {"inverseBindMatrices", accessor}});
  }
  json channels = json::array(), samplers = json::array();
  for (const RefChannel& ch : scene.clip.channels) {
    std::vector<float> times(ch.times.begin(), ch.times.end());
    std::vector<float> values(ch.values.begin(), ch.values.end());
    const int input = AppendAccessor(glb, Bytes(times), 5126, "SCALAR", times.size());
    j["accessors"].back()["min"] = {times.front()};
    j["accessors"].back()["max"] = {times.back()};
    const bool rotation = ch.path == "rotation";
    const int output = AppendAccessor(glb, Bytes(values), 5126, rotation ? "VEC4" : "VEC3",
                                      values.size() / (rotation ? 4 : 3));
    samplers.push_back({{"input", input}, {"output", output}, {"interpolation", "LINEAR"}});
    channels.push_back(
        {{"sampler", samplers.size() - 1}, {"target", {{"node", ch.node}, {"path", ch.path}}}});
  }
  for (const SceneWeightsChannel& ch : scene.weights_channels) {
    std::vector<float> times(ch.times.begin(), ch.times.end());
    std::vector<float> values(ch.values.begin(), ch.values.end());
    const int input = AppendAccessor(glb, Bytes(times), 5126, "SCALAR", times.size());
    j["accessors"].back()["min"] = {times.front()};
    j["accessors"].back()["max"] = {times.back()};
    const int output = AppendAccessor(glb, Bytes(values), 5126, "SCALAR", values.size());
    samplers.push_back({{"input", input}, {"output", output}, {"interpolation", ch.interpolation}});
    channels.push_back(
        {{"sampler", samplers.size() - 1}, {"target", {{"node", ch.node}, {"path", "weights"}}}});
  }
  j["animations"].push_back(
      {{"name", scene.clip.name}, {"channels", channels}, {"samplers", samplers}});
  return BuildGlb(glb);
}

std::vector<ScenePrimitiveRef> SkinnedPrimitives(const Scene& scene) {
  std::vector<ScenePrimitiveRef> out;
  for (std::size_t n = 0; n < scene.nodes.size(); ++n) {
    const SceneNode& node = scene.nodes[n];
    if (node.mesh < 0 || node.skin < 0) continue;
    const SceneMesh& mesh = scene.meshes[static_cast<std::size_t>(node.mesh)];
    for (std::size_t p = 0; p < mesh.primitives.size(); ++p) {
      out.push_back({static_cast<int>(n), node.mesh, static_cast<int>(p), node.skin,
                     mesh.name + "/" + std::to_string(p)});
    }
  }
  return out;
}

RefFrame SceneFrame(const Scene& scene, const ScenePrimitiveRef& p, double t) {
  RefCharacter ref;
  ref.nodes = RefNodes(scene);
  const SceneSkin& skin = scene.skins[static_cast<std::size_t>(p.skin)];
  ref.joints = skin.joints;
  ref.inverse_bind = skin.inverse_bind;
  const ScenePrimitive& sp = scene.meshes[static_cast<std::size_t>(p.mesh)]
                                 .primitives[static_cast<std::size_t>(p.primitive)];
  RefPrimitive prim;
  prim.vertex_count = sp.positions.size() / 3;
  prim.positions.assign(sp.positions.begin(), sp.positions.end());
  prim.normals.assign(sp.normals.begin(), sp.normals.end());
  prim.joints.assign(sp.joints.begin(), sp.joints.end());
  prim.weights.assign(sp.weights.begin(), sp.weights.end());
  prim.index_count = sp.indices.size();
  // Morph targets, in double: the node's weights at t, deltas added before skinning.
  std::vector<double> weights = scene.meshes[static_cast<std::size_t>(p.mesh)].weights;
  for (const SceneWeightsChannel& ch : scene.weights_channels) {
    if (ch.node == p.node) weights = SampleWeights(ch, sp.target_positions.size(), t);
  }
  for (std::size_t k = 0; k < weights.size() && k < sp.target_positions.size(); ++k) {
    for (std::size_t i = 0; i < prim.positions.size(); ++i) {
      prim.positions[i] += weights[k] * sp.target_positions[k][i];
      if (!prim.normals.empty() && !sp.target_normals[k].empty()) {
        prim.normals[i] += weights[k] * sp.target_normals[k][i];
      }
    }
  }
  return RefSkin(prim, RefPalette(ref, &scene.clip, t));
}

Mat4 WorldMatrix(const Scene& scene, int node, double t) {
  std::vector<RefNode> nodes = RefNodes(scene);
  for (const RefChannel& ch : scene.clip.channels) {
    const std::vector<double> v = RefSample(ch, t);
    RefNode& n = nodes[static_cast<std::size_t>(ch.node)];
    std::copy(v.begin(), v.end(),
              ch.path == "translation" ? n.t
              : ch.path == "rotation"  ? n.r
                                       : n.s);
  }
  Mat4 m = Compose(nodes[static_cast<std::size_t>(node)].t, nodes[static_cast<std::size_t>(node)].r,
                   nodes[static_cast<std::size_t>(node)].s);
  for (int p = nodes[static_cast<std::size_t>(node)].parent; p >= 0;
       p = nodes[static_cast<std::size_t>(p)].parent) {
    const RefNode& n = nodes[static_cast<std::size_t>(p)];
    m = Mul(Compose(n.t, n.r, n.s), m);
  }
  return m;
}

}  // namespace skinserve::testing
