#!/usr/bin/env bash
# Installs what is missing, builds camsim and runs every test: the release
# build, then the whole suite again under AddressSanitizer + UBSan (debug).
# CAMSIM_TEST_PRESETS="release" limits it to one build.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/install-deps.sh
jobs=$(nproc)
for preset in ${CAMSIM_TEST_PRESETS:-release debug}; do
  echo "=== $preset"
  cmake --preset "$preset" >/dev/null
  cmake --build --preset "$preset" -j"$jobs"
  ctest --preset "$preset" -j"$jobs"
done
