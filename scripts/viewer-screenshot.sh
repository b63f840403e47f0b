#!/usr/bin/env bash
# Takes docs/images/arv-viewer.png: Aravis's viewer (arv-viewer-0.8) showing
# camsim-gige serving the bundled scene, under a virtual X server (Xvfb).
# Needs the optional doc tooling: scripts/install-deps.sh --doc
# and a release build (camsim-gige).
#   scripts/viewer-screenshot.sh [OUT.png]
set -euo pipefail
cd "$(dirname "$0")/.."
out=${1:-docs/images/arv-viewer.png}
gige=${CAMSIM_BUILD_DIR:-build/release}/genicam/camsim-gige
for tool in "$gige" arv-viewer-0.8 arv-tool-0.8 xvfb-run xdotool import; do
  command -v "$tool" >/dev/null || { echo "viewer-screenshot: '$tool' not found (scripts/install-deps.sh --doc; cmake --build build/release --target camsim-gige)" >&2; exit 1; }
done

if [ "${1:-}" != "--inside-xvfb" ]; then
  exec xvfb-run -a -s "-screen 0 1024x768x24" "$0" --inside-xvfb "$out"
fi
out=$2
log=$(mktemp -d)
# The camera on 127.0.0.1 (the viewer finds it by discovery), RGB8 so the
# viewer shows the ISP's output as camsim run's PNG would.
"$gige" --config configs/camera.toml --input scenes/aisle_0001.exr --address 127.0.0.1 --serial CS0001 \
  >"$log/gige.log" 2>&1 &
gige_pid=$!
viewer_pid=""
cleanup() {
  [ -n "$viewer_pid" ] && kill "$viewer_pid" 2>/dev/null || true
  kill "$gige_pid" 2>/dev/null || true
  wait 2>/dev/null || true
}
trap cleanup EXIT
for _ in $(seq 50); do arv-tool-0.8 -a 127.0.0.1 control PixelFormat=RGB8 >/dev/null 2>&1 && break; sleep 0.1; done
arv-viewer-0.8 >"$log/viewer.log" 2>&1 &
viewer_pid=$!
win=$(xdotool search --sync --name "Aravis Viewer" | head -1)
sleep 2  # the camera list is filled by discovery
# Window-relative positions in arv-viewer 0.8.26's GTK layout at its default
# size: the second row of the camera list (the first is Aravis's own "Fake"),
# then the play button that appears under the list once a camera is selected.
xdotool mousemove --window "$win" 150 117 click 1
sleep 1.5
xdotool mousemove --window "$win" 78 277 click 1
sleep 4  # frames arrive; the status bar shows fps and the image count
import -window "$win" "$out"
kill "$viewer_pid"; viewer_pid=""
kill -INT "$gige_pid"; wait "$gige_pid" || true
sent=$(sed -n 's/.*: \([0-9]*\) frames sent.*/\1/p' "$log/gige.log")
if [ -z "$sent" ] || [ "$sent" -eq 0 ]; then
  echo "viewer-screenshot: the viewer took no frames (see $log)" >&2
  exit 1
fi
echo "viewer-screenshot: $out ($sent frames served)"
rm -rf "$log"
