#!/usr/bin/env bash
# Installs the Debian 12 packages camsim needs, skipping those already present.
# Idempotent; needs root (or sudo) only when something is missing.
#   scripts/install-deps.sh              the native build's packages
#   scripts/install-deps.sh PACKAGE...   these instead (scripts/cross.sh and
#                                        scripts/baremetal.sh pass their toolchains)
#   scripts/install-deps.sh --doc        optional doc tooling, not CI: Aravis's viewer
#                                        under Xvfb for scripts/viewer-screenshot.sh
set -euo pipefail

packages=(
  build-essential clang cmake pkg-config
  libopenexr-dev libimath-dev libpng-dev zlib1g-dev libtomlplusplus-dev
  libgtest-dev libgmock-dev libbenchmark-dev
  libopencv-dev   # test and bench peers only: never linked by the core or the tools
  # camsim-gige: Aravis (its pkg-config file needs libusb-1.0's), its CLI tools, libgpiod v1
  libaravis-dev libusb-1.0-0-dev aravis-tools-cli libgpiod-dev
  iproute2   # scripts/netns-run.sh: 127.0.0.2/.3 for the rig and arv-tool tests (with util-linux's unshare)
)
# scripts/viewer-screenshot.sh: arv-viewer-0.8 and the GStreamer elements it
# needs (appsrc/videoconvert, videoflip, gtksink), Xvfb, xdotool, ImageMagick's import.
doc_packages=(
  aravis-tools gstreamer1.0-plugins-base gstreamer1.0-plugins-good gstreamer1.0-gtk3
  xvfb x11-apps xdotool imagemagick
)
if [ "${1:-}" = "--doc" ]; then packages=("${doc_packages[@]}")
elif [ $# -gt 0 ]; then packages=("$@"); fi

missing=()
for p in "${packages[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [ ${#missing[@]} -eq 0 ]; then
  echo "install-deps: all ${#packages[@]} packages present"
  exit 0
fi
echo "install-deps: installing ${missing[*]}"
SUDO=""
[ "$(id -u)" -eq 0 ] || SUDO="sudo"
export DEBIAN_FRONTEND=noninteractive
$SUDO apt-get update -qq
$SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}"
