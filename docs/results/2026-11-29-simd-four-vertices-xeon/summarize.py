#!/usr/bin/env python3
"""Each row's median per round for base, new (kept) and the in-register-normals trial, the
medians of the rounds, and base / new round by round."""
import glob, json, lzma, os, re, statistics
here = os.path.dirname(os.path.abspath(__file__))
builds = {'base': 'base', 'kept': 'new', 'trial': 'trial'}  # file name -> column
rows = {}
for f in sorted(glob.glob(os.path.join(here, 'raw', 'bench-*-[0-9].json.xz'))):
    build, rnd = re.match(r'bench-(\w+)-(\d)\.json\.xz', os.path.basename(f)).groups()
    for b in json.load(lzma.open(f))['benchmarks']:
        if b.get('aggregate_name') == 'median':
            name = b['run_name'].replace('/real_time', '')
            rows.setdefault(name, {}).setdefault(builds[build], {})[int(rnd)] = b['real_time']
print('benchmark,base_us_median,new_us_median,trial_in_register_us_median,speedup_min,speedup_max')
for name, r in rows.items():
    med = {k: statistics.median(v.values()) for k, v in r.items()}
    ratios = [r['base'][i] / r['new'][i] for i in sorted(r['base'])]
    print(f"{name},{med['base']:.1f},{med['new']:.1f},{med['trial']:.1f},{min(ratios):.2f},{max(ratios):.2f}")
