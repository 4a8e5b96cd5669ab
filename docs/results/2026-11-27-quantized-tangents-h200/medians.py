#!/usr/bin/env python3
"""gpu.csv and xeon.csv from the raw Google Benchmark JSON (medians of the 5 repetitions).

gpu.csv: per run (1 chunk: the frame's kernel alone; default: 2 chunks, overlapped) and row,
the frame's time and rate, the kernel's time and its share of the device copy bound (best
BM_DeviceMemoryCopy of the same run, bytes at the row's bytes/vertex), and each quantized
row over its float row. xeon.csv: simd-openmp on 16 threads against BM_MemoryBandwidth's best.
"""
import csv
import json
import statistics


def runs(path):
    rows, bounds = {}, {}
    for b in json.load(open(path))["benchmarks"]:
        if b.get("run_type") != "iteration":
            continue
        name = b["run_name"].removesuffix("/real_time")
        if name in ("BM_DeviceMemoryCopy", "BM_MemoryBandwidth"):
            bounds[name] = max(bounds.get(name, 0), b["bytes_per_second"])
            continue
        if "/" not in name or name.startswith("BM_Pcie"):
            continue
        rows.setdefault(name, []).append(b)
    return rows, bounds


def med(bs, key):
    return statistics.median(b[key] for b in bs)


def float_of(name):
    kind, rest = name.split("/", 1)
    for q in ("QuantizedWeights8", "Quantized"):
        kind = kind.replace(q, "")
    return f"{kind}/{rest}"


with open("gpu.csv", "w", newline="") as out:
    w = csv.writer(out)
    w.writerow(["chunks", "row", "bytes/vertex", "frame us", "M vertices/s", "kernel us",
                "% copy bound", "x float (frame)", "x float (kernel)"])
    for chunks, path in (("1", "raw/gpu-c1.json"), ("default", "raw/gpu-default.json")):
        rows, bounds = runs(path)
        copy = bounds["BM_DeviceMemoryCopy"]
        for name, bs in rows.items():
            kernel_us = med(bs, "kernel_ns") / 1e3
            bytes_per_vertex = bs[0]["bytes_per_vertex"]
            vertices = int(name.split("/")[2])
            share = 100 * vertices * bytes_per_vertex / (kernel_us * 1e-6) / copy
            f = rows.get(float_of(name))
            quantized = f is not None and f is not bs
            w.writerow([chunks, name, f"{bytes_per_vertex:.0f}", f"{med(bs, 'real_time'):.0f}",
                        f"{med(bs, 'vertices_per_second') / 1e6:.0f}", f"{kernel_us:.1f}",
                        f"{share:.0f}%",
                        f"{med(bs, 'vertices_per_second') / med(f, 'vertices_per_second'):.2f}"
                        if quantized else "",
                        f"{med(f, 'kernel_ns') / med(bs, 'kernel_ns'):.2f}" if quantized else ""])

with open("xeon.csv", "w", newline="") as out:
    w = csv.writer(out)
    w.writerow(["row", "bytes/vertex", "M vertices/s", "% memory bound", "x float"])
    rows, bounds = runs("raw/xeon.json")
    bandwidth = bounds["BM_MemoryBandwidth"]
    for name, bs in rows.items():
        rate = med(bs, "vertices_per_second")
        bytes_per_vertex = bs[0]["bytes_per_vertex"]
        f = rows.get(float_of(name))
        quantized = f is not None and f is not bs
        w.writerow([name, f"{bytes_per_vertex:.0f}", f"{rate / 1e6:.0f}",
                    f"{100 * rate * bytes_per_vertex / bandwidth:.0f}%",
                    f"{rate / med(f, 'vertices_per_second'):.2f}" if quantized else ""])
