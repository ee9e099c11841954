#!/usr/bin/env bash
# Two binaries (or two settings) of the real-time drape against each other, as issue 7's
# rounds compare them on a host whose speed swings by 1.5x within minutes: ROUNDS rounds, each
# one run of A and one of B, the order alternating from round to round (A first in odd rounds),
# then the medians, ranges and the median of the per-round ratios B/A. A single pair of runs,
# or medians of runs taken one after the other, can mislead by the host's swings alone.
#
# Each side is BINARY@RES@SETTING, SETTING as scripts/realtime-series.sh takes it, e.g.
#   scripts/realtime-ab.sh 8 /tmp/old@512@6:0:chains:1:2:3:rows target/release/cloth@512@4:0:chains:1:2:5:rows
# (LIMIT, SCENE, EXTRA and KERNEL pass through to realtime-series.sh; 2 threads, 3 s).
# Prints every run's line of realtime-series.sh after its label, then the summary.
# Usage: [LIMIT=0.02] scripts/realtime-ab.sh ROUNDS BINARY@RES@SETTING BINARY@RES@SETTING
set -euo pipefail
if [ $# -ne 3 ]; then
  echo "usage: $0 ROUNDS BINARY@RES@SETTING BINARY@RES@SETTING" >&2
  exit 2
fi
rounds=$1
case $rounds in
  '' | *[!0-9]*) echo "ROUNDS must be a positive whole number, got '$rounds'" >&2; exit 2 ;;
esac
if [ "$rounds" -lt 1 ]; then
  echo "ROUNDS must be at least 1, got $rounds" >&2
  exit 2
fi
here=$(dirname "$0")
out=$(mktemp)
trap 'rm -f "$out"' EXIT
run() {
  local label=$1 spec=$2
  local bin=${spec%%@*} rest=${spec#*@}
  local res=${rest%%@*} setting=${rest#*@}
  if [ "$bin" = "$spec" ] || [ "$res" = "$rest" ]; then
    echo "a side is BINARY@RES@SETTING, got '$spec'" >&2
    exit 2
  fi
  local line
  line=$(CLOTH=$bin "$here/realtime-series.sh" "$res" 3 2 "$setting" | tail -n 1)
  echo "$label $line" | tee -a "$out"
}
"$here/host-line.sh"
echo "# A = $2"
echo "# B = $3"
for i in $(seq "$rounds"); do
  if [ $((i % 2)) = 1 ]; then
    run "round $i A" "$2"
    run "round $i B" "$3"
  else
    run "round $i B" "$3"
    run "round $i A" "$2"
  fi
done
python3 - "$out" <<'PY'
import statistics, sys
ms = {"A": {}, "B": {}}
for line in open(sys.argv[1]):
    f = line.split()
    # "round i A|B", then realtime-series.sh's columns: ms/frame is its 8th.
    ms[f[2]][int(f[1])] = float(f[10])
for side in "AB":
    v = list(ms[side].values())
    print(f"# {side}: median {statistics.median(v):.2f} ms/frame ({min(v):.2f}-{max(v):.2f}) over {len(v)} rounds")
ratios = [ms["B"][i] / ms["A"][i] for i in ms["A"] if i in ms["B"]]
print(f"# B/A per round: median {statistics.median(ratios):.3f} ({min(ratios):.3f}-{max(ratios):.3f})")
PY
