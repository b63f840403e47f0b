#!/usr/bin/env bash
# Cross-architecture bit-exactness: builds the core (CAMSIM_CORE_ONLY=ON) and
# tests/cross/core_golden for aarch64 and armhf with Debian's cross compilers,
# runs core_golden under qemu-user, and fails unless every hash equals
# tests/cross/core_hashes.txt (generated on x86-64). Build dirs: build/aarch64,
# build/armhf (presets of the same names). On x86-64 it first runs the native
# core-only build's core_golden (build/core-only: AVX-512 without IFMA).
# See docs/portability.md.
#   CAMSIM_CROSS_ARCHS="aarch64" limits it to one architecture.
set -euo pipefail
cd "$(dirname "$0")/.."
# cmake and the host compiler, the two cross compilers, qemu-user (the
# --cross group); nothing to do when scripts/test.sh installed them.
bash scripts/install-deps.sh --cross
jobs=$(nproc)
# x86-64 first: the core-only preset builds the AVX-512 kernels without their
# IFMA copies (-DCAMSIM_NO_IFMA), which the release build, on a CPU with
# IFMA, never runs.
if [ "$(uname -m)" = x86_64 ]; then
  echo "=== x86-64, core only, AVX-512 without IFMA"
  cmake --preset core-only >/dev/null
  cmake --build --preset core-only -j"$jobs" --target core_golden
  ctest --preset core-only
fi
for arch in ${CAMSIM_CROSS_ARCHS:-aarch64 armhf}; do
  echo "=== $arch"
  start=$(date +%s)
  cmake --preset "$arch" >/dev/null
  cmake --build --preset "$arch" -j"$jobs"
  built=$(date +%s)
  # ctest runs core_golden through qemu (CMAKE_CROSSCOMPILING_EMULATOR of the
  # toolchain file); its output lists any differing hash.
  ctest --preset "$arch"
  echo "=== $arch: build $((built - start)) s, core_golden under qemu $(($(date +%s) - built)) s"
done
