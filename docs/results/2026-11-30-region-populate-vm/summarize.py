#!/usr/bin/env python3
"""runs.csv and medians.csv of this folder from raw/ (tar xJf raw.tar.xz first): the first
6 s of ticks of 64 into shared memory on the VM, main's server against the same server
with its region mappings populated at registration (MAP_POPULATE), three rounds; then
client-runs.csv: that server against a load client whose regions are also allocated and mapped
in at creation (posix_fallocate + MAP_POPULATE, trial), three rounds (raw/client-trial)."""
import csv, json, os, statistics

here = os.path.dirname(os.path.abspath(__file__))
raw = os.path.join(here, 'raw')
BUILDS = [('main', 'main (86304a0)'), ('pop', 'regions populated at registration')]


def write(name, header, rows):
    with open(os.path.join(here, name), 'w', newline='') as f:
        w = csv.writer(f)
        w.writerow(header)
        w.writerows(rows)


HEADER = ['round', 'build', 'ticks answered', 'ticks dropped', 'ticks late', 'p50 ms', 'p99 ms',
          'max ms', 'server CPU us/character', 'CPU / compute']


def rows(folder, builds):
    out = []
    for rnd in (1, 2, 3):
        for key, label in builds:
            r = json.load(open(os.path.join(folder, f'r{rnd}-{key}', 'shm.json')))['results'][0]
            lat = r['latency_ms']
            out.append((rnd, label, r['frames'], r['dropped'], r['late'], f"{lat['p50']:.2f}",
                        f"{lat['p99']:.1f}", f"{lat['max']:.1f}",
                        f"{r['server_cpu_us_per_character']:.1f}",
                        f"{r['server_cpu_over_compute']:.2f}"))
    return out


runs = rows(raw, BUILDS)
write('runs.csv', HEADER, runs)
write('client-runs.csv', HEADER,
      rows(os.path.join(raw, 'client-trial'),
           [('pop', 'regions populated at registration'),
            ('client', 'and the client\'s allocated and mapped in (trial)')]))
medians = []
for _, label in BUILDS:
    mine = [r for r in runs if r[1] == label]
    col = lambda i: [float(r[i]) for r in mine]
    medians.append((label, len(mine), f'{statistics.median(col(2)):.0f}',
                    f'{statistics.median(col(3)):.0f}', f'{min(col(3)):.0f}-{max(col(3)):.0f}',
                    f'{statistics.median(col(6)):.1f}', f'{min(col(6)):.1f}-{max(col(6)):.1f}',
                    f'{statistics.median(col(8)):.1f}'))
write('medians.csv', ['server', 'runs', 'ticks answered (median of 720)', 'ticks dropped (median)',
                      'dropped (range)', 'p99 ms (median)', 'p99 (range)',
                      'server CPU us/character (median)'], medians)
