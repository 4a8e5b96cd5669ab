#!/usr/bin/env python3
"""A faulty network link between two TUN devices, like tc netem (which this kernel may
lack): every IP packet read from one device is written to the other after a delay of
`delay` +- `jitter` ms (packets overtake each other: reordering), or dropped with
probability `loss`. The devices are created here and then moved into the namespaces by
the caller (`ip link set ... netns ...`); our file descriptors keep working across that.

    link_emulator.py DEV_A DEV_B --delay 20 --jitter 15 --loss 0.02 --seed 1 --ready FILE
Writes FILE once both devices exist; runs until killed; prints its counts on SIGTERM.
SIGUSR1 turns a blackhole on and off: while on, every packet both ways is dropped (a peer
that vanished without a FIN or a reset, as a pulled cable or a dead node looks).
"""
import argparse
import fcntl
import heapq
import os
import random
import select
import signal
import struct
import sys
import threading
import time

TUNSETIFF = 0x400454CA
IFF_TUN, IFF_NO_PI = 0x0001, 0x1000


def open_tun(name):
    fd = os.open("/dev/net/tun", os.O_RDWR)
    fcntl.ioctl(fd, TUNSETIFF, struct.pack("16sH", name.encode(), IFF_TUN | IFF_NO_PI))
    return fd


def main():
    p = argparse.ArgumentParser()
    p.add_argument("dev_a")
    p.add_argument("dev_b")
    p.add_argument("--delay", type=float, default=20.0)
    p.add_argument("--jitter", type=float, default=10.0)
    p.add_argument("--loss", type=float, default=0.0)
    p.add_argument("--seed", type=int, default=1)
    p.add_argument("--ready", required=True)
    args = p.parse_args()
    rng = random.Random(args.seed)
    fds = {open_tun(args.dev_a): None, open_tun(args.dev_b): None}
    a, b = list(fds)
    peer = {a: b, b: a}
    counts = {"forwarded": 0, "dropped": 0, "reordered": 0, "blackholed": 0}
    blackhole = [False]
    queue = []  # (due, seq, fd, packet)
    lock = threading.Condition()
    seq = 0
    last_due = {a: 0.0, b: 0.0}

    def stop(*_):
        print(f"link_emulator: {counts}", flush=True)
        sys.exit(0)

    def toggle_blackhole(*_):
        blackhole[0] = not blackhole[0]
        print(f"link_emulator: blackhole {'on' if blackhole[0] else 'off'}", flush=True)

    signal.signal(signal.SIGTERM, stop)
    signal.signal(signal.SIGUSR1, toggle_blackhole)

    def writer():
        while True:
            with lock:
                while not queue or queue[0][0] > time.monotonic():
                    lock.wait(None if not queue else max(0.0, queue[0][0] - time.monotonic()))
                _, _, fd, packet = heapq.heappop(queue)
            if blackhole[0]:  # queued before the blackhole began: lost with it
                counts["blackholed"] += 1
                continue
            try:
                os.write(fd, packet)
                counts["forwarded"] += 1
            except OSError:
                pass

    threading.Thread(target=writer, daemon=True).start()
    open(args.ready, "w").close()
    while True:
        readable, _, _ = select.select(list(fds), [], [])
        for fd in readable:
            packet = os.read(fd, 65536)
            if blackhole[0]:
                counts["blackholed"] += 1
                continue
            if rng.random() < args.loss:
                counts["dropped"] += 1
                continue
            due = time.monotonic() + max(0.0, rng.gauss(args.delay, args.jitter)) / 1000.0
            if due < last_due[fd]:
                counts["reordered"] += 1
            last_due[fd] = max(last_due[fd], due)
            with lock:
                seq += 1
                heapq.heappush(queue, (due, seq, peer[fd], packet))
                lock.notify()


if __name__ == "__main__":
    main()
