#!/usr/bin/env python3
"""ticks.csv from ticks/*.json: per round and server (main at 200f0f1, or the four-vertex
kernel), ticks of 64 x 25k x 2 on the Xeon's 2 server cores: characters held at 60 ticks/s
(the capacity search) and, at the fixed load (3 streams of ticks at 60/s), server CPU and
compute per character."""
import json, os, re
here = os.path.join(os.path.dirname(os.path.abspath(__file__)), 'ticks')
print('round,server,characters held,server CPU us per character,compute us per character,checked,mismatches')
for rnd in (1, 2, 3):
    for build, label in (('base', 'main (200f0f1)'), ('new', 'four vertices')):
        cap = open(os.path.join(here, f'tick-cap-{build}-{rnd}.txt')).read()
        fixed = json.load(open(os.path.join(here, f'tick-fixed-{build}-{rnd}.json')))['results'][0]
        held = re.search(r'^capacity: (\d+) characters', cap, re.M).group(1)
        m = fixed['server_metrics']
        compute = m['compute_seconds_sum'] / fixed['server_frames'] * 1e6
        print(f"{rnd},{label},{held},{fixed['server_cpu_us_per_character']:.1f},{compute:.1f},"
              f"{fixed['checked']},{fixed['mismatches']}")
