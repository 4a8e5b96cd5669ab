#include "test_scenes.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <functional>
#include <limits>
#include <numbers>
#include <stdexcept>

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
    for (int j : skin.joints) {
      skin.inverse_bind.push_back(Mul(RigidInverse(RestWorld(*scene, j)), skin.bind_shape));
    }
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

RefChannel Scale(int node, std::vector<double> times, std::vector<double> values) {
  return {
      .node = node, .path = "scale", .interpolation = "LINEAR", .times = times, .values = values};
}

// A box of 8 corners (no shared normals: 24 vertices, 4 per face) centred at `c` with
// half-sizes `h`, normals when asked, 12 triangles; not skinned (a rigid part).
ScenePrimitive Box(const double c[3], const double h[3], bool normals) {
  ScenePrimitive p;
  for (int axis = 0; axis < 3; ++axis) {
    for (int sign = -1; sign <= 1; sign += 2) {
      const int u = (axis + 1) % 3, v = (axis + 2) % 3;
      const auto first = static_cast<uint16_t>(p.positions.size() / 3);
      for (int corner = 0; corner < 4; ++corner) {
        double x[3];
        x[axis] = c[axis] + sign * h[axis];
        x[u] = c[u] + ((corner & 1) ? h[u] : -h[u]);
        x[v] = c[v] + ((corner & 2) ? h[v] : -h[v]);
        for (double k : x) p.positions.push_back(static_cast<float>(k));
        if (normals) {
          float n[3] = {0, 0, 0};
          n[axis] = static_cast<float>(sign);
          p.normals.insert(p.normals.end(), n, n + 3);
        }
      }
      p.indices.insert(p.indices.end(),
                       {first, static_cast<uint16_t>(first + 1), static_cast<uint16_t>(first + 3),
                        first, static_cast<uint16_t>(first + 3), static_cast<uint16_t>(first + 2)});
    }
  }
  return p;
}

double TypeMax(int component_type) {
  switch (component_type) {
    case 5120:
      return 127;
    case 5121:
      return 255;
    case 5122:
      return 32767;
    case 5123:
      return 65535;
    default:
      throw std::logic_error("test scene: no integer component type " +
                             std::to_string(component_type));
  }
}

// Positions replaced by integers q = round((p - offset) / scale): what a quantizer stores;
// the caller puts translate(offset) * scale(scale) back in a node or the bind shape.
void QuantizePositions(ScenePrimitive* p, const double offset[3], double scale) {
  for (std::size_t i = 0; i < p->positions.size(); ++i) {
    p->positions[i] = static_cast<float>(std::lround((p->positions[i] - offset[i % 3]) / scale));
  }
}

// Values replaced by what normalized integers of `component_type` decode to (the importer's
// float formula), so that the scene states exactly what the file holds.
void SnapNormalized(std::vector<float>* values, int component_type) {
  const double max = TypeMax(component_type);
  for (float& v : *values) {
    const auto q = static_cast<float>(std::lround(v * max));
    v = std::max(q / static_cast<float>(max), -1.0f);
  }
}

// Weights as normalized integers whose sum per vertex is exactly the type's max.
void SnapWeights(ScenePrimitive* p, int component_type) {
  const double max = TypeMax(component_type);
  for (std::size_t v = 0; v < p->weights.size() / 4; ++v) {
    long q[4], sum = 0;
    int largest = 0;
    for (int k = 0; k < 4; ++k) {
      q[k] = std::lround(p->weights[4 * v + k] * max);
      sum += q[k];
      if (q[k] > q[largest]) largest = k;
    }
    q[largest] += static_cast<long>(max) - sum;
    for (int k = 0; k < 4; ++k) {
      p->weights[4 * v + k] = static_cast<float>(q[k]) / static_cast<float>(max);
    }
  }
}

