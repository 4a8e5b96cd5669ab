# How long MAP_POPULATE takes a RegisterRegion's mmap of a fresh (sparse) tmpfs file, against
# a plain mmap then a write to every page (what a stream's first frames did): five each, then
# the minor faults those writes take (getrusage), and the same loop again on written pages.
# Run: taskset -c 0 python3 populate-time.py (populate-time.txt, the VM, 2026-11-30 13:57 UTC).
import mmap, os, resource, time
size = 2 * 64 * 300 * 1024  # 2 slots of 64 characters x 300 KB: a tick stream's region
for trial in range(5):
    for populate in (True, False):
        path = f"/dev/shm/poptime-{os.getpid()}"
        fd = os.open(path, os.O_RDWR | os.O_CREAT | os.O_EXCL, 0o600)
        os.ftruncate(fd, size)
        t0 = time.perf_counter()
        flags = mmap.MAP_SHARED | (mmap.MAP_POPULATE if populate else 0)
        m = mmap.mmap(fd, size, flags=flags)
        t1 = time.perf_counter()
        for off in range(0, size, 4096):
            m[off] = 1
        t2 = time.perf_counter()
        m.close(); os.close(fd); os.unlink(path)
        print(f"trial {trial} {'populate' if populate else 'plain   '}: mmap {1e3*(t1-t0):7.2f} ms, "
              f"then one write a page {1e3*(t2-t1):7.2f} ms ({size // 4096} pages)")
for populate in (True, False):
    path = f"/dev/shm/poptime-{os.getpid()}"
    fd = os.open(path, os.O_RDWR | os.O_CREAT | os.O_EXCL, 0o600)
    os.ftruncate(fd, size)
    m = mmap.mmap(fd, size, flags=mmap.MAP_SHARED | (mmap.MAP_POPULATE if populate else 0))
    r0 = resource.getrusage(resource.RUSAGE_THREAD).ru_minflt
    t1 = time.perf_counter()
    for off in range(0, size, 4096):
        m[off] = 1
    t2 = time.perf_counter()
    r1 = resource.getrusage(resource.RUSAGE_THREAD).ru_minflt
    for off in range(0, size, 4096):
        m[off] = 2
    t3 = time.perf_counter()
    print(f"{'populate' if populate else 'plain   '}: first writes {1e3*(t2-t1):.1f} ms, "
          f"{r1 - r0} faults; the same writes again {1e3*(t3-t2):.1f} ms")
    m.close(); os.close(fd); os.unlink(path)
