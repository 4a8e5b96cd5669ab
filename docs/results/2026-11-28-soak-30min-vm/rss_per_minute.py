#!/usr/bin/env python3
"""From samples.csv (scripts/soak.sh's 5 s samples): rss-per-minute.csv, the server's RSS at
the last sample of each minute, and rss-slope.csv, the least-squares slope of RSS over time
after the first 5 minutes, overall and per window."""
import csv
import pathlib

here = pathlib.Path(__file__).parent
rows = [tuple(map(int, r)) for r in list(csv.reader(open(here / "samples.csv")))[1:]]


def slope(points):
    n = len(points)
    mx = sum(x for x, _ in points) / n
    my = sum(y for _, y in points) / n
    return sum((x - mx) * (y - my) for x, y in points) / sum((x - mx) ** 2 for x, _ in points)


per_minute = {}
for seconds, rss_kib, _, _ in rows:
    per_minute[seconds // 60] = rss_kib / 1024
with open(here / "rss-per-minute.csv", "w") as out:
    out.write("minute,rss_mib\n")
    for minute, mib in sorted(per_minute.items()):
        out.write(f"{minute},{mib:.1f}\n")
points = [(s / 60, r / 1024) for s, r, _, _ in rows]
with open(here / "rss-slope.csv", "w") as out:
    out.write("minutes,slope_mib_per_minute\n")
    for first, last in [(5, 30), (5, 15), (15, 25), (20, 30)]:
        window = [(x, y) for x, y in points if first <= x < last]
        out.write(f"{first}-{last},{slope(window):.2f}\n")
