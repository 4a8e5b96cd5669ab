#!/usr/bin/env python3
"""The CSVs of this folder from raw/ (tar xJf raw.tar.xz first): bench-neighbours.csv, the
bench's tick row on core 0 with the other cores idle, spinning or serving (call 1);
service-load-cores.csv, the service with its load client on 14 cores or 2 (call 1);
service-streams.csv, the service with 1, 2 or 5 streams and 1 or 2 compute threads (call 2);
bench-slots.csv, the bench's tick row into one output or 10 in turn, alone or two at once
(call 2); profile.csv, the profiled service and bench side by side (call 5); tick-gap.csv, the
bench's row back to back and with 11 ms between ticks, beside the service's one stream (call 6);
gap-kind.csv, that gap slept, spun, or slept then spun its last 1 ms (call 7, trial build);
huge-pages.csv, the row with and without glibc's heap in transparent huge pages (call 8)."""
import csv, glob, json, os, re, statistics

here = os.path.dirname(os.path.abspath(__file__))
raw = os.path.join(here, 'raw')


def bench_us(path):
    """us a character of each repetition of a BM_SkinTick json (64 characters a tick)."""
    runs = [b for b in json.load(open(path))['benchmarks'] if b.get('run_type') == 'iteration']
    scale = {'ms': 1000.0, 'us': 1.0, 'ns': 0.001}
    return [b['real_time'] * scale[b['time_unit']] / 64 for b in runs]


def service(folder):
    """(server CPU us a character, compute us a character, checked, mismatches) of a
    frame-cost.sh folder (one shm plane, ticks of 64)."""
    row = json.load(open(os.path.join(folder, 'shm.json')))['results'][0]
    return (row['server_cpu_us_per_character'], 1000 * row['server_ms']['compute'] / 64,
            row.get('checked', ''), row.get('mismatches', ''))


def services(call, pattern):
    """(the name's match of `pattern`, service(folder)) for each frame-cost.sh folder of a call
    whose name `pattern` matches (the logs beside them are files, not folders)."""
    for folder in sorted(glob.glob(os.path.join(raw, call, '*'))):
        m = re.fullmatch(pattern, os.path.basename(folder))
        if m and os.path.isdir(folder):
            yield m, service(folder)


def fmt(values):
    return ', '.join(f'{v:.1f}' for v in values)


def write(name, header, rows):
    with open(os.path.join(here, name), 'w', newline='') as f:
        w = csv.writer(f)
        w.writerow(header)
        w.writerows(rows)


def call1():
    names = {'idle': 'idle', 'spin': '14 shell loops spinning on cores 2-15',
             'service': 'a server on cores 2,3 serving 5 streams of ticks (load on 4-15)'}
    rows = []
    for path in sorted(glob.glob(os.path.join(raw, 'call1', 'a-r*-*.json'))):
        m = re.match(r'a-r(\d)-(\w+)\.json', os.path.basename(path))
        us = bench_us(path)
        rows.append([m.group(1), names[m.group(2)], fmt(us), f'{statistics.median(us):.1f}'])
    write('bench-neighbours.csv', ['round', 'the other cores', 'repetitions us a character',
                                   'median'], rows)
    rows = []
    for m, (cpu, compute, checked, bad) in services('call1', r'b-r(\d)-load(.*)'):
        rows.append([m.group(1), m.group(2), f'{cpu:.1f}', f'{compute:.1f}',
                     f'{cpu / compute:.2f}', checked, bad])
    write('service-load-cores.csv', ['round', 'load client cores', 'server CPU us a character',
                                     'compute us a character', 'CPU / compute', 'checked',
                                     'mismatches'], rows)


def call2():
    rows = []
    for m, (cpu, compute, checked, bad) in services('call2', r'a-r(\d)-s(\d)-t(\d)'):
        rows.append([m.group(1), m.group(2), m.group(3), int(m.group(2)) * 64,
                     f'{cpu:.1f}', f'{compute:.1f}', checked, bad])
    write('service-streams.csv', ['round', 'streams', 'compute threads', 'characters a tick period',
                                  'server CPU us a character', 'compute us a character',
                                  'checked', 'mismatches'], rows)
    kinds = {'one-slots1': ('1 (core 0)', 1), 'one-slots10': ('1 (core 0)', 10),
             'two0-slots10': ('2 at once: this on core 0', 10),
             'two1-slots10': ('2 at once: this on core 1', 10)}
    rows = []
    for path in sorted(glob.glob(os.path.join(raw, 'call2', 'b-r*.json'))):
        m = re.match(r'b-r(\d)-(.*)\.json', os.path.basename(path))
        cores, slots = kinds[m.group(2)]
        us = bench_us(path)
        rows.append([m.group(1), cores, slots, fmt(us), f'{statistics.median(us):.1f}'])
    write('bench-slots.csv', ['round', 'benches', 'outputs in turn', 'repetitions us a character',
                              'median'], rows)


