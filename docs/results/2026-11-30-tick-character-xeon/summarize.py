#!/usr/bin/env python3
"""The CSVs of this folder from raw/ (tar xJf raw.tar.xz first): bench.csv, the medians of
skinserve-bench's tick rows per call and setting (us a character); service.csv, the service's
ticks per round and rest encoding (call 3); service-streaming.csv, the service at a fixed load
with plain and streaming stores (call 1); service-prefetch.csv, the service with and without the
prefetch trial (call 6); service-cores.csv, the service on three pairs of cores (call 7)."""
import collections, csv, glob, json, os, re, statistics, sys

here = os.path.dirname(os.path.abspath(__file__))
raw = os.path.join(here, 'raw')


def rows_of(path):
    for b in json.load(open(path))['benchmarks']:
        yield b['name'].split('/')[0], b['seconds_per_character'] * 1e6


def bench():
    # call: (question, file pattern -> (setting, characters, slots, cores))
    def call1(name):  # r1-plain-320-twoA
        _, stores, n, slot = name.split('-')
        setting = 'streaming stores (trial)' if stores == 'nt' else 'plain stores'
        return setting, n, 1, '1' if slot == 'one' else '2 (cores 4, 6)'

    def call2(name):  # r1-pf256-320-one
        _, cfg, n, slot = name.split('-')
        setting = {'pf0': 'plain', 'pf256': 'prefetch 256 vertices ahead (trial)',
                   'pf1024': 'prefetch 1024 vertices ahead (trial)',
                   'thp': 'heap in huge pages (glibc.malloc.hugetlb=1)'}[cfg]
        return setting, n, 1, '1' if slot == 'one' else '2 (cores 4, 6)'

    def call4(name):  # r1-0+1-a, r1-0
        parts = name.split('-')
        cores = parts[1]
        return 'plain', 64, 1, (f'2 (cores {cores.replace("+", ", ")})' if '+' in cores
                                else f'1 (core {cores})')

    def call5(name):  # r1-s12-0+1-a, r1-s1-2
        parts = name.split('-')
        slots = int(parts[1][1:])
        cores = parts[2]
        return 'plain', 64, slots, ('2 (cores 0, 1)' if '+' in cores else '1 (core 2)')

    calls = [(1, 'meshes beyond the L3; streaming stores', call1),
             (2, 'software prefetch; huge pages', call2),
             (4, 'which cores', call4),
             (5, 'outputs rotating as the regions do', call5)]
    table = collections.defaultdict(list)
    for number, question, parse in calls:
        for path in sorted(glob.glob(os.path.join(raw, f'call{number}', 'r*.json'))):
            setting, n, slots, cores = parse(os.path.basename(path)[:-5])
            for row, us in rows_of(path):
                table[(number, question, row, setting, int(n), slots, cores)].append(us)
    with open(os.path.join(here, 'bench.csv'), 'w', newline='') as f:
        w = csv.writer(f)
        w.writerow(['call', 'question', 'row (25k x 2, simd)', 'setting', 'characters a tick',
                    'outputs in turn', 'cores busy', 'runs', 'median us a character', 'range'])
        for key in sorted(table):
            v = table[key]
            w.writerow(list(key) + [len(v), f'{statistics.median(v):.1f}',
                                    f'{min(v):.1f}-{max(v):.1f}'])


def held(path):
    return int(re.search(r'^capacity: (\d+) characters', open(path).read(), re.M).group(1))


def fixed_load(call, name):
    """A fixed-load run's server CPU and compute a character (us), its CPU / compute, and
    how many characters it checked and found wrong."""
    r = json.load(open(os.path.join(raw, call, name)))['results'][0]
    compute = r['server_metrics']['compute_seconds_sum'] / r['server_frames'] * 1e6
    return (f"{r['server_cpu_us_per_character']:.1f}", f'{compute:.1f}',
            f"{r['server_cpu_over_compute']:.2f}", r['checked'], r['mismatches'])


def service():
    with open(os.path.join(here, 'service.csv'), 'w', newline='') as f:
        w = csv.writer(f)
        w.writerow(['round', 'meshes stored', 'tick characters held at 60 ticks/s',
                    'single characters held over gRPC', 'server CPU us a character (5 streams)',
                    'compute us a character (5 streams)', 'CPU / compute', 'checked',
                    'mismatches'])
        for rnd in (1, 2, 3):
            single = held(os.path.join(raw, 'call3', f'single-cap-grpc-{rnd}.txt'))
            for rest in ('float32', 'quantized16'):
                cpu, compute, ratio, checked, wrong = fixed_load(
                    'call3', f'tick-fixed-{rest}-{rnd}.json')
                w.writerow([rnd, rest, held(os.path.join(raw, 'call3', f'tick-cap-{rest}-{rnd}.txt')),
                            single, cpu, compute, ratio, checked, wrong])
    with open(os.path.join(here, 'service-streaming.csv'), 'w', newline='') as f:
        w = csv.writer(f)
        w.writerow(['round', 'stores', 'server CPU us a character', 'compute us a character',
                    'CPU / compute'])
        for rnd in (1, 2):
            for tag, label in (('plain', 'plain'), ('nt', 'streaming (trial)')):
                line = open(os.path.join(raw, 'call1', f'svc-r{rnd}-{tag}', 'summary.txt')).read()
                cpu = float(re.search(r'cpu us/char\s+([\d.]+)', line).group(1))
                compute = float(re.search(r'compute us\s+([\d.]+)', line).group(1)) / 64
                ratio = re.search(r'cpu/compute\s+([\d.]+)', line).group(1)
                w.writerow([rnd, label, f'{cpu:.1f}', f'{compute:.1f}', ratio])


def service_prefetch():
    with open(os.path.join(here, 'service-prefetch.csv'), 'w', newline='') as f:
        w = csv.writer(f)
        w.writerow(['round', 'loop', 'server CPU us a character (5 streams)',
                    'compute us a character (5 streams)', 'characters held (rounds 1-2)',
                    'checked', 'mismatches'])
        for rnd in (1, 2, 3, 4):
            for pf, label in (('0', 'main'), ('1024', 'prefetch 1024 vertices ahead (trial)')):
                cpu, compute, _, checked, wrong = fixed_load('call6', f'fixed-pf{pf}-{rnd}.json')
                cap = os.path.join(raw, 'call6', f'cap-pf{pf}-{rnd}.txt')
                w.writerow([rnd, label, cpu, compute, held(cap) if os.path.exists(cap) else '',
                            checked, wrong])


def service_cores():
    with open(os.path.join(here, 'service-cores.csv'), 'w', newline='') as f:
        w = csv.writer(f)
        w.writerow(['round', 'server cores', 'server CPU us a character (5 streams)',
                    'compute us a character (5 streams)', 'characters held (one search)',
                    'checked', 'mismatches'])
        for rnd in (1, 2):
            for cores in ('0+1', '2+3', '4+6'):
                cpu, compute, _, checked, wrong = fixed_load('call7', f'fixed-{cores}-{rnd}.json')
                cap = held(os.path.join(raw, 'call7', f'cap-{cores}.txt')) if rnd == 1 else ''
                w.writerow([rnd, cores.replace('+', ', '), cpu, compute, cap, checked, wrong])


if not os.path.isdir(raw):
    sys.exit('summarize.py: unpack raw.tar.xz first (tar xJf raw.tar.xz)')
bench()
service()
service_prefetch()
service_cores()
