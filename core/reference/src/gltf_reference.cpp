#include "skinserve/reference/gltf_reference.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <functional>
#include <stdexcept>

namespace skinserve::gltf_reference {
namespace {

using nlohmann::json;

uint32_t ReadU32(const std::vector<uint8_t>& b, std::size_t at) {
  if (at + 4 > b.size()) throw std::runtime_error("glTF reference reader: GLB too short");
  uint32_t v;
  std::memcpy(&v, b.data() + at, 4);
  return v;
}

int ComponentCount(const std::string& type) {
  if (type == "SCALAR") return 1;
  if (type == "VEC2") return 2;
  if (type == "VEC3") return 3;
  if (type == "VEC4") return 4;
  if (type == "MAT4") return 16;
  throw std::runtime_error("glTF reference reader: unsupported accessor type " + type);
}

std::size_t ComponentSize(int component_type) {
  switch (component_type) {
    case 5120:
    case 5121:
      return 1;
    case 5122:
    case 5123:
      return 2;
    default:
      return 4;
  }
}

Mat4 Multiply(const Mat4& a, const Mat4& b) {
  Mat4 m{};
  for (int c = 0; c < 4; ++c)
    for (int r = 0; r < 4; ++r)
      for (int k = 0; k < 4; ++k) m[4 * c + r] += a[4 * k + r] * b[4 * c + k];
  return m;
}

}  // namespace

Mat4 Compose(const double t[3], const double q_in[4], const double s[3]) {
  const double n =
      std::sqrt(q_in[0] * q_in[0] + q_in[1] * q_in[1] + q_in[2] * q_in[2] + q_in[3] * q_in[3]);
  const double x = q_in[0] / n, y = q_in[1] / n, z = q_in[2] / n, w = q_in[3] / n;
  const double r[3][3] = {{1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)},
                          {2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)},
                          {2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)}};
  Mat4 m{};
  for (int c = 0; c < 3; ++c)
    for (int row = 0; row < 3; ++row) m[4 * c + row] = r[row][c] * s[c];
  m[12] = t[0], m[13] = t[1], m[14] = t[2], m[15] = 1;
  return m;
}

Glb ParseGlb(const std::vector<uint8_t>& bytes) {
  const uint32_t json_length = ReadU32(bytes, 12);
  Glb glb;
  glb.json = json::parse(bytes.begin() + 20, bytes.begin() + 20 + json_length);
  const std::size_t bin_at = 20 + json_length;
  if (bin_at + 8 <= bytes.size()) {
    const uint32_t bin_length = ReadU32(bytes, bin_at);
    glb.bin.assign(bytes.begin() + static_cast<std::ptrdiff_t>(bin_at + 8),
                   bytes.begin() + static_cast<std::ptrdiff_t>(bin_at + 8 + bin_length));
  }
  return glb;
}

std::size_t ElementOffset(const Glb& glb, int accessor, std::size_t e) {
  const json& a = glb.json["accessors"][static_cast<std::size_t>(accessor)];
  const json& v = glb.json["bufferViews"][a["bufferView"].get<std::size_t>()];
  const std::size_t element =
      ComponentSize(a["componentType"].get<int>()) *
      static_cast<std::size_t>(ComponentCount(a["type"].get<std::string>()));
  const std::size_t stride = v.value("byteStride", std::size_t{0});
  return v.value("byteOffset", std::size_t{0}) + a.value("byteOffset", std::size_t{0}) +
         e * (stride ? stride : element);
}

std::vector<double> ReadAccessor(const Glb& glb, int accessor) {
  const json& a = glb.json["accessors"][static_cast<std::size_t>(accessor)];
  const int ct = a["componentType"].get<int>();
  const bool normalized = a.value("normalized", false);
  const int components = ComponentCount(a["type"].get<std::string>());
  const std::size_t count = a["count"].get<std::size_t>();
  std::vector<double> out;
  for (std::size_t e = 0; e < count; ++e) {
    const std::size_t at = ElementOffset(glb, accessor, e);
    for (int c = 0; c < components; ++c) {
      const uint8_t* p = &glb.bin.at(at + static_cast<std::size_t>(c) * ComponentSize(ct));
      double v = 0;
      switch (ct) {
        case 5126: {
          float f;
          std::memcpy(&f, p, 4);
          v = f;
          break;
        }
        case 5121:
          v = normalized ? *p / 255.0 : *p;
          break;
        case 5123: {
          uint16_t u;
          std::memcpy(&u, p, 2);
          v = normalized ? u / 65535.0 : u;
          break;
        }
        case 5125: {
          uint32_t u;
          std::memcpy(&u, p, 4);
          v = u;
          break;
        }
        case 5120: {
          int8_t i;
          std::memcpy(&i, p, 1);
          v = normalized ? std::max(i / 127.0, -1.0) : i;
          break;
        }
        case 5122: {
          int16_t i;
          std::memcpy(&i, p, 2);
          v = normalized ? std::max(i / 32767.0, -1.0) : i;
          break;
        }
        default:
          throw std::runtime_error("glTF reference reader: component type " + std::to_string(ct));
      }
      out.push_back(v);
    }
  }
  return out;
}

