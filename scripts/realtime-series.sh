#!/usr/bin/env bash
# The real-time drape series of issue 7 (docs/performance.md): the drape scene with XPBD at
# RES x RES, for each "SUBSTEPS:LEVELS" setting, SECONDS simulated on THREADS threads;
# prints ms per 1/60 s frame (median) and the structural strain percentiles at the end.
# The scene's global damping (F = -d·v per particle, d = 2e-4 kg/s at its native 48²) is
# scaled by (48/RES)² so that the cloth's total damping, and so its fall, is the same at every
# resolution (unscaled, 512² would fall at its terminal speed of 5 cm/s and never drape).
# A setting SUBSTEPS:LEVELS:chains also solves the structural springs chain by chain
# (xpbd.chains = true); a fourth field sets the sweeps per substep (default 1), e.g. 10:0:chains:2
# (or 10:0:plain:2 without chains), and a fifth the Newton iterations of each chain solve
# (xpbd.chain_iterations, default 1), e.g. 10:0:chains:1:3, and a sixth the rounds of chain
# solves per sweep (xpbd.chain_rounds, default 1), e.g. 6:0:chains:1:2:2, and a seventh
# `shear` to solve the shear springs as chains along the diagonals (xpbd.shear_chains), e.g.
# 20:0:chains:1:1:1:shear, or `rows` to sweep them row by row (xpbd.shear_rows, as the real-time
# settings do), e.g. 3:0:chains:1:2:2:rows (issue 7's 256² setting), and an eighth the relaxation
# of the chain solves (xpbd.chain_relaxation, default 1; `-` in the seventh field for neither
# shear option), e.g. 4:0:chains:1:2:4:rows:1.3 (issue 7's 512² setting; the last column).
# The last column is the springs' elastic energy at the end (J): a drape that found its shape
# stores little (0.2 J at 256² with 24 substeps), one whose cells collapsed in shear much more.
# p99.9% and max% are the strain of the last frame; late_max% is the largest structural strain of
# any frame over the second half of the run (the drape settled: "stays under 10 % once draped"),
# and late_shear% the same for the shear diagonals' stretch (a drape whose cells collapsed in
# shear, a "fishnet", stretches one diagonal of each collapsed cell by 30-40 %; the converged
# drape by at most about 10 %).
# SCENE=file.toml runs another scene (default: the built-in drape); EXTRA=KEY=VALUE adds one
# more --set (e.g. EXTRA='material.shear={stiffness=1e-6,damping=0.0}'); LIMIT=0.02 sets the
# structural strain limit (xpbd.structural_limit) of every setting (the last column).
# Usage: [KERNEL=reference] [LIMIT=0.02] scripts/realtime-series.sh RES SECONDS THREADS SUBSTEPS:LEVELS[:chains[:SWEEPS[:NEWTON[:ROUNDS[:shear|rows|-[:RELAXATION]]]]]]...
set -euo pipefail
res=$1 seconds=$2 threads=$3
shift 3
bin=${CLOTH:-target/release/cloth}
out=$(mktemp -d)
damping=$(python3 -c "print(repr(2e-4 * (48 / $res) ** 2))")
"$(dirname "$0")/host-line.sh"
printf '%-6s %-9s %-6s %-7s %-7s %-6s %-6s %12s %9s %9s %9s %9s %12s %10s %10s %11s %6s %6s\n' res substeps sweeps levels chains newton rounds ms/frame p50% p99% p99.9% max% penetration E_spring/J late_max% late_shear% limit relax
for setting in "$@"; do
  IFS=: read -r substeps levels mode sweeps newton rounds shear relax <<<"$setting"
  newton=${newton:-1}
  # chain_rounds only when asked for (binaries before it reject the key).
  with_rounds=${rounds:+,chain_rounds=$rounds}
  rounds=${rounds:-1}
  # shear_chains only when asked for (binaries before it reject the key).
  with_shear=
  [ "${shear:-}" = shear ] && with_shear=,shear_chains=true
  # shear_rows only when asked for (binaries before it reject the key).
  [ "${shear:-}" = rows ] && with_shear=,shear_rows=true
  # chain_relaxation only when asked for (binaries before it reject the key).
  with_relax=${relax:+,chain_relaxation=$relax}
  # structural_limit only when asked for (binaries before it reject the key).
  with_limit=${LIMIT:+,structural_limit=$LIMIT}
  sweeps=${sweeps:-1}
  chains=false
  [ "${mode:-}" = chains ] && chains=true
  "$bin" sim "${SCENE:-drape}" --resolution "$res" --seconds "$seconds" --threads "$threads" ${KERNEL:+--kernel "$KERNEL"} \
    --set 'solver.kind="xpbd"' --set "solver.substeps=$substeps" --set "forces.damping=$damping" \
    --set "solver.xpbd={iterations=$sweeps,hierarchy_levels=$levels,chains=$chains,chain_iterations=$newton$with_rounds$with_shear$with_limit$with_relax}" \
    ${EXTRA:+--set "$EXTRA"} --report "$out/r.json" >/dev/null
  python3 - "$out/r.json" "$res" "$substeps" "$levels" "$chains${shear:+,$shear}" "$sweeps" "$newton" "$rounds" "${LIMIT:--}" "${relax:-1}" <<'PY'
import json, sys
r = json.load(open(sys.argv[1]))
q = r["final_structural_strain"]
late = r["frames"][len(r["frames"]) // 2:]
pen = max(f["max_penetration"] for f in late)
late_max = max(f["max_strain"]["structural"] for f in late)
late_shear = max(f["max_strain"]["shear"] for f in late)
print(f'{sys.argv[2]:<6} {sys.argv[3]:<9} {sys.argv[6]:<6} {sys.argv[4]:<7} {sys.argv[5]:<7} {sys.argv[7]:<6} {sys.argv[8]:<6} {r["median_frame_ms"]:12.2f} '
      f'{100*q["p50"]:9.3f} {100*q["p99"]:9.3f} {100*q["p99_9"]:9.3f} {100*q["max"]:9.3f} {pen:12.2e} {r["frames"][-1]["spring_energy"]:10.3f} {100*late_max:10.3f} {100*late_shear:11.3f} {sys.argv[9]:>6} {sys.argv[10]:>6}')
PY
done
rm -rf "$out"
