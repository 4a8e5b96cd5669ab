#!/usr/bin/env bash
# Fills build-gpu/ (git-ignored) with what scripts/gpu-region-test.sh runs on the GPU
# machine (docs/serving/gpu-regions.md#tests): the server and the Vulkan client, every shared
# library they link but the C and C++ runtimes (the GPU machine has newer ones), and the
# Vulkan loader and glvnd .debs, which the test unpacks there (the NVIDIA Vulkan driver
# needs glvnd beside libvulkan1). The client must have its renderer (--draw: built where
# glslang-tools and libpng-dev are, scripts/install-deps.sh). CesiumMan.glb goes along from
# tests/assets (the run draws it). Run after building both:
#   cmake --build build --target skinserve skinserve-gpu-region
#   scripts/gpu-region-pack.sh [BUILD_DIR]
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
build=${1:-$root/build}
d=$root/build-gpu
rm -rf "$d"
mkdir -p "$d/bin" "$d/lib" "$d/debs" "$d/assets"
if ! "$build/bin/skinserve-gpu-region" --help | grep -q -- --draw; then
  echo "gpu-region-pack: $build/bin/skinserve-gpu-region has no --draw (built without" \
    "glslangValidator or libpng): the GPU test draws pictures" >&2
  exit 1
fi
cp "$build/bin/skinserve" "$build/bin/skinserve-gpu-region" "$d/bin/"
# The loader comes from the .debs (with glvnd); everything else from here.
ldd "$d"/bin/* | awk '/=>/ {print $3}' | sort -u \
  | grep -vE '/(libc|libm|libstdc\+\+|libgcc_s|ld-linux|libvulkan)[.-]' \
  | xargs -I{} cp -L {} "$d/lib/"
strip "$d"/bin/*
(cd "$d/debs" && apt-get download libvulkan1 libegl1 libglvnd0 libopengl0 libgl1 libglx0 libgles2)
cp "$root/tests/assets/gltf/CesiumMan.glb" "$d/assets/"
cp "$root/scripts/gpu-region-test.sh" "$d/"
du -sh "$d"
