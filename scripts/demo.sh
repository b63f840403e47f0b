#!/usr/bin/env bash
# Installs what is missing, builds camsim (release) and runs it on the bundled
# 640x480 scene: raw Bayer (out/aisle_0001.raw.pgm), RGB (out/aisle_0001.png)
# and the report (out/report.json).
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/install-deps.sh
cmake --preset release >/dev/null
cmake --build --preset release -j"$(nproc)"
./build/release/host_tools/camsim run --config configs/camera.toml \
  --input scenes/aisle_0001.exr --out out --report out/report.json
