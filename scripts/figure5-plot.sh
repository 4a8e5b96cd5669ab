#!/usr/bin/env bash
# Figure 5 today: table and plot from the JSON that scripts/gpu-figure5.sh writes
# (skinserve-bench --benchmark_out). Needs jq and gnuplot.
#   scripts/figure5-plot.sh figure5.json figure5.png > figure5.md
# The table (Markdown, stdout): M vertices/s per backend and grid point, medians; OpenCL
# transfers included, with 4 streams, and kernel only (from profiling events); with
# --device-output's rows, OpenCL with the output left on the GPU (palette upload, kernel and
# the copy into the output buffer, nothing read back: GPU regions). The plot:
# the same at the largest influence count, with the PCIe (device to host, 12 B/vertex)
# and device memory (kernel bytes/vertex) bounds measured in the same run.
set -euo pipefail
json=${1:?usage: figure5-plot.sh BENCH.json OUT.png}
png=${2:?usage: figure5-plot.sh BENCH.json OUT.png}
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT

# One row per (series, vertices, bones): series vertices bones M_vertices_per_second.
jq -r '
  .benchmarks[]
  | select(.run_type == "aggregate" and .aggregate_name == "median")
  | (.run_name | split("/")) as $n
  | if ($n[0] == "BM_Skin") then
      [$n[1], $n[2], $n[3], (.vertices_per_second / 1e6)],
      (if .kernel_vertices_per_second then
         [($n[1] + " kernel only"), $n[2], $n[3], (.kernel_vertices_per_second / 1e6)]
       else empty end)
    elif ($n[0] == "BM_SkinStreams") then
      [($n[1] + " x4 streams"), $n[2], $n[3], (.items_per_second / 1e6)]
    elif ($n[0] == "BM_SkinDeviceOutput") then
      [($n[1] + " output on the GPU"), $n[2], $n[3], (.vertices_per_second / 1e6)]
    elif ($n[0] == "BM_SkinDeviceOutputInPlace") then
      [($n[1] + " output on the GPU, in place"), $n[2], $n[3], (.vertices_per_second / 1e6)]
    else empty end
  | @tsv' "$json" >"$tmp/rates.tsv"
bound() {
  jq -r --arg n "$1" '[.benchmarks[] | select(.run_name == ($n + "/real_time")
    and .aggregate_name == "max") | .bytes_per_second][0] // 0' "$json"
}
d2h=$(bound BM_PcieDeviceToHost)
h2d=$(bound BM_PcieHostToDevice)
copy=$(bound BM_DeviceMemoryCopy)
bmax=$(cut -f3 "$tmp/rates.tsv" | sort -n | tail -1)

echo "PCIe host->device $(awk -v b="$h2d" 'BEGIN{printf "%.1f", b/1e9}') GB/s, device->host" \
  "$(awk -v b="$d2h" 'BEGIN{printf "%.1f", b/1e9}') GB/s (pinned, best of 3); device memory" \
  "copy $(awk -v b="$copy" 'BEGIN{printf "%.0f", b/1e9}') GB/s (read + write)."
echo
series=$(cut -f1 "$tmp/rates.tsv" | awk '!seen[$0]++')
printf '| M vertices/s | %s |\n' "$(cut -f2,3 "$tmp/rates.tsv" | sort -n -k2 -k1 | awk '!s[$0]++' |
  awk '{printf "%s%dk x %d", (NR>1?" | ":""), $1/1000, $2}')"
printf '|---|%s\n' "$(cut -f2,3 "$tmp/rates.tsv" | sort -n -k2 -k1 | awk '!s[$0]++' | awk '{printf "---:|"}')"
while IFS= read -r s; do
  row=$(cut -f2,3 "$tmp/rates.tsv" | sort -n -k2 -k1 | awk '!s[$0]++' | while read -r v b; do
    awk -F'\t' -v s="$s" -v v="$v" -v b="$b" \
      '$1==s && $2==v && $3==b {printf "%.0f", $4; f=1} END{if(!f) printf "-"}' "$tmp/rates.tsv"
    printf ' | '
  done)
  printf '| %s | %s\n' "$s" "${row% | }|"
done <<<"$series"

# Plot: B = bmax, x = vertices.
plotcmd=""
i=0
while IFS= read -r s; do
  awk -F'\t' -v s="$s" -v b="$bmax" '$1==s && $3==b {print $2, $4}' "$tmp/rates.tsv" |
    sort -n >"$tmp/s$i.dat"
  plotcmd+="'$tmp/s$i.dat' using 1:2 with linespoints lt $((i + 1)) lw 2 title '$s', "
  i=$((i + 1))
done <<<"$series"
kernel_bytes=$((bmax * 6 + 24))
plotcmd+="$(awk -v b="$d2h" 'BEGIN{printf "%f", b/12/1e6}') with lines dt 2 lw 2 lc 'black' title 'PCIe device->host bound (12 B/vertex)', "
plotcmd+="$(awk -v b="$copy" -v k="$kernel_bytes" 'BEGIN{printf "%f", b/k/1e6}') with lines dt 4 lw 2 lc 'dark-red' title 'device memory bound ($kernel_bytes B/vertex)'"
gnuplot <<GP
set terminal pngcairo size 1100,700 font ',11'
set output '$png'
set title 'Figure 5 today: skinning rate, ${bmax} influences, positions only'
set logscale xy
set xlabel 'vertices per frame'
set ylabel 'million vertices per second'
set xtics (25000, 100000, 400000, 1600000)
set key outside right
set grid
set xrange [18000:2200000]
set yrange [10:200000]
colors = "#9400d3 #009e73 #56b4e9 #e69f00 #f0c000 #0072b2 #e51e10 #000000 #cc79a7 #808080 #8b4513 #00ced1"
do for [i=1:12] { set linetype i lc rgb word(colors, i) pt i }
plot $plotcmd
GP
