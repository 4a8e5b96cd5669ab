#!/usr/bin/env python3
"""engine.csv from engine/gpu-bench-*.json.xz: per frame size, the two rounds' medians (us a
frame) of simd-openmp on 16 cores, opencl with the output left on the GPU through copies
(BM_SkinDeviceOutput) and written in place (BM_SkinDeviceOutputInPlace), and in place's
speed against simd-openmp round by round (simd-openmp time / in-place time: > 1, the GPU wins)."""
import glob, json, lzma, os, sys
here = os.path.dirname(os.path.abspath(__file__))
t = {}
for f in sorted(glob.glob(os.path.join(here, 'engine', 'gpu-bench-*.json.xz'))):
    rnd = int(f.split('-')[-1].split('.')[0])
    for b in json.load(lzma.open(f))['benchmarks']:
        if b.get('aggregate_name') == 'median':
            name, backend, v, bones = b['run_name'].replace('/real_time', '').split('/')[:4]
            t.setdefault((int(v), int(bones)), {}).setdefault(f'{name}/{backend}', {})[rnd] = b['real_time']
fmt = lambda d: ' / '.join(f'{d[r]:.1f}' for r in sorted(d))
print('vertices x bones,simd-openmp (16 cores) us,opencl read back us,output on the GPU: copies us,in place us,in place vs simd-openmp')
for (v, bones), r in sorted(t.items()):
    simd, back = r['BM_Skin/simd-openmp'], r['BM_Skin/opencl']
    copies, place = r['BM_SkinDeviceOutput/opencl'], r['BM_SkinDeviceOutputInPlace/opencl']
    ratio = ' / '.join(f'{simd[i] / place[i]:.2f}x' for i in sorted(simd))
    print(f'{v // 1000}k x {bones},{fmt(simd)},{fmt(back)},{fmt(copies)},{fmt(place)},{ratio}')
