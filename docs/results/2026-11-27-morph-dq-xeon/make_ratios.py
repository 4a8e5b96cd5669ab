#!/usr/bin/env python3
"""Medians and ratios of this folder's raw runs: morph-ratios.csv, dq-ratios.csv and
tangents-gpu.csv. Each run's ratio is taken within the run (its rows were interleaved at
random), then the runs are listed side by side."""
import csv, glob, json, os, statistics
here = os.path.dirname(os.path.abspath(__file__))


def medians(path):
    rows = {}
    for b in json.load(open(path))["benchmarks"]:
        if b.get("run_type") == "iteration":
            rows.setdefault(b["run_name"].replace("/real_time", ""), []).append(b["real_time"])
    return {k: statistics.median(v) for k, v in rows.items()}


def runs(prefix):
    for path in sorted(glob.glob(os.path.join(here, prefix + "-*.json"))):
        _, build, rep = os.path.basename(path)[:-5].split("-")
        yield build, rep, medians(path)


def morph():
    out = [["build", "run", "skin-only us", "active:0 us", "active:4 us", "ratio 0", "ratio 4"]]
    for build, rep, m in runs("morph"):
        s = m["BM_Skin/simd/25000/4"]
        a0 = m["BM_SkinMorph/simd/25000/4/active:0"]
        a4 = m["BM_SkinMorph/simd/25000/4/active:4"]
        out.append([build, rep, f"{s:.1f}", f"{a0:.1f}", f"{a4:.1f}", f"{a0 / s:.2f}",
                    f"{a4 / s:.2f}"])
    return out


def dq():
    out = [["build", "run", "outputs", "linear us", "dual quaternions us", "ratio"]]
    for build, rep, m in runs("dq16"):
        for outputs, lin, dqn in (("positions", "BM_Skin", "BM_SkinDualQuaternion"),
                                  ("positions+normals", "BM_SkinNormals",
                                   "BM_SkinNormalsDualQuaternion")):
            a = m[f"{lin}/simd-openmp/400000/4"]
            d = m[f"{dqn}/simd-openmp/400000/4"]
            out.append([build, rep, outputs, f"{a:.0f}", f"{d:.0f}", f"{d / a:.2f}"])
    return out


def tangents():
    out = [["backend", "vertices", "method", "normals us", "tangents us", "ratio",
            "normals kernel us", "tangents kernel us"]]
    rows, kernel = {}, {}
    for b in json.load(open(os.path.join(here, "tangents-gpu.json")))["benchmarks"]:
        if b.get("aggregate_name") == "median":
            name = b["run_name"].replace("/real_time", "")
            rows[name] = b["real_time"]
            kernel[name] = b.get("kernel_ns", 0) / 1000
    for backend in ("opencl", "simd-openmp"):
        for v in (400000, 1600000):
            for method, suffix in (("linear", ""), ("dual-quaternion", "DualQuaternion")):
                n = f"BM_SkinNormals{suffix}/{backend}/{v}/4"
                t = f"BM_SkinTangents{suffix}/{backend}/{v}/4"
                out.append([backend, v, method, f"{rows[n]:.0f}", f"{rows[t]:.0f}",
                            f"{rows[t] / rows[n]:.2f}", f"{kernel[n]:.1f}", f"{kernel[t]:.1f}"])
    return out


for name, rows in (("morph-ratios.csv", morph()), ("dq-ratios.csv", dq()),
                   ("tangents-gpu.csv", tangents())):
    with open(os.path.join(here, name), "w", newline="") as f:
        csv.writer(f, lineterminator="\n").writerows(rows)
