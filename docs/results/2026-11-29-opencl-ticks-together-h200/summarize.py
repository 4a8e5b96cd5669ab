#!/usr/bin/env python3
"""summary.csv from raw/*.json: per build and round, the fixed load's server CPU per
character, its p99 and the checked ticks' mismatches, and the capacity search's result."""
import csv, json, os, sys
here = os.path.dirname(os.path.abspath(__file__))
raw = os.path.join(here, "raw")
rows = []
for rnd in (1, 2, 3):
    for build in ("base", "new"):
        fixed = json.load(open(os.path.join(raw, f"fixed-{build}-{rnd}.json")))["results"][0]
        cap = json.load(open(os.path.join(raw, f"cap-{build}-{rnd}.json")))
        held = cap.get("capacity", {}).get("characters") if isinstance(cap.get("capacity"), dict) else None
        if held is None:
            for line in open(os.path.join(raw, f"cap-{build}-{rnd}.txt")):
                if line.startswith("capacity:"):
                    held = int(line.split()[1])
        rows.append([rnd, "main (82e74cb)" if build == "base" else "together",
                     f"{fixed['server_cpu_us_per_character']:.1f}",
                     f"{fixed['latency_ms']['p99']:.2f}" if 'latency_ms' in fixed else "",
                     fixed["checked"], fixed["mismatches"], held])
w = csv.writer(sys.stdout)
w.writerow(["round", "server", "server CPU us/character (3 streams of ticks)", "p99 ms",
            "ticks checked", "mismatches", "characters held at 60 ticks/s"])
w.writerows(rows)
