#!/usr/bin/env bash
# Prints one comment line naming the machine, the date and the commit, for the head of a
# benchmark log: timings of hosts with the same core count differ by 2x, so every log says
# which host it was measured on.
set -euo pipefail
cpu=$(sed -n 's/^model name[[:space:]]*: //p' /proc/cpuinfo 2>/dev/null | head -n 1)
family=$(sed -n 's/^cpu family[[:space:]]*: //p' /proc/cpuinfo 2>/dev/null | head -n 1)
model=$(sed -n 's/^model[[:space:]]*: //p' /proc/cpuinfo 2>/dev/null | head -n 1)
commit=$(git -C "$(dirname "$0")/.." rev-parse --short HEAD 2>/dev/null || echo unknown)
echo "# host: ${cpu:-unknown CPU} (family ${family:-?}, model ${model:-?}), $(nproc) logical CPUs; $(date -u '+%Y-%m-%d %H:%M UTC'); commit $commit"
