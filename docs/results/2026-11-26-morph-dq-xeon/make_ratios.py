#!/usr/bin/env python3
"""Medians and ratios of this folder's raw runs: morph-ratios.csv and dq-ratios.csv."""
import csv, json, os, re
here = os.path.dirname(os.path.abspath(__file__))

def morph():
    rows = {}
    for b in json.load(open(os.path.join(here, "morph-simd.json")))["benchmarks"]:
        if b.get("aggregate_name") == "median":
            rows[b["run_name"]] = b["real_time"]
    out = [["row", "outputs", "active targets", "median us", "ratio to skin-only"]]
    for base, outputs in (("BM_Skin", "positions"), ("BM_SkinNormals", "positions+normals")):
        ref = rows[f"{base}/simd/25000/4/real_time"]
        morph = base.replace("BM_Skin", "BM_SkinMorph")
        for name, active in ((f"{base}/simd/25000/4", "skin only"),
                             (f"{morph}/simd/25000/4/active:0", "0"),
                             (f"{morph}/simd/25000/4/active:4", "4")):
            t = rows[name + "/real_time"]
            out.append([name, outputs, active, f"{t:.1f}", f"{t / ref:.2f}"])
    return out

def dq():
    med = {}
    for f, threads in (("dq-16threads.txt", 16), ("dq-2threads.txt", 2)):
        for line in open(os.path.join(here, f)):
            m = re.match(r"(BM_\S+)/real_time_median\s+([\d.]+) us", line)  # wall time
            if m:
                med[(threads, m.group(1))] = float(m.group(2))
    out = [["backend", "outputs", "linear us", "dual quaternions us", "ratio"]]
    for threads, backend, label in ((16, "simd-openmp", "simd-openmp (16 threads)"),
                                    (2, "simd-openmp", "simd-openmp (2 threads)"),
                                    (2, "simd", "simd (1 thread)")):
        for outputs, lin, dqn in (("positions", "BM_Skin", "BM_SkinDualQuaternion"),
                                  ("positions+normals", "BM_SkinNormals",
                                   "BM_SkinNormalsDualQuaternion")):
            a = med[(threads, f"{lin}/{backend}/400000/4")]
            d = med[(threads, f"{dqn}/{backend}/400000/4")]
            out.append([label, outputs, f"{a:.0f}", f"{d:.0f}", f"{d / a:.2f}"])
    return out


for name, rows in (("morph-ratios.csv", morph()), ("dq-ratios.csv", dq())):
    with open(os.path.join(here, name), "w", newline="") as f:
        csv.writer(f, lineterminator="\n").writerows(rows)
