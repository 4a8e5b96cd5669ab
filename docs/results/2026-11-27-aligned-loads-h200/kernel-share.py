"""kernel-share.csv from the runs' Google Benchmark JSON: per row the median kernel time per
frame (profiling events, summed over the frame's chunks), the kernel's vertices per second, its
bytes over BM_DeviceMemoryCopy's (read + write) of the same run, and the frame rate through PCIe."""
import csv, glob, json, os, re

here = os.path.dirname(os.path.abspath(__file__))
rows = []
for path in sorted(glob.glob(os.path.join(here, 'call-*', '*.json'))):
    call = os.path.basename(os.path.dirname(path))
    run = os.path.basename(path)[:-5]
    kernels = 'main 5793ccf' if run.startswith('before') else ('call 1' if run.startswith('now-') else 'kept')
    chunks = re.search(r'-c(\d)', run).group(1)
    tiles = (re.search(r'-t(\d)', run) or re.search(r'(x)', 'x')).group(1).replace('x', '1')
    order = 'sorted' if 'sorted' in run else 'shuffled'
    data = json.load(open(path))
    medians = [b for b in data['benchmarks'] if b.get('aggregate_name') == 'median']
    copy = next(b['bytes_per_second'] for b in medians if b['name'].startswith('BM_DeviceMemoryCopy'))
    for b in medians:
        if 'kernel_ns' not in b:
            continue
        name, backend, vertices, bones = b['name'].split('/')[:4]
        rows.append([call, run, kernels, chunks, tiles, order, name, backend, vertices, bones,
                     f"{b['kernel_ns'] / 1e3:.1f}", f"{b['kernel_vertices_per_second'] / 1e6:.0f}",
                     f"{100 * b['kernel_bytes_per_second'] / copy:.0f}%",
                     f"{b['items_per_second'] / 1e6:.0f}"])
with open(os.path.join(here, 'kernel-share.csv'), 'w', newline='') as f:
    w = csv.writer(f)
    w.writerow(['call', 'run', 'kernels', 'chunks', 'tiles', 'order', 'row', 'backend', 'vertices',
                'B', 'kernel us', 'kernel M v/s', '% copy bound', 'frame M v/s'])
    w.writerows(rows)

# summary.csv: call 2 (one warm machine), 1.6M x 4: main's kernels against the kept ones.
picks = [('before-c1-t1', 'main 5793ccf: 1 chunk'), ('now2-c1-t1', 'kept: 1 chunk'),
         ('now2-c1-t1-b', 'kept: 1 chunk (again)'), ('now2-c2-t1', 'kept: 2 chunks (default)'),
         ('now2-c1-t1-sorted', 'kept: 1 chunk in sorted order')]
with open(os.path.join(here, 'summary.csv'), 'w', newline='') as f:
    w = csv.writer(f)
    w.writerow(['kernels', 'row', 'kernel us', '% copy bound'])
    for run, label in picks:
        for r in rows:
            if (r[0], r[1], r[7], r[9]) == ('call-2', run, 'opencl', '4') and r[6] in (
                    'BM_Skin', 'BM_SkinNormals', 'BM_SkinQuantized'):
                w.writerow([label, r[6], r[10], r[12]])
