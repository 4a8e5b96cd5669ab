#!/usr/bin/env python3
"""medians.csv from bench.json: per row and backend, the median of the 9 interleaved
repetitions' vertices/s, bytes per vertex streamed (the bench's counter), the share of
BM_MemoryBandwidth's best repetition, and each quantized row over its float row."""
import csv
import json
import statistics

rows, bandwidth = {}, 0.0
for b in json.load(open("bench.json"))["benchmarks"]:
    if b.get("run_type") != "iteration":
        continue
    name = b["run_name"].removesuffix("/real_time")
    if name == "BM_MemoryBandwidth":
        bandwidth = max(bandwidth, b["bytes_per_second"])
        continue
    rows.setdefault(name, []).append(b)


def rate(name):
    return statistics.median(b["vertices_per_second"] for b in rows[name])


with open("medians.csv", "w", newline="") as out:
    w = csv.writer(out)
    w.writerow(["row", "backend", "threads", "M vertices/s", "bytes/vertex", "% memory bound",
                "x float"])
    for backend in ("simd", "simd-openmp"):
        for outputs in ("BM_Skin", "BM_SkinNormals"):
            for stream in ("", "Quantized", "QuantizedWeights8"):
                name = f"{outputs}{stream}/{backend}/1600000/4"
                bytes_per_vertex = rows[name][0]["bytes_per_vertex"]
                r = rate(name)
                w.writerow([outputs + stream, backend, 1 if backend == "simd" else 2,
                            f"{r / 1e6:.0f}", f"{bytes_per_vertex:.0f}",
                            f"{100 * r * bytes_per_vertex / bandwidth:.0f}%",
                            f"{r / rate(f'{outputs}/{backend}/1600000/4'):.2f}" if stream else ""])
