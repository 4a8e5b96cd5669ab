#!/usr/bin/env python3
"""A results folder's summary.csv from its runs of scripts/gpu-region-test.sh, main's server
and another alternated: runs/<base|new>-<round>/console.txt (each run's console). Per round,
server and case: the GPU region's rate and its ratios to the same frames read back over shared
memory and skinned by simd-openmp on the server's 2 cores.
  scripts/gpu-region-summary.py FOLDER ROUNDS BASE_LABEL NEW_LABEL > FOLDER/summary.csv"""
import csv, os, re, sys

folder, rounds, base_label, new_label = sys.argv[1], int(sys.argv[2]), sys.argv[3], sys.argv[4]
case_of = {("1600000 x 4", "float32", False): "1.6M x 4", ("25000 x 2", "float32", False): "25k x 2",
           ("25000 x 2", "float16", False): "25k x 2 float16", ("25000 x 2", "snorm16", False): "25k x 2 snorm16",
           ("25000 x 2", "float32", True): "ticks of 64 x 25k x 2"}
rows = []
for rnd in range(1, rounds + 1):
    for build in ("base", "new"):
        text = open(os.path.join(folder, "runs", f"{build}-{rnd}", "console.txt")).read()
        text = text[text.index("== summary"):]
        for m in re.finditer(r"^gpu-region: (\S+ x \d+): ([\d.]+) frames/s(?: = ([\d.]+) characters/s in ticks of 64)? \(\d+ frames, window 2, (\w+)\)\n"
                             r"shm-readback: .*gpu-region / shm = ([\d.]+)x\n"
                             r"simd-openmp-shm: .*gpu-region / simd-openmp = ([\d.]+)x", text, re.M):
            size, fps, chars, enc, vs_shm, vs_simd = m.groups()
            rate = f"{float(chars):.0f} characters/s" if chars else f"{float(fps):.0f} frames/s"
            rows.append([rnd, base_label if build == "base" else new_label,
                         case_of[(size, enc, chars is not None)], rate, vs_shm, vs_simd])
w = csv.writer(sys.stdout)
w.writerow(["round", "server", "case", "into a GPU region", "/ read back over shm", "/ simd-openmp over shm"])
w.writerows(sorted(rows, key=lambda r: (r[2], r[0], r[1] != base_label)))
