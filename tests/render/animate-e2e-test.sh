#!/usr/bin/env bash
# End to end with real glTF characters: a skinserve server on a free loopback port,
#   skinserve-cli animate CesiumMan.glb --render   OBJ and PNG per frame and a contact sheet
#   skinserve-cli animate --on-server --render     the same files, poses sampled by the server
#   skinserve-cli animate --clip <unknown>         non-zero exit, the file's clips listed
#   skinserve-load --mesh RiggedSimple.glb         two backends, answers checked, exit 0
#   a hand-made character with two skins (skinserve-test-scene two-skins):
#     skinserve-cli upload                         one mesh per skin
#     skinserve-cli animate --render               one OBJ per frame with a group per
#                                                  primitive, every vertex, one image
#     skinserve-cli animate --primitive 1          that primitive alone
#     skinserve-load --mesh                        the whole character, answers checked
#   a hand-made character with rigid parts (skinserve-test-scene rigid-parts):
#     skinserve-cli upload                         the rigid parts in the skin's meshes
#     skinserve-cli animate --render               every vertex of every part, one image
#     skinserve-load --mesh                        the whole character, answers checked
#   a hand-made character with tangents and morph tangent deltas (tangents):
#     skinserve-load --mesh --normals --tangents   tangents asked for and checked; refused,
#                                                  naming the mesh, of one without tangents
#     skinserve-cli upload                         float32 by itself; quantized16 refused
#   a KHR_mesh_quantization character (quantized):
#     skinserve-cli upload                         quantized16 from the file, float32 when
#                                                  asked (another mesh id), a bad name refused
#     skinserve-cli animate --backend simd         auto and float32 agree within 1e-3 extent
# The characters are the repository's (tests/assets/gltf); a missing one fails the test.
# usage: animate-e2e-test.sh SKINSERVE SKINSERVE-CLI SKINSERVE-LOAD ASSETS-DIR TEST-SCENE
set -euo pipefail
# shellcheck source-path=SCRIPTDIR source=../../scripts/lib/port-file.sh
source "$(dirname "${BASH_SOURCE[0]}")/../../scripts/lib/port-file.sh"

