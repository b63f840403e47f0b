#!/usr/bin/env bash
# Issue 7's numbers in one run: the frame rates (demo and DoF pipelines,
# sensor path, 640x480 and 1920x1080, one and two threads), each stage alone,
# and every camsim/OpenCV pair with its error, ending with the ratio table and
# the seed paper's baseline. Medians of 3 repetitions, run in random order
# so that a machine whose speed drifts slows both sides of a pair alike.
#   scripts/bench.sh [extra Google Benchmark flags]
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/install-deps.sh
cmake --preset release >/dev/null
cmake --build build/release -j"$(nproc)" --target camsim_bench
./build/release/bench/camsim_bench \
  --benchmark_filter='BM_Pipeline/|BM_PipelineDof|BM_SensorPath|BM_Distortion/|BM_OpenCvRemap|BM_Peer|BM_Stage/1920/1080/./1/' \
  --benchmark_repetitions=3 --benchmark_enable_random_interleaving=true --benchmark_report_aggregates_only=true "$@"
