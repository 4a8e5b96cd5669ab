"""medians.csv from ab/*.json (trial binary, SKINSERVE_QLOOP variants) and bench.json (kept build).

Per run: medians of wall and CPU time per frame (ms) of BM_Skin/simd (float) and the two
quantized rows, and each quantized row's speed over the float row of the same run.
"""
import glob
import json
import os
import statistics

HERE = os.path.dirname(os.path.abspath(__file__))
VARIANT = {"0": "chunk decode (before)", "1": "positions in registers (kept)",
           "2": "all in registers with scalar weights", "3": "weights per vertex by permutes"}


def medians(path):
    rows = {}
    for b in json.load(open(path))["benchmarks"]:
        if b.get("run_type") != "iteration":
            continue
        rows.setdefault(b["run_name"].split("/")[0], []).append((b["real_time"] / 1e3, b["cpu_time"] / 1e3))
    return {n: (statistics.median(w for w, _ in r), statistics.median(c for _, c in r)) for n, r in rows.items()}


def line(build, variant, run, m):
    fw, fc = m["BM_Skin"]
    cells = [build, variant, run, f"{fw:.2f}", f"{fc:.2f}"]
    for row in ("BM_SkinQuantized", "BM_SkinQuantizedWeights8"):
        w, c = m[row]
        cells += [f"{w:.2f}", f"{c:.2f}", f"{fw / w:.2f}", f"{fc / c:.2f}"]
    return ",".join(cells)


print("build,variant,run,float wall ms,float cpu ms,q16 wall ms,q16 cpu ms,q16 x float wall,q16 x float cpu,"
      "w8 wall ms,w8 cpu ms,w8 x float wall,w8 x float cpu")
for path in sorted(glob.glob(os.path.join(HERE, "ab", "v*.json"))):
    name = os.path.basename(path)[1:-5]
    print(line("trial", VARIANT[name[0]], name[1:], medians(path)))
print(line("kept", VARIANT["1"], "final", medians(os.path.join(HERE, "bench.json"))))
