# shellcheck shell=bash
# Sourced by the scripts that start a skinserve on a port the kernel picks:
#   skinserve --listen 127.0.0.1:0 --port-file FILE ... &
#   port=$(wait_for_port FILE $! [SECONDS]) || exit 1
# wait_for_port prints the port once the server wrote it (it does so when SERVING); it
# fails, saying why, when the process ends first or SECONDS (default 120) pass.
# Unlike picking a free port first and passing it, nothing can take the port in between.
wait_for_port() {
  local file=$1 pid=$2 seconds=${3:-120} ticks=0 state
  while [ ! -s "$file" ]; do
    # An exited child stays a zombie until waited for; kill -0 would still succeed.
    state=$(sed 's/.*) //' "/proc/$pid/stat" 2>/dev/null | cut -d' ' -f1)
    if [ -z "$state" ] || [ "$state" = Z ]; then
      echo "skinserve (pid $pid) ended before it wrote its port to $file" >&2
      return 1
    fi
    if [ "$ticks" -ge $((seconds * 20)) ]; then
      echo "skinserve (pid $pid) wrote no port to $file within $seconds s" >&2
      return 1
    fi
    sleep 0.05
    ticks=$((ticks + 1))
  done
  cat "$file"
}
