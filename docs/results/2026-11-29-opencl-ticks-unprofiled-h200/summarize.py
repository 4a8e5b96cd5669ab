#!/usr/bin/env python3
"""summary.csv from raw/: per round and server, opencl ticks of 64 x 25k x 2 on the H200 with
the server on 2 Xeon cores: characters held at 60 ticks/s, and at the fixed load (3 streams
of ticks) server CPU per character, p99 latency and the checked ticks' mismatches."""
import json, os, re
here = os.path.join(os.path.dirname(os.path.abspath(__file__)), 'raw')
print('round,server,characters held,server CPU us per character,p99 ms,mismatches')
for rnd in (1, 2):
    for build, label in (('base', 'main (200f0f1): profiled'), ('new', 'unprofiled')):
        held = re.search(r'^capacity: (\d+) characters',
                         open(os.path.join(here, f'cap-{build}-{rnd}.txt')).read(), re.M).group(1)
        fixed = json.load(open(os.path.join(here, f'fixed-{build}-{rnd}.json')))['results'][0]
        print(f"{rnd},{label},{held},{fixed['server_cpu_us_per_character']:.1f},"
              f"{fixed['latency_ms']['p99']:.2f},{fixed['mismatches']}")
