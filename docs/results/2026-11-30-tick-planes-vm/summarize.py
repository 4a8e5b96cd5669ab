#!/usr/bin/env python3
"""summary.csv (every run) and medians.csv of this folder from raw/ (tar xJf raw.tar.xz first):
scripts/frame-cost.sh's runs of ticks of 64 over StreamSkin into shared memory (shm) and over
the frame socket (socket), measured from the start (warm-up 0 s) and after 2 s of warm-up,
three rounds."""
import csv, json, os, statistics

here = os.path.dirname(os.path.abspath(__file__))
raw = os.path.join(here, 'raw')


def write(name, header, rows):
    with open(os.path.join(here, name), 'w', newline='') as f:
        w = csv.writer(f)
        w.writerow(header)
        w.writerows(rows)


runs = []
for rnd in (1, 2, 3):
    for warmup in (0, 2):
        folder = os.path.join(raw, f'r{rnd}-warmup{warmup}')
        switches = {row['plane']: float(row['voluntary switches/frame'])
                    for row in csv.DictReader(open(os.path.join(folder, 'summary.csv')))}
        for plane in ('shm', 'socket'):
            r = json.load(open(os.path.join(folder, f'{plane}.json')))['results'][0]
            compute = r['server_ms']['compute'] * 1000 / 64
            runs.append((rnd, warmup, plane, int(r['server_frames']),
                         f"{r['server_cpu_us_per_character']:.1f}", f'{compute:.1f}',
                         f"{r['server_cpu_over_compute']:.2f}", f'{switches[plane]:.2f}',
                         f"{r['latency_ms']['p99']:.1f}", r['dropped']))
write('summary.csv', ['round', 'warm-up s', 'plane', 'characters', 'server CPU us/character',
                      'compute us/character', 'CPU / compute', 'voluntary switches/character',
                      'p99 ms', 'dropped ticks'], runs)
medians = []
for warmup in (0, 2):
    for plane in ('shm', 'socket'):
        mine = [r for r in runs if r[1] == warmup and r[2] == plane]
        ratios = sorted(float(r[6]) for r in mine)
        cpu = [float(r[4]) for r in mine]
        p99 = [float(r[8]) for r in mine]
        medians.append((warmup, plane, len(mine), f'{statistics.median(ratios):.2f}',
                        f'{ratios[0]:.2f}-{ratios[-1]:.2f}', f'{statistics.median(cpu):.1f}',
                        f'{min(p99):.1f}-{max(p99):.1f}', sum(r[9] for r in mine)))
write('medians.csv', ['warm-up s', 'plane', 'runs', 'CPU / compute (median)', 'range',
                      'server CPU us/character (median)', 'p99 ms (range)',
                      'dropped ticks (all runs)'], medians)
