#!/usr/bin/env python3
"""kernel-us.csv: each run's median kernel time (us) and share of the device copy bound at
1.6M vertices x 4 influences, from raw/<gpu>/*.json (the same process's BM_DeviceMemoryCopy)."""
import csv, json, pathlib

RUNS = [  # gpu, name, items per work-group, copies, tiles
    ("h200", "c1-k1-a", 64, 1, 1), ("h200", "c1-k8-a", 64, 8, 1), ("h200", "c1-k2-a", 64, 2, 1),
    ("h200", "c1-k4-a", 64, 4, 1), ("h200", "c1-k1-t4", 64, 1, 4), ("h200", "c1-k8-t4", 64, 8, 4),
    ("h200", "c1-k1-b", 64, 1, 4), ("h200", "c1-k8-b", 64, 8, 4),
    ("h100", "g64-k1", 64, 1, 1), ("h100", "g256-k1", 256, 1, 1), ("h100", "g256-k8", 256, 8, 1),
    ("h100", "g256-k4", 256, 4, 1), ("h100", "g64-k1-b", 64, 1, 1), ("h100", "g256-k8-b", 256, 8, 1),
    ("h100", "g256-k1-b", 256, 1, 1),
]
ROWS = ["BM_Skin", "BM_SkinNormals", "BM_SkinDualQuaternion", "BM_SkinQuantized",
        "BM_SkinQuantizedWeights8"]
here = pathlib.Path(__file__).parent
with open(here / "kernel-us.csv", "w", newline="") as f:
    w = csv.writer(f)
    w.writerow(["gpu", "run", "items per group", "copies", "tiles", "row", "kernel us",
                "% copy bound"])
    for gpu, name, group, copies, tiles in RUNS:
        benchmarks = json.load(open(here / "raw" / gpu / f"{name}.json"))["benchmarks"]
        med = {b["run_name"]: b for b in benchmarks if b.get("aggregate_name") == "median"}
        bound = med["BM_DeviceMemoryCopy/real_time"]["bytes_per_second"]
        for row in ROWS:
            b = med[f"{row}/opencl/1600000/4/real_time"]
            w.writerow([gpu, name, group, copies, tiles, row, f"{b['kernel_ns'] / 1000:.1f}",
                        f"{100 * b['kernel_bytes_per_second'] / bound:.0f}%"])

# summary.csv: per GPU and shape, the kernel's us of each run of that shape (a-b when two).
SHORT = {"BM_Skin": "float", "BM_SkinQuantized": "quantized16",
         "BM_SkinQuantizedWeights8": "quantized8-weights", "BM_SkinDualQuaternion": "dual quaternion"}
shapes = {}
with open(here / "kernel-us.csv") as f:
    for r in csv.DictReader(f):
        if r["row"] not in SHORT:
            continue
        key = (r["gpu"], r["items per group"], r["copies"], r["tiles"])
        shapes.setdefault(key, {}).setdefault(r["row"], []).append(float(r["kernel us"]))
with open(here / "summary.csv", "w", newline="") as f:
    w = csv.writer(f)
    w.writerow(["gpu", "items per group", "copies", "tiles"] + [f"{SHORT[r]} us" for r in SHORT])
    for key, rows in shapes.items():
        cells = []
        for row in SHORT:
            v = sorted(rows[row])
            cells.append(f"{v[0]:.1f}" if len(v) == 1 else f"{v[0]:.1f}-{v[-1]:.1f}")
        w.writerow([key[0].upper(), *key[1:], *cells])
