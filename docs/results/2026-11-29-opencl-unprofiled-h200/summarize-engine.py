#!/usr/bin/env python3
"""engine.csv from engine/timing{0,1}-{1,2}.json.xz: per frame size, microseconds a frame
(round 1 / round 2) of simd-openmp on the 16 cores and of opencl written in place into device
memory with the queues unprofiled (--opencl-device-timing=0, the server's default now) and
profiled (=1), and unprofiled's speed against simd-openmp round by round (> 1: the GPU wins)."""
import glob, json, lzma, os
here = os.path.dirname(os.path.abspath(__file__))
t = {}
for timing in (0, 1):
    for rnd in (1, 2):
        f = os.path.join(here, 'engine', f'timing{timing}-{rnd}.json.xz')
        for b in json.load(lzma.open(f))['benchmarks']:
            if b.get('aggregate_name') != 'median':
                continue
            name, backend, v, bones = b['run_name'].replace('/real_time', '').split('/')[:4]
            col = ('simd', timing) if backend == 'simd-openmp' else ('gpu', timing)
            t.setdefault((int(v), int(bones)), {}).setdefault(col, {})[rnd] = b['real_time']
fmt = lambda d: ' / '.join(f'{d[r]:.1f}' for r in sorted(d))
print('vertices x bones,simd-openmp (16 cores) us,in place unprofiled us,in place profiled us,unprofiled vs simd-openmp')
for (v, bones), r in sorted(t.items()):
    simd = r[('simd', 0)]  # measured in the same invocation as the unprofiled rows
    place, profiled = r[('gpu', 0)], r[('gpu', 1)]
    ratio = ' / '.join(f'{simd[i] / place[i]:.2f}x' for i in sorted(simd))
    print(f'{v // 1000}k x {bones},{fmt(simd)},{fmt(place)},{fmt(profiled)},{ratio}')
