#!/usr/bin/env python3
"""The CSVs of this folder from raw/ (tar xJf raw.tar.xz first): bench.csv, skinserve-bench's
tick rows with tick launches off and on (calls 1 and 4: rounds 1-2 and 3, medians of 3
repetitions a run); service.csv,
opencl ticks over shared memory through main's server and this build's, alternated (call 2);
regions.csv, ticks into GPU regions with 1, 4 and 8 Vulkan clients at once (call 3);
paced.csv, K clients' ticks at 60 ticks/s into GPU regions (calls 5 and 6)."""
import csv, glob, json, os, re

here = os.path.dirname(os.path.abspath(__file__))
raw = os.path.join(here, 'raw')


def bench():
    with open(os.path.join(here, 'bench.csv'), 'w', newline='') as f:
        w = csv.writer(f)
        w.writerow(['row (opencl, 25k x 2, 64 meshes)', 'output', 'round', 'tick launches',
                    'ms a tick', 'process CPU ms a tick', 'us a character'])
        rows = []
        for path in glob.glob(os.path.join(raw, 'call[14]', 'bench-r*-tl*.json')):
            m = re.search(r'bench-r(\d)-tl(\d)\.json', path)
            for b in json.load(open(path))['benchmarks']:
                if b.get('aggregate_name') != 'median':
                    continue
                name = b['name'].split('/')[0]
                output = {'BM_SkinTickDeviceOutput': 'device memory, positions',
                          'BM_SkinTickTogether': 'host memory, positions',
                          'BM_SkinTickTogetherNormals': 'host memory, positions and normals'}[name]
                rows.append([name, output, int(m[1]), 'on' if m[2] == '1' else 'off',
                             f"{b['real_time']:.3f}", f"{b['cpu_time']:.3f}",
                             f"{b['seconds_per_character'] * 1e6:.2f}"])
        w.writerows(sorted(rows))


def service():
    with open(os.path.join(here, 'service.csv'), 'w', newline='') as f:
        w = csv.writer(f)
        w.writerow(['round', 'server', 'fixed load: server CPU us a character', 'cpu/compute',
                    'p99 ms', 'characters checked', 'mismatches', 'characters held at 60 ticks/s'])
        for r in (1, 2):
            for build, label in (('base', 'main (eadb4e4)'), ('new', 'tick launches')):
                fixed = json.load(open(os.path.join(raw, 'call2', f'fixed-{build}-{r}.json')))
                x = fixed['results'][0]
                cap = open(os.path.join(raw, 'call2', f'cap-{build}-{r}.txt')).read()
                held = re.search(r'^capacity: (\d+) characters', cap, re.M)[1]
                w.writerow([r, label, f"{x['server_cpu_us_per_character']:.1f}",
                            f"{x['server_cpu_over_compute']:.2f}", f"{x['latency_ms']['p99']:.2f}",
                            x['checked'] * 64, x['mismatches'], held])
        for call, name in ((2, 'simd-openmp-cap'), (3, 'cap-simd-openmp')):
            cap = open(os.path.join(raw, f'call{call}', f'{name}.txt')).read()
            held = re.search(r'^capacity: (\d+) characters', cap, re.M)[1]
            w.writerow([f'call {call}', 'this build, simd-openmp', '', '', '', '', '', held])


def regions():
    with open(os.path.join(here, 'regions.csv'), 'w', newline='') as f:
        w = csv.writer(f)
        w.writerow(['clients (window 2 each)', 'ticks each', 'ticks/s (sum)', 'characters/s (sum)',
                    'server CPU s over the run (uploads included)', 'wall s'])
        text = open(os.path.join(raw, 'call3', 'region-cpu.txt')).read()
        for m in re.finditer(r'^region-(\w+): (\d+) clients x (\d+) ticks of 64: server cpu (\d+) '
                             r'ticks \((\d+)/s\) over ([\d.]+) s', text, re.M):
            name, n, frames, cpu, hz, wall = m.groups()
            ticks = chars = 0.0
            for path in glob.glob(os.path.join(raw, 'call3', f'region-{name}-*.txt')):
                g = re.search(r'^gpu-region: .*: ([\d.]+) frames/s = (\d+) characters/s',
                              open(path).read(), re.M)
                ticks += float(g[1])
                chars += float(g[2])
            w.writerow([n, frames, f'{ticks:.0f}', f'{chars:.0f}', f'{int(cpu) / int(hz):.2f}',
                        wall])


def paced():
    with open(os.path.join(here, 'paced.csv'), 'w', newline='') as f:
        w = csv.writer(f)
        w.writerow(['call', 'clients at 60 ticks/s', 'characters', 'worst p99 ms', 'median p99 ms',
                    'answers later than a period', 'clients failed', 'holds',
                    'server CPU s over the step (uploads included)', 'wall s'])
        for call in (5, 6):
            text = open(os.path.join(raw, f'call{call}', 'paced.txt')).read()
            for m in re.finditer(r'^(\d+) clients \((\d+) characters\): worst p99 ([\d.]+) ms, '
                                 r'median p99 ([\d.]+) ms, (\d+) late, (\d+) failed: (holds|does not '
                                 r'hold); server cpu (\d+) ticks \((\d+)/s\) over ([\d.]+) s', text,
                                 re.M):
                k, chars, worst, median, late, failed, holds, cpu, hz, wall = m.groups()
                w.writerow([call, k, chars, worst, median, late, failed,
                            'yes' if holds == 'holds' else 'no', f'{int(cpu) / int(hz):.2f}', wall])


bench()
service()
regions()
paced()
