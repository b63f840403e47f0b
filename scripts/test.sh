#!/usr/bin/env bash
# Installs what is missing, builds camsim and runs every test: the release
# build, the whole suite again under AddressSanitizer + UBSan (debug), and
# with clang (same golden hashes from a second compiler). Then the portability
# checks (docs/portability.md): the core linked bare metal for a Cortex-M7
# (scripts/baremetal.sh: no heap, no exceptions, size report) and the core's
# golden hashes on aarch64 and armhf under qemu (scripts/cross.sh).
# CAMSIM_TEST_PRESETS="release" limits the native part to one build;
# CAMSIM_TEST_CROSS=0 leaves out the portability checks; CAMSIM_FUZZ_SECONDS
# sets the short fuzzing run per target (default 20).
set -euo pipefail
cd "$(dirname "$0")/.."
# Everything the whole run needs, in one call before any build: sudo (when
# not root) asks at once, not after the builds when its timeout has passed,
# and apt-get update runs at most once. The later scripts' own calls then
# find nothing missing.
groups=(--native --fuzz)
[ "${CAMSIM_TEST_CROSS:-1}" = 0 ] || groups+=(--baremetal --cross)
bash scripts/install-deps.sh "${groups[@]}"
jobs=$(nproc)
for preset in ${CAMSIM_TEST_PRESETS:-release debug clang}; do
  echo "=== $preset"
  cmake --preset "$preset" >/dev/null
  cmake --build --preset "$preset" -j"$jobs"
  ctest --preset "$preset" -j"$jobs"
done
# Short libFuzzer runs of every target (the long run: scripts/fuzz.sh 600).
echo "=== fuzz (${CAMSIM_FUZZ_SECONDS:-20} s per target)"
bash scripts/fuzz.sh "${CAMSIM_FUZZ_SECONDS:-20}"
if [ "${CAMSIM_TEST_CROSS:-1}" != 0 ]; then
  echo "=== bare metal (Cortex-M7)"
  bash scripts/baremetal.sh
  bash scripts/cross.sh   # last: its ctest summary closes the run
fi
