#!/usr/bin/env python3
"""medians.csv from bench.json: each row's median M vertices/s, bytes per vertex streamed,
share of the memory bound (BM_MemoryBandwidth's best repetition, as skinserve-bench prints
it) and speed over the float row of the same backend and size."""
import csv, json, sys
d = json.load(open("bench.json"))
med = {b["run_name"]: b for b in d["benchmarks"] if b.get("aggregate_name") == "median"}
bound = max(b["bytes_per_second"] for b in d["benchmarks"]
            if b["run_name"].startswith("BM_MemoryBandwidth") and b.get("run_type") == "iteration")
w = csv.writer(sys.stdout, lineterminator="\n")
w.writerow(["row", "backend", "vertices", "B", "M vertices/s", "bytes/vertex", "% memory bound",
            "x float"])
for backend in ("simd", "simd-openmp"):
    for v in (400000, 1600000):
        base = med[f"BM_Skin/{backend}/{v}/4/real_time"]["vertices_per_second"]
        for row in ("BM_Skin", "BM_SkinQuantized", "BM_SkinQuantizedWeights8"):
            r = med[f"{row}/{backend}/{v}/4/real_time"]
            rate, bpv = r["vertices_per_second"], r["bytes_per_vertex"]
            if row == "BM_Skin":  # the simd float stream, as skinserve-bench's table counts it:
                bpv = 12 + 4 + 4 * 3 + 12  # positions, 8-bit joints (77), B - 1 weights, out
            w.writerow([row, backend, v, 4, f"{rate / 1e6:.0f}", f"{bpv:g}",
                        f"{100 * rate * bpv / bound:.0f}%",
                        "" if row == "BM_Skin" else f"{rate / base:.2f}"])
print(f"# memory bound {bound / 1e9:.1f} GB/s", file=sys.stderr)
