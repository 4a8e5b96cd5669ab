#include "skinserve/model/quantized_rest.h"

#include <algorithm>
#include <cmath>
#include <limits>

namespace skinserve {
namespace {

// A step no smaller than this keeps 1 / scale (the normals' rescale in the loop) finite.
constexpr float kSmallestScale = 0x1p-100f;

uint32_t WeightSteps(RestEncoding encoding) {
  return encoding == RestEncoding::kQuantized8Weights ? kWeightSteps8 : kWeightSteps16;
}

// The first B - 1 weights of a vertex as integers of `steps`, rounded to nearest, then the
// ones rounded up the most lowered by one until their sum is at most `steps` (the last
// weight, 1 - the sum, stays >= 0). Each ends within one step of its weight.
void QuantizeWeights(const float* w, uint32_t b, uint32_t steps, uint32_t* q) {
  uint32_t sum = 0;
  for (uint32_t i = 0; i + 1 < b; ++i) {
    q[i] = static_cast<uint32_t>(std::lround(double{w[i]} * steps));
    sum += q[i];
  }
  while (sum > steps) {
    uint32_t worst = 0;
    double worst_error = -1;
    for (uint32_t i = 0; i + 1 < b; ++i) {
      const double error = q[i] - double{w[i]} * steps;
      if (q[i] > 0 && error > worst_error) worst = i, worst_error = error;
    }
    --q[worst], --sum;
  }
}

// The unit direction of xyz[0..2] in snorm16 into q[0..2]; xyz becomes what q decodes to.
void QuantizeDirection(float* xyz, int16_t* q) {
  const double length =
      std::sqrt(double{xyz[0]} * xyz[0] + double{xyz[1]} * xyz[1] + double{xyz[2]} * xyz[2]);
  for (int a = 0; a < 3; ++a) {
    q[a] = static_cast<int16_t>(std::lround(xyz[a] / length * kNormalSteps));
    xyz[a] = static_cast<float>(q[a] / double{kNormalSteps});
  }
}

}  // namespace

std::string_view RestEncodingName(RestEncoding encoding) {
  switch (encoding) {
    case RestEncoding::kFloat32:
      return "float32";
    case RestEncoding::kQuantized16:
      return "quantized16";
    case RestEncoding::kQuantized8Weights:
      return "quantized8-weights";
  }
  return "unknown";
}

std::optional<RestEncoding> ParseRestEncoding(std::string_view name) {
  for (RestEncoding e :
       {RestEncoding::kFloat32, RestEncoding::kQuantized16, RestEncoding::kQuantized8Weights}) {
    if (name == RestEncodingName(e)) return e;
  }
  return std::nullopt;
}

uint64_t QuantizedRestBytesPerVertex(RestEncoding encoding, uint64_t influences,
                                     uint64_t joint_count, bool has_normals, bool has_tangents) {
  if (encoding == RestEncoding::kFloat32) return 0;
  const uint64_t weight = encoding == RestEncoding::kQuantized8Weights ? 1 : 2;
  const uint64_t joint = joint_count <= 256 ? 1 : 2;
  return 3 * 2 * (has_normals ? 2 : 1) + (has_tangents ? 4 * 2 : 0) + influences * joint +
         (influences - 1) * weight;
}

double StreamedBytesPerVertex(RestEncoding encoding, uint32_t influences, uint32_t joint_count,
                              bool normals, bool tangents) {
  const double out = (normals ? 24.0 : 12.0) + (tangents ? 16.0 : 0.0);
  if (encoding == RestEncoding::kFloat32) {
    // The `simd` float stream (simd_stream.h): float32 rest, 8-bit joints where they fit,
    // B - 1 float weights.
    const double joint = joint_count <= 256 ? 1 : 2;
    return out + (normals ? 24.0 : 12.0) + (tangents ? 16.0 : 0.0) + influences * joint +
           (influences - 1) * 4.0;
  }
  return out + static_cast<double>(QuantizedRestBytesPerVertex(encoding, influences, joint_count,
                                                               normals, tangents));
}

uint64_t QuantizedRest::byte_size() const {
  return positions.size() * 2 + normals.size() * 2 + tangents.size() * 2 + joints8.size() +
         joints16.size() * 2 + weights8.size() + weights16.size() * 2;
}

namespace {

// Positions: the box, then one step per axis rounded up so that 65535 steps cover it;
// `positions` becomes what the steps decode to.
void QuantizePositions(std::span<float> positions, std::size_t v_count, QuantizedRest* rest) {
  float lo[3] = {positions[0], positions[1], positions[2]};
  float hi[3] = {lo[0], lo[1], lo[2]};
  for (std::size_t i = 0; i < positions.size(); ++i) {
    lo[i % 3] = std::min(lo[i % 3], positions[i]);
    hi[i % 3] = std::max(hi[i % 3], positions[i]);
  }
  for (int a = 0; a < 3; ++a) {
    const double extent = double{hi[a]} - lo[a];
    float scale = static_cast<float>(extent / kPositionSteps);
    if (double{scale} * kPositionSteps < extent) {
      scale = std::nextafter(scale, std::numeric_limits<float>::infinity());
    }
    rest->offset[a] = lo[a];
    rest->scale[a] = std::max(scale, kSmallestScale);
  }
  rest->positions = AlignedBuffer<uint16_t>(3 * v_count);
  for (std::size_t i = 0; i < 3 * v_count; ++i) {
    const int a = static_cast<int>(i % 3);
    const double q = std::round((double{positions[i]} - rest->offset[a]) / rest->scale[a]);
    rest->positions[i] = static_cast<uint16_t>(std::clamp(q, 0.0, double{kPositionSteps}));
    positions[i] =
        static_cast<float>(rest->offset[a] + double{rest->scale[a]} * rest->positions[i]);
  }
}

// Normals: the unit direction in snorm16 (skinning renormalises, so only it matters).
// Tangents: xyz as the normals, w (+1 or -1) as +-32767. Each becomes what it decodes to.
void QuantizeDirections(std::span<float> normals, std::span<float> tangents, std::size_t v_count,
                        QuantizedRest* rest) {
  if (!normals.empty()) {
    rest->normals = AlignedBuffer<int16_t>(3 * v_count);
    for (std::size_t v = 0; v < v_count; ++v) {
      QuantizeDirection(&normals[3 * v], &rest->normals[3 * v]);
    }
  }
  if (!tangents.empty()) {
    rest->tangents = AlignedBuffer<int16_t>(4 * v_count);
    for (std::size_t v = 0; v < v_count; ++v) {
      float* t = &tangents[4 * v];
      QuantizeDirection(t, &rest->tangents[4 * v]);
      rest->tangents[4 * v + 3] = static_cast<int16_t>(t[3] < 0 ? -kNormalSteps : kNormalSteps);
      t[3] = t[3] < 0 ? -1.0f : 1.0f;
    }
  }
}

// The first B - 1 weights of every vertex in 8 or 16 bits (the last is 1 - their sum);
// `weights` becomes what they decode to.
void QuantizeAllWeights(RestEncoding encoding, std::span<float> weights, std::size_t v_count,
                        uint32_t b, QuantizedRest* rest) {
  const uint32_t steps = WeightSteps(encoding);
  const bool eight = encoding == RestEncoding::kQuantized8Weights;
  if (b > 1) {
    if (eight) {
      rest->weights8 = AlignedBuffer<uint8_t>(v_count * (b - 1));
    } else {
      rest->weights16 = AlignedBuffer<uint16_t>(v_count * (b - 1));
    }
  }
  for (std::size_t v = 0; v < v_count; ++v) {
    float* w = &weights[v * b];
    uint32_t q[8] = {};
    QuantizeWeights(w, b, steps, q);
    double sum = 0;
    for (uint32_t i = 0; i + 1 < b; ++i) {
      if (eight) {
        rest->weights8[v * (b - 1) + i] = static_cast<uint8_t>(q[i]);
      } else {
        rest->weights16[v * (b - 1) + i] = static_cast<uint16_t>(q[i]);
      }
      const double decoded = double{static_cast<double>(q[i])} / steps;
      w[i] = static_cast<float>(decoded);
      sum += decoded;
    }
    w[b - 1] = static_cast<float>(1.0 - sum);
  }
}

}  // namespace

QuantizedRest Quantize(RestEncoding encoding, uint32_t vertex_count, uint32_t influences,
                       uint32_t joint_count, std::span<float> positions, std::span<float> normals,
                       std::span<float> tangents, std::span<const uint16_t> joints,
                       std::span<float> weights) {
  QuantizedRest rest;
  rest.encoding = encoding;
  rest.influences = influences;
  QuantizePositions(positions, vertex_count, &rest);
  QuantizeDirections(normals, tangents, vertex_count, &rest);
  if (joint_count <= 256) {
    rest.joints8 = AlignedBuffer<uint8_t>(joints.size());
    for (std::size_t i = 0; i < joints.size(); ++i) {
      rest.joints8[i] = static_cast<uint8_t>(joints[i]);
    }
  } else {
    rest.joints16 = AlignedBuffer<uint16_t>(joints);
  }
  QuantizeAllWeights(encoding, weights, vertex_count, influences, &rest);
  return rest;
}

}  // namespace skinserve
