#!/usr/bin/env bash
# The peer benchmark, interleaved: each round runs the peers (Taichi on 2 threads and 1
# thread, the naive C++ baseline; ../shared/peer/run.sh) and then `cloth sim` on the same
# scene with 1 and 2 threads, so that all figures of a round share the machine's state.
# Prints every figure, then the medians over the rounds and the ratios.
#
# usage: scripts/peer-compare.sh [N=128] [ROUNDS=3] [SECONDS=8]
#   CLOTH=path/to/cloth (default target/release/cloth), PEER=path/to/run.sh
#   (default ../shared/peer/run.sh next to the repository, else /work/shared/peer/run.sh)
#
# The scene at n != 128 is the peer's formulas at that n (spacing 1/n, k = Y/L0, c = 1e4/n,
# dt = 0.04/n, floor((1/60)/dt) substeps per frame), passed to `cloth sim peer-ball` as
# --set overrides, exactly what `cloth_core::presets::peer_ball(n)` builds.
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
n=${1:-128} rounds=${2:-3} seconds=${3:-8}
cloth=${CLOTH:-$root/target/release/cloth}
peer=${PEER:-}
if [[ -z $peer ]]; then
  for p in "$root/../shared/peer/run.sh" /work/shared/peer/run.sh; do
    [[ -x $p ]] && peer=$p && break
  done
fi
[[ -x $cloth ]] || { echo "no cloth binary at $cloth (cargo build --release)" >&2; exit 2; }
[[ -n $peer ]] || { echo "no peer run.sh found; set PEER=" >&2; exit 2; }

# The peer scene at n as --set overrides (python3 for the f32-exact decimal forms).
mapfile -t sets < <(python3 "$(dirname "$0")/peer-params.py" "$n")
args=()
for s in "${sets[@]}"; do args+=(--set "$s"); done

# Frames for roughly `seconds` of wall time at ~4e7 particle-substeps/s, at least 20.
substeps=$(python3 -c "print(int((1/60)/(0.04/$n)))")
frames=$(python3 -c "print(max(20, int($seconds * 4e7 / ($n * $n * $substeps))))")
# At n <= 64 the peer's own parameters are unstable for symplectic Euler (the peers reset
# the cloth when it blows up): time the frames before that.
if (( n <= 64 )); then frames=12; fi

"$(dirname "$0")/host-line.sh"
log=$(mktemp)
for r in $(seq 1 "$rounds"); do
  echo "== round $r/$rounds (n = $n)"
  "$peer" "$n" "$seconds" 2>&1 | tee -a "$log" | grep -E '^(taichi|c\+\+)|median' || true
  for t in 1 2; do
    out=$("$cloth" sim peer-ball "${args[@]}" --frames "$frames" --threads "$t" \
      --report "$log.json" 2>&1 | grep "^done:" | tail -1 || true)
    med=$(python3 -c "import json; print('%.4g' % json.load(open('$log.json'))['median_frame_particle_substeps_per_second'])")
    echo "cloth threads=$t median-frame: $med   ($out)"
    echo "cloth threads=$t median-frame: $med" >> "$log"
  done
done

python3 - "$log" "$n" <<'EOF'
import re, statistics, sys
lines = open(sys.argv[1]).read().splitlines()
runs = {}
who = None
for l in lines:
    m = re.match(r'(taichi|c\+\+) .*threads=(\S+)', l)
    if m:
        who = f"{m.group(1)} threads={m.group(2)}"
        continue
    m = re.search(r'median-frame: ([0-9.e+]+)', l)
    if m and l.startswith('cloth'):
        runs.setdefault(l.split(' median')[0], []).append(float(m.group(1)))
    elif m and who:
        runs.setdefault(who, []).append(float(m.group(1)))
        who = None
med = {k: statistics.median(v) for k, v in runs.items()}
print(f"\n== medians over rounds, n = {sys.argv[2]} (particle-substeps/s, median frame)")
for k, v in sorted(med.items()):
    print(f"{k:24} {v:10.3e}   runs: {', '.join('%.3g' % x for x in runs[k])}")
c1, c2 = med.get('cloth threads=1'), med.get('cloth threads=2')
cpp, ti2, ti1 = med.get('c++ threads=1'), med.get('taichi threads=default'), med.get('taichi threads=1')
if c1 and cpp: print(f"cloth 1 thread / naive C++      = {c1 / cpp:6.2f}x")
if c2 and ti2: print(f"cloth 2 threads / Taichi 2 thr. = {c2 / ti2:6.2f}x")
if c1 and ti1: print(f"cloth 1 thread / Taichi 1 thr.  = {c1 / ti1:6.2f}x")
if c1 and c2: print(f"cloth 2 threads / 1 thread      = {c2 / c1:6.2f}x")
EOF
rm -f "$log" "$log.json"
