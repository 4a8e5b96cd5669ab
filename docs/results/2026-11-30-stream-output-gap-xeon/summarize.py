#!/usr/bin/env python3
"""runs.csv and medians.csv of this folder from raw/ (tar xJf raw.tar.xz first): the bench's
64-mesh tick rows (float32 and quantized16 meshes) with 11 ms between ticks, on core 0, with
the trial build's four ways of writing the output, three rounds alternated (call 1)."""
import csv, json, os, statistics

here = os.path.dirname(os.path.abspath(__file__))
raw = os.path.join(here, 'raw', 'call1')
MODES = [('direct', 'plain stores (as main)'),
         ('stream512', 'streaming stores from a 512-vertex L1 chunk'),
         ('stream128', 'streaming stores from a 128-vertex L1 chunk'),
         ('copy512', 'plain copy from a 512-vertex L1 chunk')]


def rows_of(path):
    """(row, us a character) of each BM_SkinTick row of a bench json."""
    for b in json.load(open(path))['benchmarks']:
        mesh = 'quantized16' if 'Quantized' in b['name'] else 'float32'
        yield mesh, b['seconds_per_character'] * 1e6


def write(name, header, rows):
    with open(os.path.join(here, name), 'w', newline='') as f:
        w = csv.writer(f)
        w.writerow(header)
        w.writerows(rows)


runs = []
for r in (1, 2, 3):
    for mode, label in MODES:
        for mesh, us in rows_of(os.path.join(raw, f'r{r}-{mode}.json')):
            runs.append((r, label, mesh, round(us, 1)))
write('runs.csv', ['round', 'output written with', 'meshes', 'us a character'], runs)
medians = []
for mesh in ('float32', 'quantized16'):
    for _, label in MODES:
        values = [us for _, l, m, us in runs if l == label and m == mesh]
        medians.append((mesh, label, len(values), f'{statistics.median(values):.1f}',
                        f'{min(values):.1f}-{max(values):.1f}'))
write('medians.csv', ['meshes', 'output written with', 'runs', 'median us a character', 'range'],
      medians)
