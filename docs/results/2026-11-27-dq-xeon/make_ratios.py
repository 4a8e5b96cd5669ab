#!/usr/bin/env python3
"""dq-ratios.csv: dual quaternions over linear blending at 400k x 4, per run (each run's
rows were interleaved at random, so a ratio is taken within its run), before and now,
simd-openmp on 16 threads and simd on one core."""
import glob, json, os, statistics
here = os.path.dirname(os.path.abspath(__file__))


def medians(path):
    rows = {}
    for b in json.load(open(path))["benchmarks"]:
        if b.get("run_type") == "iteration":
            rows.setdefault(b["run_name"].replace("/real_time", ""), []).append(b["real_time"])
    return {k: statistics.median(v) for k, v in rows.items()}


print("backend,build,run,outputs,linear us,dual quaternions us,ratio")
for prefix, backend in (("dq16", "simd-openmp"), ("dq1", "simd")):
    for build in ("before", "now"):
        for rep in ("1", "2", "3"):
            m = medians(os.path.join(here, f"{prefix}-{build}-{rep}.json"))
            for outputs, lin, dq in (("positions", "BM_Skin", "BM_SkinDualQuaternion"),
                                     ("positions+normals", "BM_SkinNormals",
                                      "BM_SkinNormalsDualQuaternion")):
                a = m[f"{lin}/{backend}/400000/4"]
                d = m[f"{dq}/{backend}/400000/4"]
                print(f"{backend},{build},{rep},{outputs},{a:.0f},{d:.0f},{d / a:.2f}")