RefCharacter ReadReference(const Glb& glb) {
  const json& j = glb.json;
  RefCharacter ref;
  ref.nodes.resize(j["nodes"].size());
  for (std::size_t i = 0; i < j["nodes"].size(); ++i) {
    const json& n = j["nodes"][i];
    RefNode& r = ref.nodes[i];
    if (n.contains("matrix")) {
      r.has_matrix = true;
      for (int k = 0; k < 16; ++k) r.matrix[static_cast<std::size_t>(k)] = n["matrix"][k];
    }
    if (n.contains("translation"))
      for (int k = 0; k < 3; ++k) r.t[k] = n["translation"][k];
    if (n.contains("rotation"))
      for (int k = 0; k < 4; ++k) r.r[k] = n["rotation"][k];
    if (n.contains("scale"))
      for (int k = 0; k < 3; ++k) r.s[k] = n["scale"][k];
  }
  for (std::size_t i = 0; i < j["nodes"].size(); ++i) {
    for (int child : j["nodes"][i].value("children", std::vector<int>{}))
      ref.nodes[static_cast<std::size_t>(child)].parent = static_cast<int>(i);
  }
  const json& skin = j["skins"][0];
  ref.joints = skin["joints"].get<std::vector<int>>();
  const std::vector<double> ibm = ReadAccessor(glb, skin["inverseBindMatrices"].get<int>());
  for (std::size_t k = 0; k < ref.joints.size(); ++k) {
    Mat4 m;
    std::copy(ibm.begin() + static_cast<std::ptrdiff_t>(16 * k),
              ibm.begin() + static_cast<std::ptrdiff_t>(16 * k + 16), m.begin());
    ref.inverse_bind.push_back(m);
  }
  for (const json& n : j["nodes"]) {
    if (!n.contains("mesh") || !n.contains("skin")) continue;
    const json& p = j["meshes"][n["mesh"].get<std::size_t>()]["primitives"][0];
    const json& attributes = p["attributes"];
    RefPrimitive& prim = ref.primitive;
    prim.positions = ReadAccessor(glb, attributes["POSITION"].get<int>());
    prim.vertex_count = prim.positions.size() / 3;
    if (attributes.contains("NORMAL")) prim.normals = ReadAccessor(glb, attributes["NORMAL"]);
    for (double v : ReadAccessor(glb, attributes["JOINTS_0"])) prim.joints.push_back(int(v));
    prim.weights = ReadAccessor(glb, attributes["WEIGHTS_0"]);
    for (std::size_t v = 0; v < prim.vertex_count; ++v) {
      double sum = 0;
      for (int k = 0; k < 4; ++k) sum += prim.weights[4 * v + k];
      for (int k = 0; k < 4; ++k) prim.weights[4 * v + k] /= sum;
    }
    prim.index_count = p.contains("indices")
                           ? j["accessors"][p["indices"].get<std::size_t>()]["count"].get<size_t>()
                           : prim.vertex_count;
    break;
  }
  for (const json& a : j.value("animations", json::array())) {
    RefClip clip;
    clip.name = a.value("name", "");
    for (const json& c : a["channels"]) {
      const std::string path = c["target"]["path"];
      if (path == "weights") continue;
      const json& sampler = a["samplers"][c["sampler"].get<std::size_t>()];
      RefChannel ch;
      ch.node = c["target"]["node"];
      ch.path = path;
      ch.interpolation = sampler.value("interpolation", "LINEAR");
      ch.times = ReadAccessor(glb, sampler["input"]);
      ch.values = ReadAccessor(glb, sampler["output"]);
      clip.duration = std::max(clip.duration, ch.times.back());
      clip.channels.push_back(std::move(ch));
    }
    ref.clips.push_back(std::move(clip));
  }
  return ref;
}

