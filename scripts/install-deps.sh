#!/usr/bin/env bash
# Installs the Debian 12 packages camsim needs, skipping those already present.
# Idempotent: when every package asked for is installed it runs neither sudo
# nor apt-get (so a later call finds nothing to do); root (or sudo) only when
# something is missing, with one apt-get update and one apt-get install.
#   scripts/install-deps.sh              the native build's packages (--native)
#   scripts/install-deps.sh ARG...       the union of these groups and packages:
#     --native     the native build, its tests and benchmarks
#     --fuzz       libFuzzer's runtime for scripts/fuzz.sh (clang's compiler-rt)
#     --cross      scripts/cross.sh: aarch64/armhf cross compilers, qemu-user
#     --baremetal  scripts/baremetal.sh: the arm-none-eabi toolchain and newlib
#     --doc        optional doc tooling, not CI: Aravis's viewer under Xvfb
#                  for scripts/viewer-screenshot.sh
#     PACKAGE      a Debian package by name
# scripts/test.sh asks for every group its run needs in one call at its start,
# so that sudo asks for a password (if at all) before the builds, not after.
set -euo pipefail

native=(
  build-essential clang cmake pkg-config
  libopenexr-dev libimath-dev libpng-dev zlib1g-dev libtomlplusplus-dev
  libgtest-dev libgmock-dev libbenchmark-dev
  libopencv-dev   # test and bench peers only: never linked by the core or the tools
  # camsim-gige: Aravis (its pkg-config file needs libusb-1.0's), its CLI tools, libgpiod v1
  libaravis-dev libusb-1.0-0-dev aravis-tools-cli libgpiod-dev
  iproute2   # scripts/netns-run.sh: 127.0.0.2/.3 for the rig and arv-tool tests (with util-linux's unshare)
)
fuzz=(clang libclang-rt-14-dev)
# The cross compilers bring static glibc (libc6-dev-*-cross); qemu-user gives
# qemu-aarch64 and qemu-arm.
cross=(cmake make g++ g++-aarch64-linux-gnu g++-arm-linux-gnueabihf qemu-user)
baremetal=(cmake make g++ gcc-arm-none-eabi binutils-arm-none-eabi libnewlib-arm-none-eabi
  libstdc++-arm-none-eabi-newlib)
# scripts/viewer-screenshot.sh: arv-viewer-0.8 and the GStreamer elements it
# needs (appsrc/videoconvert, videoflip, gtksink), Xvfb, xdotool, ImageMagick's import.
doc=(
  aravis-tools gstreamer1.0-plugins-base gstreamer1.0-plugins-good gstreamer1.0-gtk3
  xvfb x11-apps xdotool imagemagick
)
[ $# -gt 0 ] || set -- --native
packages=()
for a in "$@"; do
  case "$a" in
    --native) packages+=("${native[@]}") ;;
    --fuzz) packages+=("${fuzz[@]}") ;;
    --cross) packages+=("${cross[@]}") ;;
    --baremetal) packages+=("${baremetal[@]}") ;;
    --doc) packages+=("${doc[@]}") ;;
    -*) echo "install-deps: unknown option $a" >&2; exit 2 ;;
    *) packages+=("$a") ;;
  esac
done
# Each package once, in the order first asked for.
mapfile -t packages < <(printf '%s\n' "${packages[@]}" | awk '!seen[$0]++')

# One dpkg-query for all: the installed ones (status "... ok installed"; it
# exits 1 when it knows a name not at all, hence || true).
installed=$(dpkg-query -W -f='${Package} ${Status}\n' "${packages[@]}" 2>/dev/null |
  awk '$(NF-1) == "ok" && $NF == "installed" {print $1}' || true)
missing=()
for p in "${packages[@]}"; do
  grep -qxF -- "$p" <<<"$installed" || missing+=("$p")
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
