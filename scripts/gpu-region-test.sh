#!/usr/bin/env bash
# GPU regions on the GPU machine (docs/serving/gpu-regions.md), from build-gpu/ as
# scripts/gpu-region-pack.sh fills it: the server with the `opencl` backend on the GPU
# (confined to 2 cores), then the headless Vulkan client (on the other cores) at 25k x 2
# and 1.6M x 4: each registers a vertex buffer it exported with a semaphore it exported,
# checks every frame of a test run against the float64 reference (copied back from the GPU
# by a submission that waits on the semaphore the server signalled), draws the character
# mid-walk from the buffer into OUT/*.png (checked against the reference's projected
# positions), then measures frames/s into a GPU region without a semaphore against the
# same frames read back into a shared-memory region, and (25k x 2) the same frames skinned by
# `simd-openmp` on the server's 2 cores into shared memory (the issue's 25k x 2 target). One
# check runs without a semaphore. CesiumMan (build-gpu/assets/CesiumMan.glb, carried by the
# pack) walks into OUT/cesiumman-walk.png: its clip's palettes, every frame checked, the
# picture of its triangles at the clip's middle checked against the reference. Then float16
# and snorm16 frames encoded into the buffer, and ticks of 64 (and 16, snorm16) characters
# into one buffer, each character checked, with their speed rows.
#   scripts/gpu-region-test.sh [OUT_DIR]      (from the repository root; OUT: $OUT or ./out)
# Exit status 0 when every run printed PASS. Overrides (for a dry run elsewhere):
# SKINSERVE_OPENCL_DEVICE (gpu), SKINSERVE_SERVER_CPUS (0,1), SKINSERVE_CLIENT_CPUS (the rest).
set -uo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
d=${SKINSERVE_GPU_DIR:-$root/build-gpu}
cesiumman=$d/assets/CesiumMan.glb
out=${1:-${OUT:-$root/out}}
mkdir -p "$out"
# Vulkan's loader and glvnd from the carried .debs; NVIDIA's Vulkan and OpenCL drivers.
vk=$(mktemp -d /tmp/skinserve-vk-XXXXXX)
for deb in "$d"/debs/*.deb; do dpkg -x "$deb" "$vk"; done
export LD_LIBRARY_PATH=$d/lib:$vk/usr/lib/x86_64-linux-gnu${LD_LIBRARY_PATH:+:$LD_LIBRARY_PATH}
ldconfig 2>/dev/null || true
for icd in /usr/local/nvidia/share/vulkan/icd.d/nvidia_icd.json \
  /usr/share/vulkan/icd.d/nvidia_icd.json /etc/vulkan/icd.d/nvidia_icd.json; do
  if [ -f "$icd" ] && [ -z "${VK_DRIVER_FILES:-}" ]; then export VK_DRIVER_FILES=$icd; fi
done
device=${SKINSERVE_OPENCL_DEVICE:-gpu}
if [ "$device" = gpu ]; then  # NVIDIA's OpenCL is installed but not listed for the loader
  mkdir -p /tmp/icd && echo libnvidia-opencl.so.1 >/tmp/icd/nvidia.icd
  export OCL_ICD_VENDORS=/tmp/icd
fi
server_cpus=${SKINSERVE_SERVER_CPUS:-0,1}
client_cpus=${SKINSERVE_CLIENT_CPUS:-2-$(($(nproc) - 1))}
{
  nvidia-smi --query-gpu=name,driver_version --format=csv 2>&1
  lscpu | grep -E 'Model name|^CPU\(s\)'
  echo "VK_DRIVER_FILES=${VK_DRIVER_FILES:-}"
} >"$out/machine.txt"
cat "$out/machine.txt"

sock=$(mktemp -d /tmp/skinserve-gpu-region-XXXXXX)
server_cmd=(taskset -c "$server_cpus" "$d/bin/skinserve" --listen "unix:$sock/grpc.sock"
  --gpu-fd-socket "$sock/fd.sock" --opencl-device "$device" --default-backend opencl --threads 2
  --backends opencl,simd-openmp --log-level info)
echo "server: ${server_cmd[*]}" | tee "$out/command.txt"
"${server_cmd[@]}" >"$out/server.log" 2>&1 &
server=$!
for _ in $(seq 1 240); do
  grep -q "serving" "$out/server.log" 2>/dev/null && break
  kill -0 "$server" 2>/dev/null || break
  sleep 0.5
done
if ! grep -q "serving" "$out/server.log"; then
  echo "FAIL: the server did not start"; tail -20 "$out/server.log"; exit 1
fi

status=0
run() {  # name, then the client's flags
  local name=$1; shift
  local cmd=(timeout 240 taskset -c "$client_cpus" "$d/bin/skinserve-gpu-region" --target "unix:$sock/grpc.sock"
    --fd-socket "$sock/fd.sock" "$@")
  echo "== $name: ${cmd[*]}" | tee -a "$out/command.txt"
  "${cmd[@]}" 2>&1 | tee "$out/$name.txt"
  if [ "${PIPESTATUS[0]}" -ne 0 ]; then status=1; echo "$name: FAIL"; else echo "$name: PASS"; fi
}
run 25k-x2 --vertices 25000 --influences 2 --check 300 --draw "$out/walk-25k-x2.png" \
  --frames 5000 --window 2 --compare-backend simd-openmp
run 25k-x2-normals --vertices 25000 --influences 2 --normals --check 100 \
  --draw "$out/walk-25k-x2-normals.png" --frames 0
run 25k-x2-no-semaphore --vertices 25000 --influences 2 --semaphore false --check 100 --frames 0
run 1.6M-x4 --vertices 1600000 --influences 4 --check 20 \
  --draw "$out/walk-1.6M-x4.png" --draw-size 1024 --frames 300 --window 2
run cesiumman-walk --mesh "$cesiumman" --check 120 --draw "$out/cesiumman-walk.png" --frames 0
# Encoded into the GPU buffer (the server's opencl encoder): every frame decoded and checked.
run 25k-x2-float16 --vertices 25000 --influences 2 --normals --encoding float16 --check 100 \
  --frames 2000 --window 2 --compare-backend simd-openmp
run 25k-x2-snorm16 --vertices 25000 --influences 2 --normals --encoding snorm16 --check 100 \
  --frames 2000 --window 2 --compare-backend simd-openmp
# Ticks of 64 characters (64 meshes) into one GPU region, signalled once per tick: every
# character of 20 ticks checked, then ticks/s and characters/s against the same ticks read
# back over shm and skinned by simd-openmp on the server's 2 cores.
run ticks-64 --vertices 25000 --influences 2 --characters-per-tick 64 --check 20 \
  --frames 300 --window 2 --compare-backend simd-openmp
run ticks-16-snorm16 --vertices 25000 --influences 2 --normals --characters-per-tick 16 \
  --encoding snorm16 --check 20 --frames 0
# Each check said it waited on the semaphore, each picture is there.
for name in 25k-x2 25k-x2-normals 1.6M-x4 cesiumman-walk 25k-x2-float16 25k-x2-snorm16 \
  ticks-64 ticks-16-snorm16; do
  if ! grep -q "each read after a GPU wait on the semaphore" "$out/$name.txt"; then
    echo "$name: FAIL: its check did not wait on the semaphore"; status=1
  fi
done
for png in walk-25k-x2 walk-25k-x2-normals walk-1.6M-x4 cesiumman-walk; do
  if [ ! -s "$out/$png.png" ]; then echo "$png.png: FAIL: not written"; status=1; fi
done
# The 25k x 2 speed rows (the GPU region, opencl read back, simd-openmp) and CesiumMan's
# triangles (not the synthetic points) were all printed.
if ! grep -q "^simd-openmp-shm: 25000 x 2: .* gpu-region / simd-openmp = " "$out/25k-x2.txt"; then
  echo "25k-x2: FAIL: no simd-openmp row"; status=1
fi
if ! grep -q "^draw: .* as triangles into .*cesiumman-walk.png" "$out/cesiumman-walk.txt"; then
  echo "cesiumman-walk: FAIL: its picture was not drawn as triangles"; status=1
fi
# Every client unregistered what it registered (GPU regions and the comparisons' shared-memory
# ones): none was left for the idle limit to reap.
registered=$(grep -c "region '.*' registered by" "$out/server.log" || true)
unregistered=$(grep -c "region '.*' of .* unregistered" "$out/server.log" || true)
echo "regions: $registered registered, $unregistered unregistered by their clients"
if [ "$registered" -ne "$unregistered" ]; then
  echo "regions: FAIL: $registered registered, $unregistered unregistered"; status=1
fi

kill "$server" 2>/dev/null; wait "$server" 2>/dev/null
rm -rf "$sock" "$vk"
echo "== summary"
grep -hE "^(character|device|check|draw|gpu-region|shm-readback|simd-openmp-shm|regions|FAIL)" \
  "$out"/*x*.txt "$out"/cesiumman-walk.txt "$out"/ticks-*.txt
[ "$status" -eq 0 ] && echo "ALL PASS" || echo "SOME FAILED"
exit "$status"
