#!/usr/bin/env python3
"""kernel-share.csv from the three runs' JSON: each row's kernel-only share of the device
copy bound (kernel_bytes_per_second over BM_DeviceMemoryCopy's bytes_per_second, medians),
local palette (`opencl`) against global (`opencl-global`), per tile count."""
import csv, json, sys
rows = []
for tiles in (1, 2, 4):
    d = json.load(open(f"palette-tiles{tiles}.json"))
    med = {b["run_name"]: b for b in d["benchmarks"] if b.get("aggregate_name") == "median"}
    bound = med["BM_DeviceMemoryCopy/real_time"]["bytes_per_second"]
    for row in ("BM_Skin", "BM_SkinNormals"):
        for v in (400000, 1600000):
            for b in (1, 4, 8):
                local = med.get(f"{row}/opencl/{v}/{b}/real_time")
                glob = med.get(f"{row}/opencl-global/{v}/{b}/real_time")
                if not local or not glob:
                    continue
                share = lambda r: 100 * r["kernel_bytes_per_second"] / bound
                rows.append([tiles, row, v, b, f"{local['kernel_vertices_per_second'] / 1e6:.0f}",
                             f"{glob['kernel_vertices_per_second'] / 1e6:.0f}",
                             f"{share(local):.0f}%", f"{share(glob):.0f}%",
                             f"{local['kernel_vertices_per_second'] / glob['kernel_vertices_per_second']:.2f}x"])
w = csv.writer(sys.stdout, lineterminator="\n")
w.writerow(["tiles", "row", "vertices", "B", "local M v/s", "global M v/s", "local % copy bound",
            "global % copy bound", "local / global"])
w.writerows(rows)
