#!/usr/bin/env bash
# Issue 7's scaling series: the peer scene (Taichi's cloth on a ball, the peer's formulas at
# each n: h = 0.04/n, stiffness ∝ n) at n = 32 … 512, the SAME simulated window at every n
# (FRAMES frames of 1/60 s), 1 and 2 threads; prints particle-substeps/s of the median frame
# and the per-particle throughput relative to 128².
# Usage: scripts/scaling-series.sh FRAMES [N...]   (default N: 32 64 128 256 512)
set -euo pipefail
frames=$1
shift
sizes=("${@:-32 64 128 256 512}")
read -r -a sizes <<< "${sizes[*]}"
bin=${CLOTH:-target/release/cloth}
out=$(mktemp -d)
"$(dirname "$0")/host-line.sh"
printf '%-5s %-9s %-7s %-8s %14s %14s\n' n substeps frames status "1 thread" "2 threads"
for n in "${sizes[@]}"; do
  mapfile -t sets < <(python3 "$(dirname "$0")/peer-params.py" "$n")
  args=()
  for s in "${sets[@]}"; do args+=(--set "$s"); done
  res=()
  status=ok
  for t in 1 2; do
    "$bin" sim peer-ball "${args[@]}" --frames "$frames" --threads "$t" --report "$out/r.json" \
      >/dev/null 2>&1 || true
    res+=("$(python3 -c "import json; r = json.load(open('$out/r.json')); print('%.3e %s %d' % (r['median_frame_particle_substeps_per_second'], r['status'] if isinstance(r['status'], str) else 'unstable', len(r['frames'])))")")
  done
  read -r t1 s1 f1 <<< "${res[0]}"
  read -r t2 _ _ <<< "${res[1]}"
  printf '%-5s %-9s %-7s %-8s %14s %14s\n' "$n" "$(python3 -c "print(int((1/60)/(0.04/$n)))")" "$f1" "$s1" "$t1" "$t2"
done
rm -rf "$out"
