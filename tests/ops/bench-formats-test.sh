#!/usr/bin/env bash
# skinserve-bench with Google Benchmark's output flags: --benchmark_format=json prints one
# JSON document (with the paper tables asked for, they stay off it), csv prints CSV,
# console prints the paper tables; --benchmark_out writes its own format alongside.
# usage: bench-formats-test.sh SKINSERVE-BENCH WORK-DIR
set -euo pipefail
bench=$1 work=$2
rm -rf "$work" && mkdir -p "$work"
run=("$bench" --backends=serial,sse --vertices=1000 --bones=1 --benchmark_min_time=0.01)
fail() { echo "bench-formats-test: FAILED: $*" >&2; exit 1; }

"${run[@]}" --paper-tables --benchmark_format=json --benchmark_out="$work/out.csv" \
  --benchmark_out_format=csv >"$work/stdout.json" 2>"$work/stderr.txt"
python3 - "$work/stdout.json" <<'PY' || fail "json stdout"
import json, sys
doc = json.load(open(sys.argv[1]))  # the whole of stdout: nothing but the JSON
names = [b["name"] for b in doc["benchmarks"]]
assert any("serial" in n for n in names) and any("sse" in n for n in names), names
print(f"bench-formats-test: json: {len(names)} results")
PY
grep -q "console only" "$work/stderr.txt" || fail "no note that the tables are console-only"
grep -q "^name,iterations" "$work/out.csv" || fail "--benchmark_out csv"

"${run[@]}" --benchmark_format=csv >"$work/stdout.csv" 2>/dev/null
python3 - "$work/stdout.csv" <<'PY' || fail "csv stdout"
import csv, sys
rows = list(csv.DictReader(open(sys.argv[1])))
assert rows and all(r["name"] and float(r["real_time"]) > 0 for r in rows), rows
print(f"bench-formats-test: csv: {len(rows)} rows")
PY

"${run[@]}" --paper-tables --benchmark_repetitions=1 >"$work/stdout.txt" 2>/dev/null
grep -q "serial" "$work/stdout.txt" && grep -qi "speedup" "$work/stdout.txt" ||
  fail "console output without the paper tables"
echo "bench-formats-test: console: tables present"

# --tick=3: a tick's rows (3 distinct meshes a tick), with the time a character took.
"${run[@]}" --tick=3 --quantized --benchmark_filter=Tick --benchmark_format=json \
  >"$work/tick.json" 2>/dev/null
python3 - "$work/tick.json" <<'PY' || fail "tick rows"
import json, sys
rows = {b["name"]: b for b in json.load(open(sys.argv[1]))["benchmarks"]}
for name in ("BM_SkinTick/serial/1000/1/characters:3/real_time",
             "BM_SkinTickNormals/sse/1000/1/characters:3/real_time"):
    assert name in rows, (name, list(rows))
    row = rows[name]
    assert "error_message" not in row, row
    per = row["seconds_per_character"]
    # a tick's time is its three characters'
    assert 0 < per and abs(per * 3 - row["real_time"] * 1e-3) < 0.05 * per * 3, row
print(f"bench-formats-test: tick: {len(rows)} rows")
PY

# --tick-slots=2: the same rows writing two outputs in turn, named so.
"${run[@]}" --tick=3 --tick-slots=2 --benchmark_filter='BM_SkinTick/serial' \
  --benchmark_format=json >"$work/tick-slots.json" 2>/dev/null
python3 - "$work/tick-slots.json" <<'PY' || fail "tick-slots rows"
import json, sys
rows = {b["name"]: b for b in json.load(open(sys.argv[1]))["benchmarks"]}
name = "BM_SkinTick/serial/1000/1/characters:3/slots:2/real_time"
assert list(rows) == [name], list(rows)
assert "error_message" not in rows[name] and rows[name]["seconds_per_character"] > 0, rows[name]
PY
"${run[@]}" --tick=3 --tick-slots=0 >/dev/null 2>"$work/slots-err.txt" &&
  fail "--tick-slots=0 accepted"
grep -q -- "--tick-slots=: at least 1" "$work/slots-err.txt" || fail "--tick-slots=0 unnamed"
"${run[@]}" --tick-slots=2 >/dev/null 2>"$work/slots-err.txt" && fail "--tick-slots without --tick"
grep -q -- "--tick-slots=: only with --tick=N" "$work/slots-err.txt" ||
  fail "--tick-slots without --tick unnamed"
echo "bench-formats-test: tick slots: named, 0 and without --tick refused"

# --tick-gap-us=20000: a 20 ms pause after each tick, named so and left out of the timing (a
# tick of three 1000-vertex characters takes microseconds; with its pause it would be >= 20 ms).
"${run[@]}" --tick=3 --tick-gap-us=20000 --benchmark_filter='BM_SkinTick/serial' \
  --benchmark_min_time=0.0001 --benchmark_format=json >"$work/tick-gap.json" 2>/dev/null
python3 - "$work/tick-gap.json" <<'PY' || fail "tick-gap rows"
import json, sys
rows = {b["name"]: b for b in json.load(open(sys.argv[1]))["benchmarks"]}
name = "BM_SkinTick/serial/1000/1/characters:3/gap_us:20000/real_time"
assert list(rows) == [name], list(rows)
row = rows[name]
assert "error_message" not in row and row["iterations"] >= 1, row
assert row["time_unit"] == "ms" and 0 < row["real_time"] < 20, row
PY
"${run[@]}" --tick-gap-us=5 >/dev/null 2>"$work/gap-err.txt" && fail "--tick-gap-us without --tick"
grep -q -- "--tick-gap-us=: only with --tick=N" "$work/gap-err.txt" ||
  fail "--tick-gap-us without --tick unnamed"
echo "bench-formats-test: tick gap: named, left out of the timing, without --tick refused"
echo "bench-formats-test: PASSED"
