#!/usr/bin/env bash
# Installs every Debian 12 package skinserve needs to build, test and run.
# Idempotent: packages already present are left alone; needs root (or sudo).
#   install-deps.sh [all]   everything: build, run, tests, plots, deploy tests (the default)
#   install-deps.sh build   what compiling needs (the container's build stage)
#   install-deps.sh runtime what the binaries need to run (the container's runtime stage)
set -euo pipefail

BUILD_PACKAGES=(
  build-essential cmake ninja-build pkg-config git ca-certificates ccache
  libgrpc++-dev libprotobuf-dev protobuf-compiler protobuf-compiler-grpc
  ocl-icd-opencl-dev opencl-c-headers opencl-clhpp-headers libvulkan-dev glslang-tools libpng-dev
  libglm-dev libcli11-dev libspdlog-dev libfmt-dev
  libtinygltf-dev nlohmann-json3-dev libstb-dev libcairo2-dev
  libgtest-dev libgmock-dev libbenchmark-dev
  clang-format
)
# What the binaries need at run time (the container's runtime stage uses this list).
RUNTIME_PACKAGES=(
  pocl-opencl-icd ocl-icd-libopencl1
  libgrpc++1.51 libprotobuf32 libspdlog1.10 libfmt9 libgomp1 libtinygltf2d libcairo2 libssl3
)
# The interop test (a client nobody here wrote), the plots, and the documentation site
# (scripts/docs.sh: MkDocs with the Material theme).
TEST_PACKAGES=(
  python3 python3-grpcio python3-grpc-tools python3-numpy python3-matplotlib gnuplot-nox
  mkdocs mkdocs-material
)
# Figure 5's table and plot from skinserve-bench's JSON (scripts/figure5-plot.sh).
GPU_PACKAGES=(
  jq gnuplot-nox
)
# The deployment tests: manifests lint, and the container image built and run with podman
# (deploy/smoke-test.sh).
DEPLOY_PACKAGES=(
  yamllint podman runc debootstrap
)
# kubectl renders the kustomize overlays offline (deploy.manifests). Debian's is
# kubernetes-client; a kubectl already installed from elsewhere (a newer one owning
# /usr/bin/kubectl) is left alone rather than replaced.
if ! command -v kubectl >/dev/null 2>&1; then DEPLOY_PACKAGES+=(kubernetes-client); fi
# Security (issue 27): openssl makes the tests' certificates (scripts/make-dev-certs.sh);
# clinfo lists OpenCL platforms when debugging a machine (not in the runtime image).
TEST_PACKAGES+=(openssl clinfo)
# Operations (issue 15): skinserve-load's metrics scrapes (cpp-httplib's client); promtool
# (prometheus) and curl to check the exposition; the Python client's venv, pip install and
# pytest (Debian's grpcio and numpy are its runtime).
BUILD_PACKAGES+=(libcpp-httplib-dev)
RUNTIME_PACKAGES+=(libcpp-httplib0.11)
TEST_PACKAGES+=(prometheus curl python3-venv python3-pip python3-setuptools python3-pytest)
# Conventions (issue 30): man pages generated from --help at build time (help2man);
# script(1) (bsdutils, essential) gives the progress-line test its terminal.
BUILD_PACKAGES+=(help2man)
# The Python client's wheel (issue 30): built with pip, setuptools and wheel, its messages
# from protobuf-compiler's protoc, run on Debian's protobuf; mypy --strict on it, packaging
# to compare its pinned ranges with what is installed.
TEST_PACKAGES+=(python3-protobuf python3-wheel python3-packaging python3-mypy)
# GPU regions' renderer (skinserve-gpu-region --draw, issue 44): its drawing test runs on
# the CPU's Vulkan, Mesa's lavapipe.
TEST_PACKAGES+=(mesa-vulkan-drivers)
# Short functions (issue 45): conventions.function_length finds every function with
# universal-ctags.
TEST_PACKAGES+=(universal-ctags)

# Proof under stress: clang with its sanitizer and libFuzzer runtimes, libomp for TSan
# (its libarcher), iproute2 for the network-fault test's namespaces and netem.
STRESS_PACKAGES=(
  clang-14 libclang-rt-14-dev libomp-14-dev iproute2 procps
)

# The `simd` backends: Google Highway (run-time SIMD dispatch).
SIMD_BUILD_PACKAGES=(libhwy-dev)
SIMD_RUNTIME_PACKAGES=(libhwy1)

# The engine on arm64 (scripts/arm64-test.sh): Debian's cross toolchain, qemu-user, and the
# engine's libraries for arm64 installed beside the amd64 ones (multiarch; the arm64
# architecture is added below when they are wanted).
ARM64_PACKAGES=(
  crossbuild-essential-arm64 qemu-user libhwy-dev:arm64 libfmt-dev:arm64 libssl-dev:arm64
  ocl-icd-opencl-dev:arm64 libtinygltf-dev:arm64 libgtest-dev:arm64 libgomp1:arm64
)

want=("${BUILD_PACKAGES[@]}" "${RUNTIME_PACKAGES[@]}" "${TEST_PACKAGES[@]}" "${GPU_PACKAGES[@]}" "${DEPLOY_PACKAGES[@]}"
  "${STRESS_PACKAGES[@]}" "${SIMD_BUILD_PACKAGES[@]}" "${SIMD_RUNTIME_PACKAGES[@]}"
  "${ARM64_PACKAGES[@]}")
case "${1:-all}" in
  runtime) want=("${RUNTIME_PACKAGES[@]}" "${SIMD_RUNTIME_PACKAGES[@]}") ;;  # runtime stage
  build)  # compile, no test tools
    want=("${BUILD_PACKAGES[@]}" "${RUNTIME_PACKAGES[@]}" "${SIMD_BUILD_PACKAGES[@]}"
      "${SIMD_RUNTIME_PACKAGES[@]}") ;;
  all) ;;
  *) echo "usage: $0 [all|build|runtime]" >&2; exit 2 ;;
esac

missing=()
for p in "${want[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q 'install ok installed' || missing+=("$p")
done
if [ ${#missing[@]} -eq 0 ]; then
  echo "install-deps: all ${#want[@]} packages present"
  exit 0
fi

SUDO=""
[ "$(id -u)" -eq 0 ] || SUDO="sudo"
echo "install-deps: installing ${missing[*]}"
export DEBIAN_FRONTEND=noninteractive
if [[ " ${missing[*]}" == *":arm64"* ]] && ! dpkg --print-foreign-architectures | grep -qx arm64; then
  $SUDO dpkg --add-architecture arm64
fi
$SUDO apt-get update -qq
$SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}"
