#!/usr/bin/env python3
"""ratios.csv: per run of bench-last, float and quantized M vertices/s (medians of 5) and
quantized / float in the same process, from raw/last-*.json."""
import csv, json, pathlib

here = pathlib.Path(__file__).parent
with open(here / "ratios.csv", "w", newline="") as f:
    w = csv.writer(f)
    w.writerow(["run", "backend", "vertices", "float M v/s", "quantized16 M v/s",
                "quantized16 x float", "quantized8-weights M v/s", "quantized8-weights x float"])
    for path in sorted((here / "raw").glob("last-*.json")):
        med = {b["run_name"]: b for b in json.load(open(path))["benchmarks"]
               if b.get("aggregate_name") == "median"}
        for backend in ["simd", "simd-openmp"]:
            for v in ["1600000", "10000000"]:
                rate = lambda row: med[f"{row}/{backend}/{v}/4/real_time"]["items_per_second"] / 1e6
                fl, q, q8 = rate("BM_Skin"), rate("BM_SkinQuantized"), rate("BM_SkinQuantizedWeights8")
                w.writerow([path.stem, backend, v, f"{fl:.0f}", f"{q:.0f}", f"{q / fl:.2f}x",
                            f"{q8:.0f}", f"{q8 / fl:.2f}x"])
