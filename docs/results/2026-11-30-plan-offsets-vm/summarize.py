#!/usr/bin/env python3
"""summary.csv (every run), medians.csv and plan-builds.csv of this folder from raw/ (tar xJf
raw.tar.xz first): run.sh's frame-cost runs of main (base) and this change (new), alternated,
three rounds; plan-builds.sh's counts for each build."""
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
    for build in ('base', 'new'):
        for load, planes in (('single', ('grpc', 'shm', 'socket')), ('tick', ('shm', 'socket'))):
            folder = os.path.join(raw, f'{load}-{build}-{rnd}')
            per = 64 if load == 'tick' else 1
            for plane in planes:
                r = json.load(open(os.path.join(folder, f'{plane}.json')))['results'][0]
                compute = r['server_ms']['compute'] * 1000 / per
                runs.append((rnd, build, load, plane, f"{r['server_cpu_us_per_character']:.1f}",
                             f'{compute:.1f}', f"{r['server_cpu_over_compute']:.2f}",
                             f"{r['latency_ms']['p99']:.1f}", r['dropped'], sum(r['errors'].values())))
write('summary.csv', ['round', 'build', 'load', 'plane', 'server CPU us/character',
                      'compute us/character', 'CPU / compute', 'p99 ms', 'dropped', 'errors'], runs)
medians = []
for load, planes in (('single', ('grpc', 'shm', 'socket')), ('tick', ('shm', 'socket'))):
    for plane in planes:
        for build in ('base', 'new'):
            mine = [r for r in runs if r[1] == build and r[2] == load and r[3] == plane]
            cpu = sorted(float(r[4]) for r in mine)
            ratio = sorted(float(r[6]) for r in mine)
            medians.append((load, plane, build, len(mine), f'{statistics.median(cpu):.1f}',
                            f'{cpu[0]:.1f}-{cpu[-1]:.1f}', f'{statistics.median(ratio):.2f}',
                            f'{ratio[0]:.2f}-{ratio[-1]:.2f}', sum(int(r[9]) for r in mine)))
write('medians.csv', ['load', 'plane', 'build', 'runs', 'server CPU us/character (median)',
                      'range', 'CPU / compute (median)', 'range', 'errors (all runs)'], medians)
builds = []
for build in ('base', 'new'):
    for row in csv.DictReader(open(os.path.join(raw, f'plan-builds-{build}.csv'))):
        builds.append((build, row['load'], row['plane'], row['offered per second'],
                       row['plan builds per second']))
write('plan-builds.csv', ['build', 'load', 'plane', 'characters offered per second',
                          'plan builds per second'], builds)
