#!/usr/bin/env bash
# Issue 7's numbers in one run: the frame rates (demo and DoF pipelines,
# sensor path; one thread and all the machine's hardware threads), each
# stage of the demo pipeline alone and the whole pipeline at 640x480 and
# 1920x1080 on one thread and all threads, and every camsim/OpenCV pair with
# its error, ending with the ratio table and the seed paper's baseline.
# Medians of 3 repetitions, run in random order so that a machine whose speed
# drifts slows both sides of a pair alike.
# Run time: 74 benchmarks on a machine of 2 or more hardware threads (51 on
# one; add --benchmark_list_tests to list them) x 3 repetitions of at least
# 0.5 s each. Expect about 4 minutes on 2 cores plus the build: ~3 min timed
# (~0.7 s a repetition, and the first one's iteration estimate), ~30 s of
# set-up and error measurement (the same set at --benchmark_min_time=0.05,
# which shrinks only the timed part, took 46 s).
#   scripts/bench.sh [extra Google Benchmark flags]
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/install-deps.sh
cmake --preset release >/dev/null
cmake --build build/release -j"$(nproc)" --target camsim_bench
./build/release/bench/camsim_bench \
  --benchmark_filter='BM_Pipeline/|BM_PipelineDof|BM_SensorPath|BM_Distortion/|BM_OpenCvRemap|BM_Peer|BM_Stage/' \
  --benchmark_repetitions=3 --benchmark_enable_random_interleaving=true --benchmark_report_aggregates_only=true "$@"
