#!/usr/bin/env bash
# Compares two or more camsim_bench binaries (say, before and after a change)
# on a machine whose speed drifts, as a shared VM's does by up to 1.5x within
# minutes: the binaries take turns, ROUNDS times, each run short, and the
# fastest time of each benchmark per binary is printed. Drift slows every
# binary in turn, so the minima compare like with like.
#   scripts/bench-ab.sh FILTER ROUNDS BENCH_A BENCH_B [BENCH_C ...]
# FILTER is a --benchmark_filter regex. Copy each binary aside first (a build
# overwrites build/release/bench/camsim_bench).
set -euo pipefail
if [ $# -lt 4 ]; then
  sed -n '2,9p' "$0"
  exit 2
fi
filter=$1
rounds=$2
shift 2
for ((r = 0; r < rounds; ++r)); do
  for bin in "$@"; do
    # The bench colours its output even with --benchmark_color=false: strip it.
    "$bin" --benchmark_filter="$filter" --benchmark_min_time=0.3 2>/dev/null |
      sed 's/\x1b\[[0-9;]*m//g' | awk -v bin="$bin" '/^BM_/ { print bin, $1, $2, $3 }'
  done
done | awk '
  { key = $2 SUBSEP $1; if (!(key in best) || $3 < best[key]) { best[key] = $3; unit[key] = $4 } runs[key]++ }
  END {
    for (key in best) { split(key, k, SUBSEP); printf "%-60s %-40s %10.3f %s (%d runs)\n", k[1], k[2], best[key], unit[key], runs[key] }
  }' | sort
