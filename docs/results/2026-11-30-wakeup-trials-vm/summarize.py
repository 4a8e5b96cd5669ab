#!/usr/bin/env python3
"""summary.csv of this folder from raw/ (tar xJf raw.tar.xz first): each trial's
scripts/frame-cost.sh runs (command.txt says which setting each folder ran with)."""
import csv, glob, json, os

here = os.path.dirname(os.path.abspath(__file__))
raw = os.path.join(here, 'raw')
# folder of raw/ -> (trial, load, what the setting was)
TRIALS = {
    'client-spin': ('client spins for its answer (SPIN_US)', 'single'),
    'sndbuf-streamskin-ticks': ('net.core.wmem_default (bytes)', 'tick'),
    'sndbuf-frame-socket': ('net.core.wmem_default (bytes)', None),
    'server-window': ('server HTTP/2 window (WIN_BYTES)', 'tick'),
}

rows = []
for trial, (setting_name, load) in TRIALS.items():
    for run in sorted(glob.glob(os.path.join(raw, trial, '*'))):
        name = os.path.basename(run)
        kind = load or ('tick' if name.startswith('t') else 'single')
        setting = name.lstrip('bst').split('-')[0]
        per = 64 if kind == 'tick' else 1
        for summary in csv.DictReader(open(os.path.join(run, 'summary.csv'))):
            plane = summary['plane']
            r = json.load(open(os.path.join(run, f'{plane}.json')))['results'][0]
            rows.append((trial, setting_name, setting, name, kind, plane,
                         summary['server CPU us/character'],
                         f"{r['server_ms']['compute'] * 1000 / per:.1f}", summary['CPU / compute'],
                         summary['voluntary switches/frame'], f"{r['latency_ms']['p50']:.2f}",
                         f"{r['latency_ms']['p99']:.2f}", r['dropped']))
with open(os.path.join(here, 'summary.csv'), 'w', newline='') as f:
    w = csv.writer(f)
    w.writerow(['trial', 'setting', 'value', 'run', 'load', 'plane', 'server CPU us/character',
                'compute us/character', 'CPU / compute', 'voluntary switches/frame', 'p50 ms',
                'p99 ms', 'dropped'])
    w.writerows(rows)
