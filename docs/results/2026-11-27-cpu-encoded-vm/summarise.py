# Pairs each BM_Skin[Normals]Encoded<E>/... row with its HostEncoded<E> twin: medians of the
# 9 interleaved repetitions, wall and CPU time (us per frame), direct / host.
import json, statistics, sys
runs = json.load(open(sys.argv[1]))["benchmarks"]
rows = {}
for b in runs:
    if b.get("run_type") != "iteration":
        continue
    rows.setdefault(b["run_name"], []).append((b["real_time"], b["cpu_time"]))
print(f"{'row (direct)':58} {'host wall':>10} {'direct wall':>11} {'ratio':>6} {'host cpu':>9} {'direct cpu':>10} {'ratio':>6}")
for name in sorted(rows):
    if "HostEncoded" in name or "Encoded" not in name:
        continue
    host = rows.get(name.replace("Encoded", "HostEncoded"))
    if host is None:
        continue
    d, h = rows[name], host
    hw, dw = statistics.median(x[0] for x in h), statistics.median(x[0] for x in d)
    hc, dc = statistics.median(x[1] for x in h), statistics.median(x[1] for x in d)
    print(f"{name:58} {hw:10.1f} {dw:11.1f} {dw/hw:6.3f} {hc:9.1f} {dc:10.1f} {dc/hc:6.3f}")
