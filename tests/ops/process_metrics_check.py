#!/usr/bin/env python3
"""Checks a server's process_* series against the test's own readings of that process.

usage: process_metrics_check.py METRICS_URL PID LAUNCHED_EPOCH_SECONDS GRPC_PORT
Each reading is taken right before and right after a scrape, so a value that moves (CPU,
memory) must fall between them, within the stated tolerance.
"""
import os
import socket
import sys
import time
import urllib.request

url, pid, launched, grpc_port = sys.argv[1], int(sys.argv[2]), float(sys.argv[3]), int(sys.argv[4])
problems = []
PAGE_KIB = os.sysconf("SC_PAGESIZE") // 1024
TICKS = os.sysconf("SC_CLK_TCK")


def scrape():
    with urllib.request.urlopen(url, timeout=10) as r:
        text = r.read().decode()
    samples = {}
    for line in text.splitlines():
        if line and not line.startswith("#"):
            name, value = line.rsplit(" ", 1)
            samples[name] = float(value)
    return samples


def status_kib(field):
    """A 'Field:   N kB' line of /proc/PID/status, in KiB."""
    with open(f"/proc/{pid}/status") as f:
        for line in f:
            if line.startswith(field + ":"):
                return int(line.split()[1])
    raise KeyError(field)


def cpu_seconds():
    with open(f"/proc/{pid}/stat") as f:
        fields = f.read().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / TICKS  # utime, stime: fields 14 and 15


def open_fds():
    return len(os.listdir(f"/proc/{pid}/fd"))


def expect_between(name, got, low, high):
    if got is None or not low <= got <= high:
        problems.append(f"{name} = {got}, expected between {low} and {high}")


def task_switches(kind):
    """The live threads' context switches of `kind` (voluntary, nonvoluntary), summed."""
    total = 0
    for task in os.listdir(f"/proc/{pid}/task"):
        try:
            with open(f"/proc/{pid}/task/{task}/status") as f:
                total += sum(int(line.split()[1]) for line in f
                             if line.startswith(f"{kind}_ctxt_switches:"))
        except FileNotFoundError:
            pass  # the thread ended meanwhile
    return total


def readings():
    return {"rss": status_kib("VmRSS") * 1024, "vm": status_kib("VmSize") * 1024,
            "cpu": cpu_seconds(), "fds": open_fds(), "voluntary": task_switches("voluntary"),
            "involuntary": task_switches("nonvoluntary")}


before = readings()
m = scrape()
after = readings()

# Resident and virtual memory: between the readings around the scrape, give or take
# 4 MiB (the scrape itself allocates the exposition; /proc's RSS counters lag by a page
# batch per thread).
slack = 4 << 20
for key, name in (("rss", "process_resident_memory_bytes"), ("vm", "process_virtual_memory_bytes")):
    expect_between(name, m.get(name), min(before[key], after[key]) - slack,
                   max(before[key], after[key]) + slack)
# CPU: the clock-tick counters, between the readings (one tick of slack each way).
expect_between("process_cpu_seconds_total", m.get("process_cpu_seconds_total"),
               before["cpu"] - 1 / TICKS, after["cpu"] + 1 / TICKS)
if m.get("process_cpu_seconds_total", 0) <= 0:
    problems.append("process_cpu_seconds_total is not above 0 after a start-up")
# Start time: after the test launched it (btime has whole seconds: 1 s of slack), and
# within the time the server took to come up.
ready = time.time()
expect_between("process_start_time_seconds", m.get("process_start_time_seconds"),
               launched - 1.0, ready)
# Descriptors: the scrape's own connection is one more than the test saw, at most.
expect_between("process_open_fds", m.get("process_open_fds"), min(before["fds"], after["fds"]) - 1,
               max(before["fds"], after["fds"]) + 2)
# Context switches: every thread's, ended ones too, so at least what the live threads had
# before the scrape (the scrape's own come on top; ended threads' cannot be seen from here).
for kind in ("voluntary", "involuntary"):
    name = f'skinserve_process_context_switches_total{{kind="{kind}"}}'
    got = m.get(name)
    if got is None or got < before[kind] or got <= 0:
        problems.append(f"{name} = {got}, expected at least the live threads' {before[kind]} "
                        "and above 0")
with open(f"/proc/{pid}/limits") as f:
    soft = next(line.split()[3] for line in f if line.startswith("Max open files"))
want_max = -1.0 if soft == "unlimited" else float(soft)
if m.get("process_max_fds") != want_max:
    problems.append(f"process_max_fds = {m.get('process_max_fds')}, /proc/{pid}/limits says {soft}")


def cgroup_memory_limit():
    """What the server should see as its memory limit: the cgroup file system as mounted
    for this process (the test runs in the same mount namespace), 0 for none."""
    root = "/sys/fs/cgroup"
    path = (f"{root}/memory.max" if os.path.exists(f"{root}/cgroup.controllers")
            else f"{root}/memory/memory.limit_in_bytes")
    try:
        text = open(path).read().strip()
    except OSError:
        return 0.0
    if text == "max" or int(text) >= 1 << 62:
        return 0.0
    return float(text)


if m.get("skinserve_memory_limit_bytes") != cgroup_memory_limit():
    problems.append(f"skinserve_memory_limit_bytes = {m.get('skinserve_memory_limit_bytes')}, "
                    f"the cgroup says {cgroup_memory_limit()}")

# Clients connecting: 20 TCP connections to the gRPC port each hold a descriptor in the
# server once accepted; process_open_fds grows by them, and shrinks once they close.
base = m["process_open_fds"]
clients = [socket.create_connection(("127.0.0.1", grpc_port), timeout=5) for _ in range(20)]
deadline = time.time() + 10
while open_fds() < before["fds"] + 20 and time.time() < deadline:
    time.sleep(0.05)
grown = scrape()["process_open_fds"]
expect_between("process_open_fds with 20 clients", grown, base + 20 - 2, open_fds() + 2)
for c in clients:
    c.close()
deadline = time.time() + 20
while open_fds() > base + 5 and time.time() < deadline:  # the bound asserted below
    time.sleep(0.1)
shrunk = scrape()["process_open_fds"]
expect_between("process_open_fds after the clients left", shrunk, 0, base + 5)

for key in ("process_cpu_seconds_total", "process_resident_memory_bytes",
            "process_open_fds", "process_start_time_seconds"):
    print(f"process-metrics-test: {key} {m.get(key)}")
print(f"process-metrics-test: open fds {base:g}, with 20 clients {grown:g}, after {shrunk:g}")
for p in problems:
    print("process-metrics-test: FAILED:", p)
sys.exit(1 if problems else 0)
