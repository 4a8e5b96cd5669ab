#include "quantized_reference.h"

#include <algorithm>
#include <cmath>

#include "skinserve/reference/synthetic.h"

namespace skinserve::testing {

MeshArrays RandomQuantizedCaseMesh(const QuantizedCase& c, uint64_t seed) {
  MeshArrays arrays = MakeSyntheticMesh({.vertex_count = c.vertices,
                                         .influences = c.influences,
                                         .joint_count = c.joints,
                                         .normals = c.normals,
                                         .seed = seed});
  const float shift[3] = {static_cast<float>(seed % 7) * 3.5f - 10.0f, 4.0f,
                          -static_cast<float>(seed % 5)};
  for (std::size_t i = 0; i < arrays.positions.size(); ++i) arrays.positions[i] += shift[i % 3];
  return arrays;
}

namespace {

double Steps(RestEncoding e) {
  return e == RestEncoding::kQuantized8Weights ? kWeightSteps8 : kWeightSteps16;
}

// One vertex's input as float64.
struct Vertex {
  double p[3];
  double n[3];
  double w[kMaxInfluences];
};

Vertex Decoded(const QuantizedRest& q, uint32_t b, std::size_t v) {
  Vertex x{};
  for (int a = 0; a < 3; ++a) {
    x.p[a] = double{q.offset[a]} + double{q.scale[a]} * q.positions[3 * v + a];
    if (!q.normals.empty()) x.n[a] = q.normals[3 * v + a] / 32767.0;
  }
  double sum = 0;
  for (uint32_t i = 0; i + 1 < b; ++i) {
    const double stored =
        q.weights8.empty() ? q.weights16[v * (b - 1) + i] : q.weights8[v * (b - 1) + i];
    x.w[i] = stored / Steps(q.encoding);
    sum += x.w[i];
  }
  x.w[b - 1] = 1.0 - sum;
  return x;
}

Vertex Original(const MeshArrays& a, std::size_t v) {
  Vertex x{};
  for (int k = 0; k < 3; ++k) {
    x.p[k] = a.positions[3 * v + k];
    if (!a.normals.empty()) x.n[k] = a.normals[3 * v + k];
  }
  // Mesh::Create renormalises weights to sum exactly 1: so does this reference.
  double sum = 0;
  for (uint32_t i = 0; i < a.influences; ++i) sum += a.weights[v * a.influences + i];
  for (uint32_t i = 0; i < a.influences; ++i) x.w[i] = a.weights[v * a.influences + i] / sum;
  return x;
}

// The blended matrix sum_i w_i M_i (equation 3), 3x4 row-major, in float64.
void Blend(std::span<const float> palette, const uint16_t* joints, const double* w, uint32_t b,
           double m[12]) {
  std::fill(m, m + 12, 0.0);
  for (uint32_t i = 0; i < b; ++i) {
    for (int e = 0; e < 12; ++e) m[e] += w[i] * palette[12 * joints[i] + e];
  }
}

}  // namespace

double FloatTolerance(std::span<const float> palette, const MeshArrays& a) {
  double max_p = 0, max_row = 0, max_t = 0;
  for (float x : a.positions) max_p = std::max(max_p, std::fabs(double{x}));
  for (std::size_t j = 0; j < palette.size() / 12; ++j) {
    for (int r = 0; r < 3; ++r) {
      double row = 0;
      for (int c = 0; c < 3; ++c) row += std::fabs(palette[12 * j + 4 * r + c]);
      max_row = std::max(max_row, row);
      max_t = std::max(max_t, std::fabs(double{palette[12 * j + 4 * r + 3]}));
    }
  }
  return 1e-5 * (1 + max_p * max_row + max_t);
}

QuantizedErrors CheckQuantized(const Mesh& mesh, const MeshArrays& original,
                               std::span<const float> palette, std::span<const float> positions,
                               std::span<const float> normals) {
  const QuantizedRest& q = *mesh.quantized_rest();
  const uint32_t b = mesh.influences();
  const double float_tolerance = FloatTolerance(palette, original);
  double extent = 0;
  for (int a = 0; a < 3; ++a) extent = std::max(extent, double{q.scale[a]} * kPositionSteps);
  QuantizedErrors e;
  for (std::size_t v = 0; v < mesh.vertex_count(); ++v) {
    const uint16_t* joints = original.joints.data() + v * b;
    const Vertex d = Decoded(q, b, v), o = Original(original, v);
    double m[12];
    Blend(palette, joints, d.w, b, m);
    for (int r = 0; r < 3; ++r) {
      const double* row = m + 4 * r;
      const double got = positions[3 * v + r];
      const double dequantized = row[0] * d.p[0] + row[1] * d.p[1] + row[2] * d.p[2] + row[3];
      e.dequantized_position = std::max(e.dequantized_position, std::fabs(got - dequantized));
      // Reference 2: the original input, and the bound.
      double mo[12];
      Blend(palette, joints, o.w, b, mo);
      const double* ro = mo + 4 * r;
      const double exact = ro[0] * o.p[0] + ro[1] * o.p[1] + ro[2] * o.p[2] + ro[3];
      double bound = float_tolerance;
      for (int k = 0; k < 3; ++k) bound += std::fabs(row[k]) * q.scale[k] / 2;
      const float* last = palette.data() + 12 * joints[b - 1];
      for (uint32_t i = 0; i + 1 < b; ++i) {
        const float* mi = palette.data() + 12 * joints[i];
        double diff = mi[4 * r + 3] - last[4 * r + 3];
        for (int k = 0; k < 3; ++k) diff += (mi[4 * r + k] - last[4 * r + k]) * o.p[k];
        bound += std::fabs(diff) / Steps(q.encoding);
      }
      const double error = std::fabs(got - exact);
      e.over_bound = std::max(e.over_bound, std::isnan(got) ? 1e30 : error / bound);
      e.relative_to_extent = std::max(e.relative_to_extent, error / extent);
    }
    if (!normals.empty()) {
      double n[3], length = 0;
      for (int r = 0; r < 3; ++r) {
        n[r] = m[4 * r] * d.n[0] + m[4 * r + 1] * d.n[1] + m[4 * r + 2] * d.n[2];
        length += n[r] * n[r];
      }
      length = std::sqrt(length);
      for (int r = 0; r < 3; ++r) {
        const double error = std::fabs(normals[3 * v + r] - n[r] / length);
        e.dequantized_normal =
            std::max(e.dequantized_normal, std::isnan(normals[3 * v + r]) ? 1e30 : error);
      }
    }
  }
  if (std::isnan(e.dequantized_position)) e.dequantized_position = 1e30;
  return e;
}

void ExpectQuantizedTangentsMatchReference(Backend& backend, const MeshCase& c,
                                           RestEncoding encoding, uint64_t seed,
                                           const std::string& what) {
  auto mesh = Mesh::Create(MakeSyntheticMesh({.vertex_count = c.vertices,
                                              .influences = c.influences,
                                              .joint_count = c.joints,
                                              .normals = true,
                                              .tangents = true,
                                              .seed = seed}),
                           {.rest_encoding = encoding});
  ASSERT_TRUE(mesh.ok()) << what << ": " << mesh.status().ToString();
  ASSERT_EQ((*mesh)->quantized_rest()->tangents.size(), 4u * c.vertices) << what;
  auto prepared = backend.Prepare(*mesh);
  ASSERT_TRUE(prepared.ok()) << what << ": " << prepared.status().ToString();
  ExpectFrameMatchesReference(backend, **prepared, **mesh, MakeSyntheticPalette(c.joints, seed, 2),
                              {c.vertices, c.influences, c.joints, true, true},
                              SkinningMethod::kLinear,
                              what + " " + std::string(RestEncodingName(encoding)));
}

}  // namespace skinserve::testing
