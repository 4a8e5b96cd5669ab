# DQ/linear ratios per run from the JSON files in this folder: medians of the 7
# repetitions; simd (one thread, pinned): CPU time; simd-openmp (2 threads): wall time.
import collections, glob, json, os, re, statistics, sys
folder = sys.argv[1] if len(sys.argv) > 1 else os.path.dirname(os.path.abspath(__file__))
print("backend,build,run,outputs,time,linear us,dual quaternions us,ratio")
for f in sorted(glob.glob(os.path.join(folder, "*-bench-*.json"))):
    backend, build, run = re.match(r"(simd(?:-openmp)?)-bench-(\w+)-(\d+)\.json", os.path.basename(f)).groups()
    key = "cpu_time" if backend == "simd" else "real_time"
    rows = collections.defaultdict(list)
    for b in json.load(open(f))["benchmarks"]:
        if b.get("run_type") == "iteration":
            rows[b["name"].split("/")[0]].append(b[key])
    for outputs, lin, dq in [("positions", "BM_Skin", "BM_SkinDualQuaternion"),
                             ("positions+normals", "BM_SkinNormals", "BM_SkinNormalsDualQuaternion")]:
        l, d = statistics.median(rows[lin]), statistics.median(rows[dq])
        print(f"{backend},{build},{run},{outputs},{key.split('_')[0]},{l:.0f},{d:.0f},{d / l:.2f}")
