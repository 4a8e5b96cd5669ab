#!/usr/bin/env python3
"""Prints name, base medians (us) round by round, new medians, and new/base speed-up ranges."""
import glob, json, lzma, os, re, sys
here = os.path.dirname(os.path.abspath(__file__))
rows = {}
for f in sorted(glob.glob(os.path.join(here, 'raw', '*-[0-9].json.xz'))):
    build, rnd = re.match(r'(\w+)-(\d)\.json\.xz', os.path.basename(f)).groups()
    for b in json.load(lzma.open(f))['benchmarks']:
        if b.get('aggregate_name') != 'median':
            continue
        name = b['run_name'].replace('/real_time', '')
        rows.setdefault(name, {}).setdefault(build, {})[int(rnd)] = b['real_time']
print('benchmark,base_us_r1,base_us_r2,base_us_r3,new_us_r1,new_us_r2,new_us_r3,speedup_min,speedup_max')
for name, r in rows.items():
    base = [r.get('base', {}).get(i) for i in (1, 2, 3)]
    new = [r.get('new', {}).get(i) for i in (1, 2, 3)]
    ratios = [b / n for b, n in zip(base, new) if b and n]
    fmt = lambda xs: ','.join('' if x is None else f'{x:.1f}' for x in xs)
    print(f"{name},{fmt(base)},{fmt(new)},{min(ratios):.2f},{max(ratios):.2f}" if ratios else name)
