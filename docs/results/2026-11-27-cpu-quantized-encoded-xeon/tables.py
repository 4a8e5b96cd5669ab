"""quantized.csv (quantized over float simd-openmp / simd, each process's own float row) and
encoded.csv (simd writing the encoding itself against float32 then the host encoder) from the
runs' Google Benchmark JSON; medians."""
import csv, glob, json, os

here = os.path.dirname(os.path.abspath(__file__))


def medians(path):
    out = {}
    for b in json.load(open(path))['benchmarks']:
        if b.get('aggregate_name') == 'median':
            out[b['name'].split('/real_time')[0].split('/process_time')[0]] = b
    return out


rows = []
for path in sorted(glob.glob(os.path.join(here, 'q*.json'))):
    m = medians(path)
    run = os.path.basename(path)[:-5]
    rate = lambda prefix: next(v['items_per_second'] for k, v in m.items() if k.startswith(prefix))
    f, q16, q8 = rate('BM_Skin/'), rate('BM_SkinQuantized/'), rate('BM_SkinQuantizedWeights8/')
    backend, vertices = next(k for k in m if k.startswith('BM_Skin/')).split('/')[1:3]
    binary = '3b02344 (chunk decode)' if '3b02344' in run else 'main (positions in registers)'
    rows.append([run, binary, backend, vertices, f'{f / 1e6:.0f}', f'{q16 / 1e6:.0f}',
                 f'{q16 / f:.2f}x', f'{q8 / 1e6:.0f}', f'{q8 / f:.2f}x'])
with open(os.path.join(here, 'quantized.csv'), 'w', newline='') as out:
    w = csv.writer(out)
    w.writerow(['run', 'simd loop', 'backend', 'vertices', 'float M v/s', 'quantized16 M v/s',
                'quantized16 x float', 'quantized8-weights M v/s', 'quantized8-weights x float'])
    w.writerows(rows)

m = medians(os.path.join(here, 'encoded.json'))
with open(os.path.join(here, 'encoded.csv'), 'w', newline='') as out:
    w = csv.writer(out)
    w.writerow(['row', 'backend', 'vertices', 'host-encoded us', 'direct us', 'host / direct (wall)',
                'host / direct (process CPU)'])
    for name in sorted(m):
        if 'HostEncoded' not in name:
            continue
        direct = m.get(name.replace('HostEncoded', 'Encoded'))
        if direct is None:
            continue
        row, backend, vertices = name.replace('HostEncoded', 'Encoded').split('/')[:3]
        us = lambda b: b['real_time'] / (1e3 if b['time_unit'] == 'ns' else 1)
        w.writerow([row, backend, vertices, f'{us(m[name]):.1f}', f'{us(direct):.1f}',
                    f"{m[name]['real_time'] / direct['real_time']:.2f}x",
                    f"{m[name]['cpu_time'] / direct['cpu_time']:.2f}x"])