std::vector<double> RefSample(const RefChannel& ch, double t) {
  const std::size_t n = ch.path == "rotation" ? 4 : 3;
  const bool cubic = ch.interpolation == "CUBICSPLINE";
  const std::size_t keys = ch.times.size();
  auto key = [&](std::size_t k, std::size_t part) {  // part: 0 in-tangent, 1 value, 2 out
    return std::vector<double>(
        ch.values.begin() + static_cast<std::ptrdiff_t>(((cubic ? 3 * k + part : k)) * n),
        ch.values.begin() + static_cast<std::ptrdiff_t>(((cubic ? 3 * k + part : k) + 1) * n));
  };
  if (t <= ch.times.front()) return key(0, 1);
  if (t >= ch.times.back()) return key(keys - 1, 1);
  std::size_t k = 0;
  while (!(ch.times[k] <= t && t < ch.times[k + 1])) ++k;
  const double t0 = ch.times[k], t1 = ch.times[k + 1];
  const double u = (t - t0) / (t1 - t0);
  std::vector<double> a = key(k, 1), b = key(k + 1, 1), out(n);
  if (ch.interpolation == "STEP") return a;
  if (cubic) {
    const std::vector<double> m0 = key(k, 2), m1 = key(k + 1, 0);
    const double d = t1 - t0;
    for (std::size_t c = 0; c < n; ++c) {
      out[c] = (2 * u * u * u - 3 * u * u + 1) * a[c] + (u * u * u - 2 * u * u + u) * d * m0[c] +
               (-2 * u * u * u + 3 * u * u) * b[c] + (u * u * u - u * u) * d * m1[c];
    }
  } else if (n == 4) {
    double dot = 0;
    for (std::size_t c = 0; c < 4; ++c) dot += a[c] * b[c];
    if (dot < 0) {
      for (double& x : b) x = -x;
      dot = -dot;
    }
    const double theta = std::acos(std::min(1.0, dot));
    for (std::size_t c = 0; c < 4; ++c) {
      out[c] = theta < 1e-9 ? a[c] + u * (b[c] - a[c])
                            : (std::sin((1 - u) * theta) * a[c] + std::sin(u * theta) * b[c]) /
                                  std::sin(theta);
    }
  } else {
    for (std::size_t c = 0; c < n; ++c) out[c] = a[c] + u * (b[c] - a[c]);
  }
  if (n == 4) {
    double len = 0;
    for (double x : out) len += x * x;
    for (double& x : out) x /= std::sqrt(len);
  }
  return out;
}

std::vector<double> RefPalette(const RefCharacter& ref, const RefClip* clip, double t) {
  std::vector<RefNode> nodes = ref.nodes;
  if (clip) {
    for (const RefChannel& ch : clip->channels) {
      const std::vector<double> v = RefSample(ch, t);
      RefNode& n = nodes[static_cast<std::size_t>(ch.node)];
      double* target = ch.path == "translation" ? n.t : ch.path == "rotation" ? n.r : n.s;
      std::copy(v.begin(), v.end(), target);
    }
  }
  std::vector<Mat4> model(nodes.size());
  std::vector<bool> done(nodes.size(), false);
  std::function<const Mat4&(std::size_t)> world = [&](std::size_t i) -> const Mat4& {
    if (!done[i]) {
      const RefNode& n = nodes[i];
      const Mat4 local = n.has_matrix ? n.matrix : Compose(n.t, n.r, n.s);
      model[i] = n.parent < 0 ? local : Multiply(world(static_cast<std::size_t>(n.parent)), local);
      done[i] = true;
    }
    return model[i];
  };
  std::vector<double> palette;
  for (std::size_t j = 0; j < ref.joints.size(); ++j) {
    const Mat4 m = Multiply(world(static_cast<std::size_t>(ref.joints[j])), ref.inverse_bind[j]);
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 4; ++c) palette.push_back(m[static_cast<std::size_t>(4 * c + r)]);
  }
  return palette;
}

RefFrame RefSkin(const RefPrimitive& p, const std::vector<double>& palette) {
  RefFrame f;
  for (std::size_t v = 0; v < p.vertex_count; ++v) {
    double m[12] = {};
    for (int k = 0; k < 4; ++k) {
      const double w = p.weights[4 * v + static_cast<std::size_t>(k)];
      const std::size_t joint =
          static_cast<std::size_t>(p.joints[4 * v + static_cast<std::size_t>(k)]);
      for (int e = 0; e < 12; ++e) m[e] += w * palette[12 * joint + static_cast<std::size_t>(e)];
    }
    const double* x = &p.positions[3 * v];
    for (int r = 0; r < 3; ++r)
      f.positions.push_back(m[4 * r] * x[0] + m[4 * r + 1] * x[1] + m[4 * r + 2] * x[2] +
                            m[4 * r + 3]);
    if (!p.normals.empty()) {
      const double* n = &p.normals[3 * v];
      double o[3];
      for (int r = 0; r < 3; ++r)
        o[r] = m[4 * r] * n[0] + m[4 * r + 1] * n[1] + m[4 * r + 2] * n[2];
      const double len = std::sqrt(o[0] * o[0] + o[1] * o[1] + o[2] * o[2]);
      for (double c : o) f.normals.push_back(c / len);
    }
  }
  return f;
}

}  // namespace skinserve::gltf_reference