if [ $# -ne 5 ]; then
  echo "usage: $0 skinserve skinserve-cli skinserve-load assets-dir skinserve-test-scene" >&2
  exit 2
fi
server=$1 cli=$2 load=$3 assets=$4 scene=$5
for f in CesiumMan.glb RiggedSimple.glb; do
  if [ ! -f "$assets/$f" ]; then
    echo "animate-e2e: FAILED: $assets/$f is missing (part of the repository: git checkout it)" >&2
    exit 1
  fi
done

work=$(mktemp -d "${TMPDIR:-/tmp}/skinserve-animate.XXXXXX")
pid=""
say() { echo "animate-e2e: $*"; }
fail() { echo "animate-e2e: FAILED: $*" >&2; exit 1; }
cleanup() {
  local rc=$?
  if [ -n "$pid" ]; then
    kill -TERM "$pid" 2>/dev/null || true
    for _ in $(seq 1 50); do kill -0 "$pid" 2>/dev/null || break; sleep 0.1; done
    kill -KILL "$pid" 2>/dev/null || true
    wait "$pid" 2>/dev/null || true
  fi
  if [ $rc -ne 0 ]; then
    echo "--- server log, last 15 lines"
    tail -15 "$work/server.log" 2>/dev/null || true
  fi
  rm -rf "$work"
  exit $rc
}
trap cleanup EXIT
trap 'exit 130' INT TERM

"$server" --listen 127.0.0.1:0 --port-file "$work/port" --log-level warn \
  >"$work/server.log" 2>&1 &
pid=$!
port=$(wait_for_port "$work/port" "$pid" 60) || fail "server not serving after 60 s"
target=127.0.0.1:$port

# ---- animate: 0.5 s at 10 fps is frames 0..4 --------------------------------------------
out=$work/out
say "skinserve-cli animate CesiumMan.glb --seconds 0.5 --fps 10 --render"
timeout 120 "$cli" --target "$target" animate "$assets/CesiumMan.glb" --seconds 0.5 --fps 10 \
  --backend sse --render --out "$out" || fail "animate exited $?"
for i in 0 1 2 3 4; do
  for ext in obj png; do
    [ -s "$out/frame_000$i.$ext" ] || fail "$out/frame_000$i.$ext missing or empty"
  done
done
[ ! -e "$out/frame_0005.obj" ] || fail "frame_0005.obj written: more frames than 0.5 s at 10 fps"
[ -s "$out/contact-sheet.png" ] || fail "contact-sheet.png missing"
# Every vertex of the character (SOURCES.md: 3273), faces, and a pose that moves.
vertices=$(grep -c '^v ' "$out/frame_0000.obj")
[ "$vertices" -eq 3273 ] || fail "frame_0000.obj has $vertices vertices, not 3273"
grep -q '^f ' "$out/frame_0000.obj" || fail "frame_0000.obj has no faces"
! cmp -s "$out/frame_0000.obj" "$out/frame_0004.obj" || fail "frames 0 and 4 are identical"
python3 - "$out" <<'PY' || fail "PNG sizes"
import struct, sys
def size(path):
    with open(path, "rb") as f:
        head = f.read(24)
    assert head[:8] == b"\x89PNG\r\n\x1a\n", path + ": not a PNG"
    return struct.unpack(">II", head[16:24])
out = sys.argv[1]
assert size(out + "/frame_0000.png") == (640, 640), size(out + "/frame_0000.png")
w, h = size(out + "/contact-sheet.png")
assert w == 1024 and h > 0, (w, h)
PY

# ---- the same with --on-server: the server samples the uploaded clip ---------------------
# (every vertex against float64: tests/character/animate_on_server_test.cpp; here the files)
say "skinserve-cli animate CesiumMan.glb --on-server --render"
timeout 120 "$cli" --target "$target" animate "$assets/CesiumMan.glb" --seconds 0.5 --fps 10 \
  --backend sse --render --on-server --out "$work/server" >"$work/server.txt" ||
  fail "animate --on-server exited $?"
grep -q '^  clip [0-9a-f]\{64\}: .* bytes stored' "$work/server.txt" ||
  fail "animate --on-server uploaded no clip: $(cat "$work/server.txt")"
for i in 0 1 2 3 4; do
  for ext in obj png; do
    [ -s "$work/server/frame_000$i.$ext" ] || fail "--on-server frame_000$i.$ext missing or empty"
  done
done
[ ! -e "$work/server/frame_0005.obj" ] || fail "--on-server wrote more frames than 0.5 s at 10 fps"
[ -s "$work/server/contact-sheet.png" ] || fail "--on-server contact-sheet.png missing"
vertices=$(grep -c '^v ' "$work/server/frame_0004.obj")
[ "$vertices" -eq 3273 ] || fail "--on-server frame_0004.obj has $vertices vertices, not 3273"

# ---- a clip the file does not have -------------------------------------------------------
say "skinserve-cli animate --clip NoSuchClip"
if "$cli" --target "$target" animate "$assets/CesiumMan.glb" --clip NoSuchClip --out "$work/bad" \
  2>"$work/bad.err"; then
  fail "animate --clip NoSuchClip exited 0"
fi
grep -q "Anim_0" "$work/bad.err" || fail "the error does not list the clips: $(cat "$work/bad.err")"

# ---- load client with a glTF workload -----------------------------------------------------
say "skinserve-load --mesh RiggedSimple.glb --backends serial,sse --duration 1"
timeout 120 "$load" --target "$target" --mesh "$assets/RiggedSimple.glb" --backends serial,sse \
  --duration 1 --warmup 0 --check-every 5 --json "$work/load.json" ||
  fail "skinserve-load exited $?"
python3 - "$work/load.json" <<'PY' || fail "load report"
import json, sys
results = json.load(open(sys.argv[1]))["results"]
assert [r["backend"] for r in results] == ["serial", "sse"], results
for r in results:
    assert r["vertices"] == 960 and r["frames"] > 0 and r["checked"] > 0, r
    assert r["mismatches"] == 0 and not r["errors"], r
PY
# ---- a whole character of several skins and primitives ----------------------------------
two=$work/two-skins.glb
facts=$("$scene" two-skins "$two") || fail "skinserve-test-scene exited $?"
say "two-skins.glb: $facts"
total=${facts%% vertices*}
names=${facts#*primitives: }
"$cli" --target "$target" upload "$two" >"$work/upload.txt" || fail "upload exited $?"
meshes=$(grep -c '^[^ ].*: [0-9a-f]\{64\}' "$work/upload.txt" || true)
[ "$meshes" -eq 2 ] || fail "upload stored $meshes meshes, not one per skin (2): $(cat "$work/upload.txt")"

say "skinserve-cli animate two-skins.glb --render"
timeout 120 "$cli" --target "$target" animate "$two" --fps 10 --seconds 0.5 --backend sse \
  --render --width 160 --height 160 --out "$work/two" || fail "animate exited $?"
for i in 0 1 2 3 4; do
  [ -s "$work/two/frame_000$i.obj" ] || fail "two-skins frame_000$i.obj missing or empty"
  [ -s "$work/two/frame_000$i.png" ] || fail "two-skins frame_000$i.png missing or empty"
done
vertices=$(grep -c '^v ' "$work/two/frame_0004.obj")
[ "$vertices" -eq "$total" ] || fail "frame_0004.obj has $vertices vertices, the character $total"
groups=$(grep '^g ' "$work/two/frame_0004.obj" | cut -d' ' -f2- | tr '\n' ' ' | sed 's/ $//')
[ "$groups" = "$names" ] || fail "frame_0004.obj groups '$groups', primitives '$names'"

say "skinserve-cli animate two-skins.glb --primitive 1"
timeout 60 "$cli" --target "$target" animate "$two" --fps 10 --seconds 0.2 --primitive 1 \
  --out "$work/one" || fail "animate --primitive 1 exited $?"
groups=$(grep '^g ' "$work/one/frame_0000.obj" | cut -d' ' -f2-)
[ "$groups" = "$(echo "$names" | cut -d' ' -f2)" ] || fail "--primitive 1 wrote groups '$groups'"

say "skinserve-load --mesh two-skins.glb"
timeout 120 "$load" --target "$target" --mesh "$two" --backends sse --duration 1 --warmup 0 \
  --check-every 3 --json "$work/two-load.json" || fail "skinserve-load --mesh two-skins exited $?"
python3 - "$work/two-load.json" "$total" <<'PY' || fail "two-skins load report"
import json, sys
results = json.load(open(sys.argv[1]))["results"]
for r in results:
    assert r["vertices"] == int(sys.argv[2]) and r["frames"] > 0 and r["checked"] > 0, r
    assert r["mismatches"] == 0 and not r["errors"], r
PY
# ---- a character with rigid parts (meshes on nodes without a skin) ----------------------
rigid=$work/rigid-parts.glb
facts=$("$scene" rigid-parts "$rigid") || fail "skinserve-test-scene exited $?"
say "rigid-parts.glb: $facts"
total=${facts%% vertices*}
names=${facts#*primitives: }
"$cli" --target "$target" upload "$rigid" >"$work/rigid-upload.txt" || fail "upload exited $?"
uploaded=$(grep -c '^  .*: vertices' "$work/rigid-upload.txt" || true)
[ "$uploaded" -eq "$(echo "$names" | wc -w)" ] ||
  fail "upload listed $uploaded primitives, the file has $names: $(cat "$work/rigid-upload.txt")"

say "skinserve-cli animate rigid-parts.glb --render"
timeout 120 "$cli" --target "$target" animate "$rigid" --fps 10 --seconds 0.5 --backend sse \
  --render --width 160 --height 160 --out "$work/rigid" || fail "animate exited $?"
[ -s "$work/rigid/frame_0004.png" ] || fail "rigid-parts frame_0004.png missing or empty"
vertices=$(grep -c '^v ' "$work/rigid/frame_0004.obj")
[ "$vertices" -eq "$total" ] || fail "frame_0004.obj has $vertices vertices, the character $total"
groups=$(grep '^g ' "$work/rigid/frame_0004.obj" | cut -d' ' -f2- | sort | tr '\n' ' ' | sed 's/ $//')
expected=$(echo "$names" | tr ' ' '\n' | sort | tr '\n' ' ' | sed 's/ $//')
[ "$groups" = "$expected" ] || fail "frame_0004.obj groups '$groups', primitives '$expected'"

say "skinserve-load --mesh rigid-parts.glb"
timeout 120 "$load" --target "$target" --mesh "$rigid" --backends sse --duration 1 --warmup 0 \
  --check-every 3 --json "$work/rigid-load.json" || fail "skinserve-load --mesh rigid-parts exited $?"
python3 - "$work/rigid-load.json" "$total" <<'PY' || fail "rigid-parts load report"
import json, sys
results = json.load(open(sys.argv[1]))["results"]
for r in results:
    assert r["vertices"] == int(sys.argv[2]) and r["frames"] > 0 and r["checked"] > 0, r
    assert r["mismatches"] == 0 and not r["errors"], r
PY
# ---- a character with tangents (and morph targets with tangent deltas) ------------------
tangent=$work/tangents.glb
facts=$("$scene" tangents "$tangent") || fail "skinserve-test-scene exited $?"
say "tangents.glb: $facts"
total=${facts%% vertices*}
say "skinserve-load --mesh tangents.glb --normals --tangents"
timeout 120 "$load" --target "$target" --mesh "$tangent" --backends sse,simd --normals --tangents \
  --duration 1 --warmup 0 --check-every 2 --json "$work/tangent-load.json" ||
  fail "skinserve-load --mesh tangents.glb --tangents exited $?"
python3 - "$work/tangent-load.json" "$total" <<'PY' || fail "tangents load report"
import json, sys
results = json.load(open(sys.argv[1]))["results"]
assert len(results) == 2, results
for r in results:
    assert r["vertices"] == int(sys.argv[2]) and r["frames"] > 0 and r["checked"] > 0, r
    assert r["tangents"] and r["mismatches"] == 0 and not r["errors"], r
PY
say "skinserve-load --mesh RiggedSimple.glb --tangents (it has none): refused"
if "$load" --target "$target" --mesh "$assets/RiggedSimple.glb" --backends sse --normals \
  --tangents --duration 1 2>"$work/no-tangents.err"; then
  fail "--tangents on a mesh without tangents exited 0"
fi
grep -q -- "--tangents: Armature has no tangents in" "$work/no-tangents.err" ||
  fail "--tangents without tangents: $(cat "$work/no-tangents.err")"

# ---- the rest stream a quantized glTF asks for (KHR_mesh_quantization) --------------------
quant=$work/quantized.glb
facts=$("$scene" quantized "$quant") || fail "skinserve-test-scene exited $?"
say "quantized.glb: $facts"
"$cli" --target "$target" upload "$quant" >"$work/q-upload.txt" || fail "upload exited $?"
grep -q '^  rest stream quantized16: every primitive stores POSITION as 8- or 16-bit' "$work/q-upload.txt" ||
  fail "upload of quantized.glb did not take quantized16 from the file: $(cat "$work/q-upload.txt")"
"$cli" --target "$target" upload --rest-encoding float32 "$quant" >"$work/f-upload.txt" ||
  fail "upload --rest-encoding float32 exited $?"
grep -q '^  rest stream float32: asked with --rest-encoding' "$work/f-upload.txt" ||
  fail "--rest-encoding float32 did not win: $(cat "$work/f-upload.txt")"
q_id=$(grep -o '[0-9a-f]\{64\}' "$work/q-upload.txt")
f_id=$(grep -o '[0-9a-f]\{64\}' "$work/f-upload.txt")
[ "$q_id" != "$f_id" ] || fail "float32 and quantized16 uploads share the mesh id $q_id"
if "$cli" --target "$target" upload --rest-encoding quantized9 "$quant" 2>"$work/bad-enc.err"; then
  fail "--rest-encoding quantized9 exited 0"
fi
grep -q -- "--rest-encoding 'quantized9' is none of auto, float32" "$work/bad-enc.err" ||
  fail "--rest-encoding quantized9: $(cat "$work/bad-enc.err")"
# tangents.glb's character has morph targets too: a quantized stream carries none of those.
if "$cli" --target "$target" upload --rest-encoding quantized16 "$work/tangents.glb" \
  2>"$work/tan-enc.err"; then
  fail "--rest-encoding quantized16 of a mesh with morph targets exited 0"
fi
grep -q -- "--rest-encoding quantized16: .* has morph targets, which a quantized rest stream" \
  "$work/tan-enc.err" || fail "quantized16 with morph targets: $(cat "$work/tan-enc.err")"
"$cli" --target "$target" upload "$work/tangents.glb" >"$work/tan-upload.txt" ||
  fail "upload tangents.glb exited $?"
grep -q '^  rest stream float32: .* has morph targets (a quantized rest stream carries none)' \
  "$work/tan-upload.txt" || fail "tangents.glb not float32 by itself: $(cat "$work/tan-upload.txt")"
# The same clip from the quantized stream (simd reads the integers) and from float32: within
# 1e-3 of the character's extent, far above the stream's bound (docs/backends/quantized-rest.md,
# 1.3e-5 of it for positions plus a 16-bit weight step) and far below a wrong box or joint.
say "skinserve-cli animate quantized.glb, auto and float32, on simd"
for enc in auto float32; do
  timeout 60 "$cli" --target "$target" animate "$quant" --fps 10 --seconds 0.5 --backend simd \
    --rest-encoding "$enc" --out "$work/q-$enc" >"$work/q-$enc.txt" ||
    fail "animate --rest-encoding $enc exited $?"
done
grep -q '^  rest stream quantized16' "$work/q-auto.txt" ||
  fail "animate did not take quantized16: $(cat "$work/q-auto.txt")"
python3 - "$work/q-auto" "$work/q-float32" <<'PY' || fail "quantized and float32 animations differ"
import sys
def vertices(path):
    return [tuple(map(float, l.split()[1:4])) for l in open(path) if l.startswith("v ")]
for i in range(5):
    q = vertices(f"{sys.argv[1]}/frame_000{i}.obj")
    f = vertices(f"{sys.argv[2]}/frame_000{i}.obj")
    assert len(q) == len(f) == 66, (i, len(q), len(f))
    extent = max(max(v[k] for v in f) - min(v[k] for v in f) for k in range(3))
    worst = max(abs(a - b) for u, w in zip(q, f) for a, b in zip(u, w))
    assert worst <= 1e-3 * extent, f"frame {i}: {worst} > 1e-3 * extent {extent}"
PY
say "passed"