Mat4 Dequantization(const double offset[3], double scale) {
  return {scale, 0, 0, 0, 0, scale, 0, 0, 0, 0, scale, 0, offset[0], offset[1], offset[2], 1};
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

namespace {

// Appends `part` to `to`: its vertices renumbered after `to`'s; when `lower` >= 0 skinned
// to joints `lower` (at y <= y0) and `upper` (at y >= y1), blended linearly between.
void AppendPart(ScenePrimitive* to, const ScenePrimitive& part, int lower = -1, int upper = -1,
                double y0 = 0, double y1 = 1) {
  const auto first = static_cast<uint16_t>(to->positions.size() / 3);
  to->positions.insert(to->positions.end(), part.positions.begin(), part.positions.end());
  to->normals.insert(to->normals.end(), part.normals.begin(), part.normals.end());
  for (uint16_t i : part.indices) to->indices.push_back(static_cast<uint16_t>(first + i));
  if (lower < 0) return;
  for (std::size_t v = 0; v < part.positions.size() / 3; ++v) {
    const double u = std::clamp((part.positions[3 * v + 1] - y0) / (y1 - y0), 0.0, 1.0);
    to->joints.insert(to->joints.end(),
                      {static_cast<uint8_t>(lower), static_cast<uint8_t>(upper), 0, 0});
    to->weights.insert(to->weights.end(),
                       {static_cast<float>(1 - u), static_cast<float>(u), 0.0f, 0.0f});
  }
}

std::vector<std::vector<double>> RotationsAboutX(const std::vector<double>& degrees) {
  std::vector<std::vector<double>> keys;
  for (double d : degrees) keys.push_back(Quat(1, 0, 0, d));
  return keys;
}

}  // namespace

Scene WalkingFace() {
  Scene s;
  // 0 Hips -> 1 LeftHip -> 2 LeftKnee, 3 RightHip -> 4 RightKnee, 5 Chest -> 6 LeftShoulder,
  // 7 RightShoulder, 8 Head (mesh 1, rigid, morph targets); 9 BodyNode (mesh 0, skin 0).
  // Facing +z, y up, about 1.8 tall; the clip is two strides in place.
  s.nodes.resize(10);
  s.nodes[0] = {.name = "Hips", .children = {1, 3, 5, 9}};
  s.nodes[0].t[1] = 0.95;
  s.nodes[1] = {.name = "LeftHip", .children = {2}};
  s.nodes[1].t[0] = 0.12, s.nodes[1].t[1] = -0.05;
  s.nodes[2] = {.name = "LeftKnee"};
  s.nodes[2].t[1] = -0.42;
  s.nodes[3] = {.name = "RightHip", .children = {4}};
  s.nodes[3].t[0] = -0.12, s.nodes[3].t[1] = -0.05;
  s.nodes[4] = {.name = "RightKnee"};
  s.nodes[4].t[1] = -0.42;
  s.nodes[5] = {.name = "Chest", .children = {6, 7, 8}};
  s.nodes[5].t[1] = 0.45;
  s.nodes[6] = {.name = "LeftShoulder"};
  s.nodes[6].t[0] = 0.25, s.nodes[6].t[1] = 0.05;
  s.nodes[7] = {.name = "RightShoulder"};
  s.nodes[7].t[0] = -0.25, s.nodes[7].t[1] = 0.05;
  s.nodes[8] = {.name = "Head", .mesh = 1};
  s.nodes[8].t[1] = 0.12;
  s.nodes[9] = {.name = "BodyNode", .mesh = 0, .skin = 0};
  s.skins.push_back({.joints = {0, 1, 2, 3, 4, 5, 6, 7}, .inverse_bind = {}});

  // The body in rest world space: torso bending between Hips and Chest, thighs, shins with
  // feet and arms each on one joint.
  ScenePrimitive body;
  auto box = [](double cx, double cy, double cz, double hx, double hy, double hz) {
    const double c[3] = {cx, cy, cz}, h[3] = {hx, hy, hz};
    return Box(c, h, true);
  };
  AppendPart(&body, box(0, 1.2, 0, 0.2, 0.3, 0.11), 0, 5, 1.0, 1.4);
  for (int side = 0; side < 2; ++side) {
    const double x = side == 0 ? 0.12 : -0.12;
    const int hip = side == 0 ? 1 : 3, knee = hip + 1, shoulder = side == 0 ? 6 : 7;
    AppendPart(&body, box(x, 0.69, 0, 0.07, 0.21, 0.07), hip, hip);
    AppendPart(&body, box(x, 0.26, 0, 0.06, 0.22, 0.06), knee, knee);
    AppendPart(&body, box(x, 0.025, 0.05, 0.065, 0.025, 0.11), knee, knee);
    AppendPart(&body, box(2.4 * x, 1.15, 0, 0.05, 0.3, 0.05), shoulder, shoulder);
  }
  // The head in its node's space: a block, two eyes and a mouth standing out of its front.
  // Target 0 opens the mouth (its lower half and the chin drop), target 1 shuts the eyes
  // (each eye's top and bottom meet); positions only, as the boxes keep their normals.
  ScenePrimitive head;
  AppendPart(&head, box(0, 0.17, 0, 0.16, 0.17, 0.14));
  const std::size_t eyes_from = head.positions.size() / 3;
  AppendPart(&head, box(0.075, 0.23, 0.16, 0.045, 0.045, 0.04));
  AppendPart(&head, box(-0.075, 0.23, 0.16, 0.045, 0.045, 0.04));
  const std::size_t mouth_from = head.positions.size() / 3;
  AppendPart(&head, box(0, 0.085, 0.16, 0.08, 0.02, 0.04));
  const std::size_t n = head.positions.size() / 3;
  std::vector<float> open(3 * n, 0.0f), shut(3 * n, 0.0f);
  for (std::size_t v = 0; v < n; ++v) {
    const float y = head.positions[3 * v + 1];
    if (v < eyes_from && y < 0.01f) open[3 * v + 1] = -0.04f;  // the chin
    if (v >= mouth_from && y < 0.085f) open[3 * v + 1] = -0.08f;
    if (v >= eyes_from && v < mouth_from) shut[3 * v + 1] = y > 0.23f ? -0.04f : 0.04f;
  }
  head.target_positions = {open, shut};
  head.target_normals = {{}, {}};
  s.meshes.push_back({"Body", {body}});
  s.meshes.push_back({"Head", {head}, {0.0, 0.0}});

  // Two strides: legs swing +-25 degrees (forward is negative about x), knees bend as a leg
  // swings forward, arms swing against the legs, hips bob, the head turns left and right.
  const std::vector<double> quarter = {0, 0.25, 0.5, 0.75, 1, 1.25, 1.5, 1.75, 2};
  const std::vector<double> half = {0, 0.5, 1, 1.5, 2};
  s.clip.channels.push_back(Rotation(1, half, RotationsAboutX({-25, 25, -25, 25, -25})));
  s.clip.channels.push_back(Rotation(3, half, RotationsAboutX({25, -25, 25, -25, 25})));
  s.clip.channels.push_back(
      Rotation(2, quarter, RotationsAboutX({5, 15, 10, 55, 5, 15, 10, 55, 5})));
  s.clip.channels.push_back(
      Rotation(4, quarter, RotationsAboutX({10, 55, 5, 15, 10, 55, 5, 15, 10})));
  s.clip.channels.push_back(Rotation(6, half, RotationsAboutX({20, -20, 20, -20, 20})));
  s.clip.channels.push_back(Rotation(7, half, RotationsAboutX({-20, 20, -20, 20, -20})));
  std::vector<double> bob;
  for (std::size_t k = 0; k < quarter.size(); ++k)
    bob.insert(bob.end(), {0, k % 2 ? 0.97 : 0.93, 0});
  s.clip.channels.push_back(Translation(0, quarter, bob));
  s.clip.channels.push_back(Rotation(8, half,
                                     {Quat(0, 1, 0, 0), Quat(0, 1, 0, 15), Quat(0, 1, 0, 0),
                                      Quat(0, 1, 0, -15), Quat(0, 1, 0, 0)}));
  // The face: the mouth opens, closes as the eyes shut, then the eyes open again.
  s.weights_channels.push_back({.node = 8,
                                .interpolation = "LINEAR",
                                .times = {0, 0.4, 0.8, 1.1, 1.6, 2},
                                .values = {0, 0, 1, 0, 1, 0, 0, 1, 0, 1, 0, 0}});
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

Scene RigidParts() {
  Scene s;
  // 0 Root -> 1 Hip -> 2 Knee -> 5 Shield; 3 Helmet under Hip; 4 BodyNode (mesh 0, skin 0:
  // Hip, Knee); 6 Lamp under Root. Rigid: 3 (mesh 1, 2 primitives, non-trivial TRS), 5
  // (mesh 2, no normals, animated rotation and non-uniform scale, under animated Knee under
  // animated Hip), 6 (mesh 1 again, animated translation).
  s.nodes.resize(7);
  s.nodes[0] = {.name = "Root", .children = {1, 4, 6}};
  s.nodes[1] = {.name = "Hip", .children = {2, 3}};
  s.nodes[1].t[1] = 0.5;
  s.nodes[2] = {.name = "Knee", .children = {5}};
  s.nodes[2].t[1] = 1.0;
  s.nodes[3] = {.name = "Helmet"};
  s.nodes[3].t[0] = 0.2, s.nodes[3].t[1] = 1.8, s.nodes[3].t[2] = -0.1;
  SetRotation(&s.nodes[3], Quat(1, 2, 0, 35));
  s.nodes[3].s[0] = s.nodes[3].s[1] = s.nodes[3].s[2] = 1.5;
  s.nodes[3].mesh = 1;
  s.nodes[4] = {.name = "BodyNode", .mesh = 0, .skin = 0};
  s.nodes[4].t[2] = 3.0;  // ignored for a skinned mesh
  s.nodes[5] = {.name = "Shield", .mesh = 2};
  s.nodes[5].t[0] = 0.4;
  SetRotation(&s.nodes[5], Quat(0, 1, 0, 20));
  s.nodes[5].s[0] = 2.0, s.nodes[5].s[1] = 0.5, s.nodes[5].s[2] = 1.25;
  s.nodes[6] = {.name = "Lamp", .mesh = 1};
  s.nodes[6].t[0] = -1.5;
  s.skins.push_back({.joints = {1, 2}, .inverse_bind = {}});
  const double a[3] = {-0.3, 0.5, 0.0};
  s.meshes.push_back({"Body", {Strip(a, 0.6, 2.0, 5, 0, 1, true)}});
  const double c1[3] = {0, 0, 0}, h1[3] = {0.2, 0.15, 0.25}, c2[3] = {0.1, 0.3, 0},
               h2[3] = {0.05, 0.1, 0.05}, c3[3] = {0.3, 0, 0.1}, h3[3] = {0.3, 0.4, 0.05};
  s.meshes.push_back({"Helmet", {Box(c1, h1, true), Box(c2, h2, true)}});
  s.meshes.push_back({"Shield", {Box(c3, h3, false)}});
  s.clip.channels.push_back(Translation(0, {0, 2}, {0, 0, 0, 1, 0.5, -2}));
  s.clip.channels.push_back(
      Rotation(1, {0, 1, 2}, {Quat(0, 0, 1, 0), Quat(0, 0, 1, 50), Quat(1, 1, 0, 30)}));
  s.clip.channels.push_back(Rotation(2, {0, 2}, {Quat(0, 0, 1, 0), Quat(1, 0, 0, -70)}));
  s.clip.channels.push_back(Rotation(5, {0, 2}, {Quat(0, 1, 0, 20), Quat(0, 1, 1, 100)}));
  s.clip.channels.push_back(Scale(5, {0, 1, 2}, {2, 0.5, 1.25, 1, 1.5, 0.75, 0.5, 1, 2}));
  s.clip.channels.push_back(Translation(6, {0.5, 1.5}, {-1.5, 0, 0, -1, 1, 0.5}));
  Finish(&s);
  return s;
}

Scene Quantized() {
  Scene s;
  s.extensions_required = {"KHR_mesh_quantization"};
  // 0 Root -> 1 Bone0 -> 2 Bone1, 3 SkinNode (mesh 0, skin 0), 4 Arm (animated) -> 5 ArmMesh
  // (mesh 1, rigid) whose transform is the dequantization, as gltfpack writes it.
  s.nodes.resize(6);
  s.nodes[0] = {.name = "Root", .children = {1, 3, 4}};
  s.nodes[1] = {.name = "Bone0", .children = {2}};
  s.nodes[2] = {.name = "Bone1"};
  s.nodes[2].t[1] = 1.0;
  s.nodes[3] = {.name = "SkinNode", .mesh = 0, .skin = 0};
  s.nodes[4] = {.name = "Arm", .children = {5}};
  s.nodes[4].t[0] = 1.0;
  const double rigid_offset[3] = {-0.25, 0.5, 0.125};
  const double rigid_scale = 1.0 / 1024;
  s.nodes[5] = {.name = "ArmMesh", .mesh = 1};
  std::copy(rigid_offset, rigid_offset + 3, s.nodes[5].t);
  s.nodes[5].s[0] = s.nodes[5].s[1] = s.nodes[5].s[2] = rigid_scale;

  // Skinned: int16 positions (dequantized by the bind shape in the inverse bind matrices),
  // int8 normals, uint8 weights.
  const double skin_offset[3] = {-0.5, 0.0, -0.25};
  const double skin_scale = 1.0 / 4096;
  s.skins.push_back({.joints = {1, 2}, .inverse_bind = {}});
  s.skins[0].bind_shape = Dequantization(skin_offset, skin_scale);
  const double a[3] = {-0.4, 0.1, 0.0};
  ScenePrimitive skinned = Strip(a, 0.5, 1.8, 6, 0, 1, true);
  for (std::size_t i = 0; i < skinned.normals.size(); i += 3) {  // tilted: not axis-aligned
    skinned.normals[i] = 0.3f, skinned.normals[i + 1] = -0.2f, skinned.normals[i + 2] = 0.93f;
  }
  QuantizePositions(&skinned, skin_offset, skin_scale);
  SnapNormalized(&skinned.normals, 5120);
  SnapWeights(&skinned, 5121);
  skinned.encoding = {.position_type = 5122, .normal_type = 5120, .weight_type = 5121};
  // The same with uint16 weights and int16 normals.
  const double b[3] = {0.2, 0.3, 0.1};
  ScenePrimitive skinned16 = Strip(b, 0.2, 1.0, 3, 1, 0, true);
  QuantizePositions(&skinned16, skin_offset, skin_scale);
  SnapNormalized(&skinned16.normals, 5122);
  SnapWeights(&skinned16, 5123);
  skinned16.encoding = {.position_type = 5122, .normal_type = 5122, .weight_type = 5123};
  s.meshes.push_back({"QuantizedBody", {skinned, skinned16}});

  // Rigid: int16 positions with the node's dequantization, int8 normals; and normalized
  // uint16 positions (values in [0, 1]) under the same node.
  const double c[3] = {0.1, 0.2, 0.0}, h[3] = {0.3, 0.1, 0.2};
  ScenePrimitive box = Box(c, h, true);
  QuantizePositions(&box, rigid_offset, rigid_scale);
  SnapNormalized(&box.normals, 5120);
  box.encoding = {.position_type = 5122, .normal_type = 5120};
  const double c2[3] = {0.5, 0.5, 0.5}, h2[3] = {0.25, 0.5, 0.125};
  ScenePrimitive unit = Box(c2, h2, true);
  SnapNormalized(&unit.positions, 5123);
  SnapNormalized(&unit.normals, 5122);
  unit.encoding = {.position_type = 5123, .position_normalized = true, .normal_type = 5122};
  s.meshes.push_back({"QuantizedArm", {box, unit}});

  s.clip.channels.push_back(
      Rotation(2, {0, 1, 2}, {Quat(0, 0, 1, 0), Quat(0, 0, 1, 60), Quat(1, 0, 1, 40)}));
  s.clip.channels.push_back(Rotation(4, {0, 2}, {Quat(0, 1, 0, 0), Quat(1, 1, 0, 90)}));
  s.clip.channels.push_back(Translation(0, {0, 2}, {0, 0, 0, 0.5, 0, 1}));
  Finish(&s);
  return s;
}

Scene Sparse() {
  Scene s;
  // 0 Root -> 1 Bone0 -> 2 Bone1, 3 SkinNode (mesh 0, skin 0), 4 Prop (mesh 1, rigid,
  // animated).
  s.nodes.resize(5);
  s.nodes[0] = {.name = "Root", .children = {1, 3, 4}};
  s.nodes[1] = {.name = "Bone0", .children = {2}};
  s.nodes[2] = {.name = "Bone1"};
  s.nodes[2].t[1] = 1.0;
  s.nodes[3] = {.name = "SkinNode", .mesh = 0, .skin = 0};
  s.nodes[4] = {.name = "Prop", .mesh = 1};
  s.nodes[4].t[2] = 0.5;
  s.skins.push_back({.joints = {1, 2}, .inverse_bind = {}});
  const double a[3] = {-0.3, 0.0, 0.0}, b[3] = {0.3, 0.2, 0.1};
  ScenePrimitive over_base = Strip(a, 0.4, 2.0, 6, 0, 1, true);
  over_base.encoding = {.sparse_positions = 5121, .sparse_normals = 5123, .sparse_weights = 5125};
  ScenePrimitive short_indices = Strip(b, 0.2, 1.0, 4, 1, 0, true);
  short_indices.encoding = {.sparse_positions = 5123};
  s.meshes.push_back({"SparseBody", {over_base, short_indices}});
  // Corners at the origin stay in the zero base; the others are substituted.
  const double c[3] = {0.2, 0.3, 0.1}, h[3] = {0.2, 0.3, 0.1};
  ScenePrimitive prop = Box(c, h, true);
  prop.encoding = {.sparse_positions = 5125, .positions_no_base = true};
  s.meshes.push_back({"SparseProp", {prop}});
  s.clip.channels.push_back(Rotation(2, {0, 2}, {Quat(0, 0, 1, 0), Quat(1, 0, 1, 70)}));
  s.clip.channels.push_back(Rotation(4, {0, 2}, {Quat(1, 0, 0, 0), Quat(1, 0, 0, 120)}));
  Finish(&s);
  return s;
}

namespace {

void PutComponent(std::vector<uint8_t>* out, double v, int component_type, bool normalized) {
  auto put = [&](auto x) {
    const auto* p = reinterpret_cast<const uint8_t*>(&x);
    out->insert(out->end(), p, p + sizeof x);
  };
  if (component_type == 5126) return put(static_cast<float>(v));
  const double q = normalized ? std::round(v * TypeMax(component_type)) : v;
  if (q != std::round(q))
    throw std::logic_error("test scene: " + std::to_string(v) + " is no integer");
  switch (component_type) {
    case 5120:
      return put(static_cast<int8_t>(q));
    case 5121:
      return put(static_cast<uint8_t>(q));
    case 5122:
      return put(static_cast<int16_t>(q));
    case 5123:
      return put(static_cast<uint16_t>(q));
    default:
      throw std::logic_error("test scene: component type " + std::to_string(component_type));
  }
}

std::size_t TypeSize(int component_type) {
  return component_type == 5120 || component_type == 5121   ? 1
         : component_type == 5122 || component_type == 5123 ? 2
                                                            : 4;
}

// Appends a vertex attribute accessor of `values` (`n` components per vertex) stored as
// `component_type`, each element padded to 4 bytes (byteStride) as the spec asks of vertex
// attributes. sparse_type != 0 writes the elements `substituted` picks as a sparse
// substitution (indices of that type), over a base holding garbage there, or no base at all
// (`no_base`: zeros, so the others must be zero).
int WriteAttribute(Glb& glb, const std::vector<float>& values, int n, const char* type,
                   int component_type, bool normalized, int sparse_type, bool no_base,
                   const std::function<bool(std::size_t)>& substituted) {
  const std::size_t count = values.size() / static_cast<std::size_t>(n);
  const std::size_t element = TypeSize(component_type) * static_cast<std::size_t>(n);
  const std::size_t stride = (element + 3) / 4 * 4;
  std::vector<uint8_t> base, sparse_indices, sparse_values;
  for (std::size_t e = 0; e < count; ++e) {
    const bool sparse = sparse_type != 0 && substituted(e);
    for (int c = 0; c < n; ++c) {
      const float v = values[e * static_cast<std::size_t>(n) + static_cast<std::size_t>(c)];
      if (!sparse && no_base && v != 0.0f) {
        throw std::logic_error("test scene: a non-zero value left to a zero base");
      }
      // Garbage under a substitution: the importer must not read it.
      if (!no_base)
        PutComponent(&base, sparse ? (component_type == 5126 ? 99.0 : 3.0) : v, component_type,
                     sparse ? false : normalized);
      if (sparse) PutComponent(&sparse_values, v, component_type, normalized);
    }
    if (!no_base) base.resize(base.size() + stride - element);
    if (sparse) {
      const auto at = static_cast<uint32_t>(e);
      const auto* p = reinterpret_cast<const uint8_t*>(&at);
      sparse_indices.insert(sparse_indices.end(), p, p + TypeSize(sparse_type));
    }
  }
  json a = {{"componentType", component_type}, {"type", type}, {"count", count}};
  if (normalized) a["normalized"] = true;
  if (!no_base) {
    a["bufferView"] = AppendBufferView(glb, base);
    glb.json["bufferViews"].back()["byteStride"] = stride;
  }
  if (sparse_type != 0) {
    const std::size_t substitutions = sparse_indices.size() / TypeSize(sparse_type);
    a["sparse"] = {
        {"count", substitutions},
        {"indices",
         {{"bufferView", AppendBufferView(glb, sparse_indices)}, {"componentType", sparse_type}}},
        {"values", {{"bufferView", AppendBufferView(glb, sparse_values)}}}};
  }
  glb.json["accessors"].push_back(a);
  return static_cast<int>(glb.json["accessors"].size()) - 1;
}

}  // namespace

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
  if (!scene.extensions_required.empty()) {
    j["extensionsRequired"] = scene.extensions_required;
    j["extensionsUsed"] = scene.extensions_required;
  }
  j["scene"] = 0;
  j["scenes"] = json::array({{{"nodes", roots}}});
  for (const SceneMesh& mesh : scene.meshes) {
    json primitives = json::array();
    for (const ScenePrimitive& p : mesh.primitives) {
      const std::size_t v = p.positions.size() / 3;
      const SceneEncoding& e = p.encoding;
      const auto odd = [](std::size_t i) { return i % 2 == 1; };
      const auto non_zero = [&](std::size_t i) {
        return p.positions[3 * i] != 0 || p.positions[3 * i + 1] != 0 ||
               p.positions[3 * i + 2] != 0;
      };
      json attributes;
      attributes["POSITION"] =
          WriteAttribute(glb, p.positions, 3, "VEC3", e.position_type, e.position_normalized,
                         e.sparse_positions, e.positions_no_base,
                         e.positions_no_base ? std::function<bool(std::size_t)>(non_zero)
                                             : std::function<bool(std::size_t)>(odd));
      // min/max are in the stored units: the integers of a normalized accessor.
      const bool scaled = e.position_type != 5126 && e.position_normalized;
      std::vector<float> lo(3, 1e30f), hi(3, -1e30f);
      for (std::size_t i = 0; i < p.positions.size(); ++i) {
        const float stored =
            scaled ? static_cast<float>(std::round(p.positions[i] * TypeMax(e.position_type)))
                   : p.positions[i];
        lo[i % 3] = std::min(lo[i % 3], stored);
        hi[i % 3] = std::max(hi[i % 3], stored);
      }
      j["accessors"].back()["min"] = lo;
      j["accessors"].back()["max"] = hi;
      if (!p.normals.empty()) {
        attributes["NORMAL"] = WriteAttribute(
            glb, p.normals, 3, "VEC3", e.normal_type, e.normal_type != 5126, e.sparse_normals,
            e.sparse_normals != 0, [](std::size_t) { return true; });
      }
      if (!p.joints.empty()) {
        attributes["JOINTS_0"] = AppendAccessor(glb, Bytes(p.joints), 5121, "VEC4", v);
        attributes["WEIGHTS_0"] =
            WriteAttribute(glb, p.weights, 4, "VEC4", e.weight_type, e.weight_type != 5126,
                           e.sparse_weights, false, odd);
      }
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
    if (node.mesh < 0) continue;
    const SceneMesh& mesh = scene.meshes[static_cast<std::size_t>(node.mesh)];
    for (std::size_t p = 0; p < mesh.primitives.size(); ++p) {
      out.push_back({static_cast<int>(n), node.mesh, static_cast<int>(p), node.skin,
                     mesh.name + "/" + std::to_string(p)});
    }
  }
  return out;
}

namespace {

// Primitive `p`'s positions with its morph targets applied in double, with the node's
// weights at `t` (its weights channel, else the mesh's default weights).
std::vector<double> MorphedPositions(const Scene& scene, const ScenePrimitiveRef& p, double t) {
  const ScenePrimitive& sp = scene.meshes[static_cast<std::size_t>(p.mesh)]
                                 .primitives[static_cast<std::size_t>(p.primitive)];
  std::vector<double> positions(sp.positions.begin(), sp.positions.end());
  std::vector<double> weights = scene.meshes[static_cast<std::size_t>(p.mesh)].weights;
  for (const SceneWeightsChannel& ch : scene.weights_channels) {
    if (ch.node == p.node) weights = SampleWeights(ch, sp.target_positions.size(), t);
  }
  for (std::size_t k = 0; k < weights.size() && k < sp.target_positions.size(); ++k) {
    for (std::size_t i = 0; i < positions.size(); ++i) {
      positions[i] += weights[k] * sp.target_positions[k][i];
    }
  }
  return positions;
}

RefFrame RigidFrame(const Scene& scene, const ScenePrimitiveRef& p, double t) {
  const ScenePrimitive& sp = scene.meshes[static_cast<std::size_t>(p.mesh)]
                                 .primitives[static_cast<std::size_t>(p.primitive)];
  const Mat4 m = WorldMatrix(scene, p.node, t);
  const std::vector<double> positions = MorphedPositions(scene, p, t);
  // Normals go by the inverse transpose of the upper 3x3: cofactor(A) / det(A).
  auto at = [&](int r, int c) { return m[4 * c + r]; };
  double cof[3][3];
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) {
      const int r1 = (r + 1) % 3, r2 = (r + 2) % 3, c1 = (c + 1) % 3, c2 = (c + 2) % 3;
      cof[r][c] = at(r1, c1) * at(r2, c2) - at(r1, c2) * at(r2, c1);
    }
  }
  const double det = at(0, 0) * cof[0][0] + at(0, 1) * cof[0][1] + at(0, 2) * cof[0][2];
  RefFrame f;
  for (std::size_t v = 0; v < sp.positions.size() / 3; ++v) {
    const double* x = &positions[3 * v];
    for (int r = 0; r < 3; ++r) {
      f.positions.push_back(at(r, 0) * x[0] + at(r, 1) * x[1] + at(r, 2) * x[2] + at(r, 3));
    }
    if (sp.normals.empty()) continue;
    const float* n = &sp.normals[3 * v];
    double o[3];
    for (int r = 0; r < 3; ++r)
      o[r] = (cof[r][0] * n[0] + cof[r][1] * n[1] + cof[r][2] * n[2]) / det;
    const double len = std::sqrt(o[0] * o[0] + o[1] * o[1] + o[2] * o[2]);
    for (double c : o) f.normals.push_back(c / len);
  }
  return f;
}

}  // namespace

RefFrame SceneFrame(const Scene& scene, const ScenePrimitiveRef& p, double t) {
  if (p.skin < 0) return RigidFrame(scene, p, t);
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
