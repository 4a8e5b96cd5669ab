#!/usr/bin/env python3
"""bench.csv (skinserve-bench medians, opencl 1.6M x 4) and service.csv (frames/s through the
service) from this folder's raw output."""
import json, os
here = os.path.dirname(os.path.abspath(__file__))


def bench():
    rows = [["build", "row", "median us", "kernel us", "transfer us", "bytes read back/vertex"]]
    for build in ("before", "now"):
        for b in json.load(open(os.path.join(here, f"gpu-{build}.json")))["benchmarks"]:
            if b.get("aggregate_name") != "median" or not b["name"].startswith("BM_Skin"):
                continue
            name = b["name"].replace("/real_time", "").replace("_median", "")
            name = name.replace("/opencl/1600000/4", "")
            back = b.get("read_back_bytes_per_vertex")
            if back is None:
                back = 24 if "Normals" in name else 12
            if "Streams" in name and "Encoded" in name:
                back = back / 4  # the counter sums the 4 threads' values
            rows.append([build, name, f"{b['real_time']:.0f}", f"{b.get('kernel_ns', 0) / 1e3:.0f}",
                         f"{b.get('transfer_ns', 0) / 1e3:.0f}", f"{back:g}"])
    for name in ("BM_PcieDeviceToHost", "BM_DeviceMemoryCopy"):
        for b in json.load(open(os.path.join(here, "gpu-now.json")))["benchmarks"]:
            if b.get("aggregate_name") == "median" and b["name"].startswith(name):
                rows.append(["now", f"{name} ({b['bytes_per_second'] / 1e9:.0f} GB/s)",
                             f"{b['real_time']:.0f}", "", "", ""])
    return rows


def service():
    rows = [["call", "checks", "server", "rest", "answer", "plane", "frames/s", "p50 ms",
             "x before float32 in its plane and call"]]
    for call, prefix, checks in (("1", "service", "every 50th"), ("2", "service2", "none")):
        base = {}
        runs = []
        for server, rest, answer in (("before", "float32", "float32"), ("before", "float32", "snorm16"),
                                     ("now", "float32", "float32"), ("now", "float32", "snorm16"),
                                     ("now", "quantized16", "snorm16"), ("now", "quantized16", "float16")):
            path = os.path.join(here, f"{prefix}-{server}-{rest}-{answer}.json")
            if not os.path.exists(path):
                continue
            for r in json.load(open(path))["results"]:
                plane = r["data_plane"]
                if (server, rest, answer) == ("before", "float32", "float32"):
                    base[plane] = r["frames_per_second"]
                runs.append((server, rest, answer, plane, r))
        for server, rest, answer, plane, r in runs:
            rows.append([call, checks, server, rest, answer, plane, f"{r['frames_per_second']:.0f}",
                         f"{r['latency_ms']['p50']:.1f}" if isinstance(r.get('latency_ms'), dict) else "",
                         f"{r['frames_per_second'] / base[plane]:.2f}"])
    return rows


for name, rows in (("bench.csv", bench()), ("service.csv", service())):
    with open(os.path.join(here, name), "w") as f:
        for row in rows:
            f.write(",".join(str(c) for c in row) + "\n")
