// Encode and decode throughput of the vertex encodings over a 25k-vertex frame's positions
// (what a server pays per response, and a client per frame).
#include <benchmark/benchmark.h>

#include <random>
#include <vector>

#include "skinserve/encoding/vertex_encoding.h"

namespace skinserve {
namespace {

constexpr std::size_t kVertices = 25000;

std::vector<float> Positions() {
  std::mt19937 rng(1);
  std::uniform_real_distribution<float> u(-1.0f, 1.0f);
  std::vector<float> p(3 * kVertices);
  for (float& v : p) v = u(rng);
  return p;
}

void BM_Encode(benchmark::State& state) {
  const auto encoding = static_cast<VertexEncoding>(state.range(0));
  const std::vector<float> positions = Positions();
  std::vector<std::byte> bytes(EncodedBytes(encoding, kVertices));
  for (auto _ : state) {
    Bounds bounds;  // computed as a server must for snorm16 only
    if (encoding == VertexEncoding::kSnorm16) bounds = *ComputeBounds(positions);
    Status s = EncodePositions(encoding, positions, bounds, bytes);
    benchmark::DoNotOptimize(s);
    benchmark::DoNotOptimize(bytes.data());
  }
  state.SetLabel(VertexEncodingName(encoding));
  state.SetItemsProcessed(state.iterations() * kVertices);
}

void BM_Decode(benchmark::State& state) {
  const auto encoding = static_cast<VertexEncoding>(state.range(0));
  const std::vector<float> positions = Positions();
  const Bounds bounds = *ComputeBounds(positions);
  std::vector<std::byte> bytes(EncodedBytes(encoding, kVertices));
  if (!EncodePositions(encoding, positions, bounds, bytes).ok()) state.SkipWithError("encode");
  std::vector<float> out(positions.size());
  for (auto _ : state) {
    Status s = DecodePositions(encoding, bytes, bounds, out);
    benchmark::DoNotOptimize(s);
    benchmark::DoNotOptimize(out.data());
  }
  state.SetLabel(VertexEncodingName(encoding));
  state.SetItemsProcessed(state.iterations() * kVertices);
}

BENCHMARK(BM_Encode)->DenseRange(0, 2);
BENCHMARK(BM_Decode)->DenseRange(0, 2);

}  // namespace
}  // namespace skinserve

BENCHMARK_MAIN();
