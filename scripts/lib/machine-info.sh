# shellcheck shell=bash
# Sourced by the measuring scripts: write_machine_info FILE ROOT writes what a run's
# machine.txt states (when, the CPU, the GPU if any, the commit of ROOT's checkout).
write_machine_info() {
  local file=$1 root=$2
  {
    date -u +%Y-%m-%dT%H:%MZ
    lscpu | grep -E 'Model name|^CPU\(s\)|L3' || true
    nvidia-smi --query-gpu=name,driver_version --format=csv,noheader 2>/dev/null || true
    git -C "$root" rev-parse --short HEAD 2>/dev/null || true
  } >"$file"
}
