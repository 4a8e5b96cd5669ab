#!/usr/bin/env bash
# Per-thread voluntary context switches of a real server (pinned to core 0, --threads 1) over
# one 4 s run of 32 streams of 25k x 2 at 60 fps (load on core 1), grouped by thread name.
# Usage: [TCP=1] thread-switches.sh BIN_DIR POLL_STRATEGY PLANE   (TCP=1: the load over TCP)
# per-thread voluntary switches: BIN MODE PLANE
bin=$1; mode=$2; plane=${3:-grpc}
sd=$(mktemp -d); pf=$(mktemp -u)
env GRPC_POLL_STRATEGY=$mode ${NATIVE:+NATIVE_UNIX=1} ${NOBDP:+NO_BDP=1} taskset -c 0 $bin/skinserve --listen "127.0.0.1:0,unix:$sd/g.sock" --metrics-listen 127.0.0.1:0 --shm-dir /dev/shm --threads 1 --shm-max-regions-per-connection 256 --port-file $pf > $sd/log 2>&1 &
srv=$!
for i in $(seq 100); do [ -s $pf ] && break; sleep 0.2; done
snap() { for t in /proc/$srv/task/*; do echo "$(basename $t) $(cat $t/comm | tr ' ' _) $(awk '/^voluntary_ctxt/ {print $2}' $t/status)"; done | sort; }
[ -n "$TCP" ] && TARGET=127.0.0.1:$(head -1 $pf | grep -o "[0-9]*$"); echo target=${TARGET:-unix}; cat $pf | head -2
snap > $sd/before
taskset -c 1 $bin/skinserve-load --target ${TARGET:-unix:$sd/g.sock} --backends simd --vertices 25000 --bones 2 --streams 32 --rate 60 --duration 4 --warmup 0 --data-planes $plane --shm-dir /dev/shm > $sd/load.txt 2>&1
snap > $sd/after
frames=$((32*60*4))
join -a2 $sd/before $sd/after | awk -v f=$frames '{b=(NF==5?$3:0); a=$NF; d=a-b; name=$2; s[name]+=d; n[name]++} END {for (k in s) if (s[k]>0) printf "%-22s threads %3d  switches/frame %.2f\n", k, n[k], s[k]/f}' | sort -k5 -nr
grep -iE "error|simd" $sd/load.txt | head -5
kill $srv; wait $srv 2>/dev/null; rm -rf $sd $pf
