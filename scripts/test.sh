#!/usr/bin/env bash
# Installs what is missing, builds camsim and runs every test: the release
# build, the whole suite again under AddressSanitizer + UBSan (debug), and
# with clang (same golden hashes from a second compiler).
# CAMSIM_TEST_PRESETS="release" limits it to one build.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/install-deps.sh
jobs=$(nproc)
for preset in ${CAMSIM_TEST_PRESETS:-release debug clang}; do
  echo "=== $preset"
  cmake --preset "$preset" >/dev/null
  cmake --build --preset "$preset" -j"$jobs"
  ctest --preset "$preset" -j"$jobs"
done