def call5():
    d = os.path.join(raw, 'call5')

    def share(report, pattern):
        for line in open(os.path.join(d, report)):
            m = re.match(r'\s+([\d.]+)%\s+\[[.k]\]\s+(.*)', line)
            if m and re.search(pattern, m.group(2)):
                return float(m.group(1))
        return 0.0

    def kernel(report):
        total = 0.0
        for line in open(os.path.join(d, report)):
            m = re.match(r'\s+([\d.]+)%\s+\[k\]', line)
            if m:
                total += float(m.group(1))
        return total

    bench = re.search(r'([\d.]+)us', open(os.path.join(d, 'bench.txt')).read().split('BM_SkinTick')[-1])
    load = open(os.path.join(d, 'load.txt')).read().splitlines()
    row = next(l for l in load if l.startswith('simd+shm+tick64')).split()
    compute_ms = float(row[14])  # the compute column, ms a tick
    stat = open(os.path.join(d, 'server-stat.txt')).read().split()
    faults = int(stat[stat.index('minflt', 6) + 1]) - int(stat[2])
    rows = [
        ['the service (5 streams of ticks, server on cores 0,1)', f'{compute_ms * 1000 / 64:.1f}',
         f"{share('server-report.txt', 'SkinRange'):.1f}", f"{share('server-report.txt', 'ValidatePalette'):.2f}",
         f"{share('server-report.txt', 'ColumnPalette'):.2f}", f"{kernel('server-report.txt'):.1f}",
         faults],
        ['skinserve-bench BM_SkinTick (core 0, after the service)', f'{float(bench.group(1)):.1f}',
         f"{share('bench-report.txt', 'SkinRange'):.1f}", f"{share('bench-report.txt', 'ValidatePalette'):.2f}",
         f"{share('bench-report.txt', 'ColumnPalette'):.2f}", f"{kernel('bench-report.txt'):.1f}", ''],
    ]
    write('profile.csv', ['process', 'us a character (compute / bench row)', 'loop % of samples',
                          'ValidatePalette %', 'ColumnPalette %', 'kernel % (listed rows)',
                          'minor faults in the 6 s'], rows)


def call6():
    rows = []
    for path in sorted(glob.glob(os.path.join(raw, 'call6', 'r*-gap*-slots*.json'))):
        m = re.match(r'r(\d)-gap(\d+)-slots(\d)\.json', os.path.basename(path))
        us = bench_us(path)
        gap = 'back to back' if m.group(2) == '0' else f'{int(m.group(2)) // 1000} ms after each tick'
        rows.append([m.group(1), 'skinserve-bench BM_SkinTick (core 0)', gap, m.group(3), fmt(us),
                     f'{statistics.median(us):.1f}'])
    for m, (_, compute, _, _) in services('call6', r'svc-r(\d)'):
        rows.append([m.group(1), 'the service, 1 stream of ticks (--threads 1)',
                     'a 60 ticks/s period', 2, f'{compute:.1f}', f'{compute:.1f}'])
    write('tick-gap.csv', ['round', 'what', 'ticks', 'outputs in turn',
                           'us a character (repetitions; the service: compute)', 'median'], rows)


def call7():
    names = {'none': 'back to back', 'sleep': 'sleeping 11 ms',
             'spin': 'spinning 11 ms (trial)', 'sleep-then-spin': 'sleeping 10 ms, spinning 1 (trial)'}
    rows = []
    for path in sorted(glob.glob(os.path.join(raw, 'call7', 'r*.json'))):
        m = re.match(r'r(\d)-(.*)\.json', os.path.basename(path))
        us = bench_us(path)
        rows.append([m.group(1), names[m.group(2)], fmt(us), f'{statistics.median(us):.1f}'])
    write('gap-kind.csv', ['round', 'between ticks', 'repetitions us a character', 'median'], rows)


def call8():
    rows = []
    for path in sorted(glob.glob(os.path.join(raw, 'call8', 'r*.json'))):
        m = re.match(r'r(\d)-(4k|thp)-(none|gap)\.json', os.path.basename(path))
        us = bench_us(path)
        smaps = open(path + '.smaps').read()
        huge = re.search(r'AnonHugePages:\s+(\d+)', smaps)
        rss = re.search(r'Rss:\s+(\d+)', smaps)
        rows.append([m.group(1),
                     'huge pages (glibc.malloc.hugetlb=1)' if m.group(2) == 'thp' else '4 KiB pages',
                     'back to back' if m.group(3) == 'none' else '11 ms after each tick',
                     f'{int(huge.group(1)) >> 10} of {int(rss.group(1)) >> 10}' if huge else '',
                     fmt(us), f'{statistics.median(us):.1f}'])
    write('huge-pages.csv', ['round', 'heap', 'ticks', 'MiB in huge pages (of resident, at 6 s)',
                             'repetitions us a character', 'median'], rows)


if __name__ == '__main__':
    call1()
    call2()
    call5()
    call6()
    call7()
    call8()
