#include "paper_tables.h"

#include <fmt/format.h>

#include <algorithm>
#include <set>
#include <sstream>

#include "skinserve/model/quantized_rest.h"
#include "workload_cache.h"

namespace skinserve::bench {
namespace {

std::vector<std::string> Split(const std::string& s, char sep) {
  std::vector<std::string> parts;
  std::stringstream stream(s);
  for (std::string part; std::getline(stream, part, sep);) parts.push_back(part);
  return parts;
}

// The rest stream a row's kind names: BM_Skin[Normals|Tangents]Quantized[Weights8] or float.
RestEncoding StreamOf(const std::string& kind) {
  if (kind.find("QuantizedWeights8") != std::string::npos) return RestEncoding::kQuantized8Weights;
  if (kind.find("Quantized") != std::string::npos) return RestEncoding::kQuantized16;
  return RestEncoding::kFloat32;
}

}  // namespace

void PaperTablesReporter::ReportRuns(const std::vector<Run>& runs) {
  ConsoleReporter::ReportRuns(runs);
  for (const Run& run : runs) {
    if (run.run_type == Run::RT_Iteration && run.repetitions > 1) continue;
    const std::vector<std::string> name = Split(run.run_name.function_name, '/');
    const bool aggregate = run.run_type == Run::RT_Aggregate;
    if (name.size() == 1 && name[0] == "BM_MemoryBandwidth") {
      // The best repetition when repeated (see its registration), the single run otherwise.
      if (aggregate && run.aggregate_name != "max") continue;
      auto it = run.counters.find("bytes_per_second");
      if (it != run.counters.end()) bandwidth_bytes_per_second_ = it->second.value;
      continue;
    }
    if (name.size() == 1 && (name[0] == "BM_PcieHostToDevice" || name[0] == "BM_PcieDeviceToHost" ||
                             name[0] == "BM_DeviceMemoryCopy")) {
      if (aggregate && run.aggregate_name != "max") continue;
      auto it = run.counters.find("bytes_per_second");
      if (it != run.counters.end()) device_bounds_[name[0]] = it->second.value;
      continue;
    }
    // Medians when repeated, the single run otherwise.
    if (aggregate && run.aggregate_name != "median") continue;
    if (name.size() != 4) continue;
    // Several threads (BM_SkinStreams): items, summed over the threads.
    auto it = run.counters.find(name[0].rfind("BM_SkinStreams", 0) == 0 ? "items_per_second"
                                                                        : "vertices_per_second");
    if (it == run.counters.end()) continue;
    const std::tuple key{name[0], name[1], static_cast<uint32_t>(std::stoul(name[2])),
                         static_cast<uint32_t>(std::stoul(name[3]))};
    rates_[key] = it->second.value;
    if (auto kernel = run.counters.find("kernel_vertices_per_second");
        kernel != run.counters.end()) {
      kernel_rates_[key] = kernel->second.value;
    }
  }
}

void PaperTablesReporter::PrintTables(const std::vector<std::string>& backends) const {
  for (const char* kind : {"BM_Skin", "BM_SkinNormals"}) {
    std::set<uint32_t> vertices, bones;
    for (const auto& [key, rate] : rates_) {
      if (std::get<0>(key) != kind) continue;
      vertices.insert(std::get<2>(key));
      bones.insert(std::get<3>(key));
    }
    if (vertices.empty()) continue;
    const std::string what = std::string(kind) == "BM_Skin" ? "positions" : "positions+normals";
    auto rate = [&](const std::string& backend, uint32_t v, uint32_t b) {
      auto it = rates_.find({kind, backend, v, b});
      return it == rates_.end() ? 0.0 : it->second;
    };
    fmt::print("\n== Speedup over serial ({}, 77 joints; medians of one run) ==\n", what);
    for (const std::string& backend : backends) {
      fmt::print("\n{}\n{:>10}", backend, "vertices");
      for (uint32_t b : bones) fmt::print(" {:>8}", fmt::format("B={}", b));
      fmt::print("\n");
      for (uint32_t v : vertices) {
        fmt::print("{:>10}", v);
        for (uint32_t b : bones) {
          const double serial = rate("serial", v, b), mine = rate(backend, v, b);
          fmt::print(" {:>8}", serial > 0 && mine > 0 ? fmt::format("{:.2f}x", mine / serial)
                                                      : std::string("-"));
        }
        fmt::print("\n");
      }
    }
    fmt::print("\nMillion vertices per second ({})\n{:>16}", what, "backend \\ V,B");
    const uint32_t v_max = *vertices.rbegin(), b_max = *bones.rbegin();
    // The memory bound at the largest frame: what the copy bandwidth allows at the bytes
    // a vertex of the uploaded layout moves (the `simd` stream moves fewer, see
    // docs/backends/simd.md).
    const double bound_at_max =
        bandwidth_bytes_per_second_ / BytesPerVertex(b_max, what != "positions");
    for (uint32_t v : vertices) fmt::print(" {:>10}", fmt::format("{}k,{}", v / 1000, b_max));
    if (bound_at_max > 0) fmt::print(" {:>10}", "% of bound");
    fmt::print("\n");
    for (const std::string& backend : backends) {
      fmt::print("{:>16}", backend);
      for (uint32_t v : vertices) fmt::print(" {:>10.1f}", rate(backend, v, b_max) / 1e6);
      if (bound_at_max > 0) {
        fmt::print(" {:>9.0f}%", 100 * rate(backend, v_max, b_max) / bound_at_max);
      }
      fmt::print("\n");
    }
    if (bandwidth_bytes_per_second_ > 0) {
      std::string fastest;
      double best = 0;
      for (const std::string& backend : backends) {
        if (backend == "passthrough") continue;
        if (rate(backend, v_max, b_max) > best)
          best = rate(backend, v_max, b_max), fastest = backend;
      }
      const double bytes = BytesPerVertex(b_max, what != "positions");
      const double bound = bandwidth_bytes_per_second_ / bytes;
      fmt::print(
          "\nMemory bandwidth (copy, all cores, best repetition): {:.1f} GB/s; at {} B/vertex the "
          "bound is {:.0f} M vertices/s.\nFastest at {} x {}: {} with {:.0f} M vertices/s = "
          "{:.0f}% of the bound.\n",
          bandwidth_bytes_per_second_ / 1e9, bytes, bound / 1e6, v_max, b_max, fastest, best / 1e6,
          100 * best / bound);
      if (best > bound) {
        fmt::print(
            "Faster than the bound: the bandwidth run was disturbed (other processes?) or the "
            "frame fits in cache; rerun with more --benchmark_repetitions.\n");
      }
    }
  }
}

void PaperTablesReporter::PrintDeviceBounds() const {
  auto bound = [&](const char* name) {
    auto it = device_bounds_.find(name);
    return it == device_bounds_.end() ? 0.0 : it->second;
  };
  const double h2d = bound("BM_PcieHostToDevice"), d2h = bound("BM_PcieDeviceToHost"),
               copy = bound("BM_DeviceMemoryCopy");
  if (d2h <= 0 || copy <= 0) return;
  fmt::print(
      "\n== OpenCL device against its bounds (best repetitions) ==\nPCIe host->device {:.1f} "
      "GB/s, device->host {:.1f} GB/s (pinned); device memory copy {:.0f} GB/s (read + "
      "write).\nFrame bound: 12 B/vertex of positions back over PCIe (6 encoded); kernel bound: "
      "BytesPerVertex "
      "through device memory.\n",
      h2d / 1e9, d2h / 1e9, copy / 1e9);
  fmt::print("{:<16} {:>10} {:>3} {:>12} {:>8} {:>14} {:>8}\n", "backend", "vertices", "B",
             "M vert/s", "% PCIe", "kernel M v/s", "% mem");
  for (const auto& [key, rate] : rates_) {
    const auto& [kind, backend, v, b] = key;
    if (kind.find("Normals") != std::string::npos || kind.find("Tangents") != std::string::npos ||
        backend.rfind("opencl", 0) != 0) {
      continue;
    }
    auto kernel = kernel_rates_.find(key);
    const double kernel_rate = kernel == kernel_rates_.end() ? 0.0 : kernel->second;
    // A quantized row's kernel reads its integers (quantized_rest.h), not the float stream.
    const RestEncoding rest = StreamOf(kind);
    const double bytes = rest == RestEncoding::kFloat32
                             ? BytesPerVertex(b, false)
                             : StreamedBytesPerVertex(rest, b, kPaperJoints, false);
    // Encoded rows (--encoding): 6 bytes a vertex come back; their kernel time holds the
    // encoder's kernels too: they report no kernel rate (0 below).
    const bool encoded = kind.find("Encoded") != std::string::npos;
    std::string label = kind.rfind("BM_SkinStreams", 0) == 0 ? "  (streams)" : "";
    if (rest != RestEncoding::kFloat32) {
      label += fmt::format("  ({}, {:.0f} B/vertex)", RestEncodingName(rest), bytes);
    }
    if (encoded) label += fmt::format("  ({})", kind.substr(kind.find("Encoded")));
    fmt::print("{:<16} {:>10} {:>3} {:>12.0f} {:>7.0f}% {:>14.0f} {:>7.0f}%{}\n", backend, v, b,
               rate / 1e6, 100 * rate * (encoded ? 6 : 12) / d2h, kernel_rate / 1e6,
               100 * kernel_rate * bytes / copy, label);
  }
}

void PaperTablesReporter::PrintQuantizedShares() const {
  bool header = false;
  for (const auto& [key, rate] : rates_) {
    const auto& [kind, backend, vertices, bones] = key;
    const RestEncoding rest = StreamOf(kind);
    if (rest == RestEncoding::kFloat32) continue;
    const bool tangents = kind.rfind("BM_SkinTangents", 0) == 0;
    const bool normals = tangents || kind.rfind("BM_SkinNormals", 0) == 0;
    if (!header) {
      fmt::print(
          "\nQuantized rest stream (medians when repeated; memory bound: BM_MemoryBandwidth's "
          "best, {:.1f} GB/s; float rows at the simd float stream's bytes):\n{:<34} {:>16} {:>10} "
          "{:>3} {:>10} {:>6} {:>7} {:>9}\n",
          bandwidth_bytes_per_second_ / 1e9, "row", "backend", "vertices", "B", "M vert/s", "B/vtx",
          "% bound", "x float");
      header = true;
    }
    const auto row = [&](const std::string& name, RestEncoding encoding, double vertices_per_s,
                         double over_float) {
      const double bytes = StreamedBytesPerVertex(encoding, bones, kPaperJoints, normals, tangents);
      const double share = bandwidth_bytes_per_second_ > 0
                               ? 100 * vertices_per_s * bytes / bandwidth_bytes_per_second_
                               : 0;
      fmt::print("{:<34} {:>16} {:>10} {:>3} {:>10.1f} {:>6.0f} {:>6.0f}% {:>9}\n", name, backend,
                 vertices, bones, vertices_per_s / 1e6, bytes, share,
                 over_float > 0 ? fmt::format("{:.2f}x", over_float) : "");
    };
    const std::string float_kind =
        tangents ? "BM_SkinTangents" : (normals ? "BM_SkinNormals" : "BM_Skin");
    const auto float_rate = rates_.find({float_kind, backend, vertices, bones});
    if (float_rate != rates_.end() && rest == RestEncoding::kQuantized16) {
      row(float_kind, RestEncoding::kFloat32, float_rate->second, 0);
    }
    row(kind, rest, rate, float_rate != rates_.end() ? rate / float_rate->second : 0);
  }
}

}  // namespace skinserve::bench
