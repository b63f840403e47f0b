# Cross build for 32-bit ARM Linux with hard float (Debian armhf: ARMv7-A,
# Thumb-2, VFPv3-D16) with Debian's cross compiler (package
# g++-arm-linux-gnueabihf). Programs are linked statically so that
# qemu-arm (package qemu-user) runs them without a target sysroot; ctest
# runs them through qemu automatically (CMAKE_CROSSCOMPILING_EMULATOR).
# Only the core builds for this target (CAMSIM_CORE_ONLY=ON): OpenEXR, toml++
# and GoogleTest are host-only. Used by the "armhf" preset and scripts/cross.sh.
set(CMAKE_SYSTEM_NAME Linux)
set(CMAKE_SYSTEM_PROCESSOR arm)

set(CMAKE_C_COMPILER arm-linux-gnueabihf-gcc)
set(CMAKE_CXX_COMPILER arm-linux-gnueabihf-g++)

# Look for libraries and headers only in the target's tree, programs on the host.
set(CMAKE_FIND_ROOT_PATH /usr/arm-linux-gnueabihf)
set(CMAKE_FIND_ROOT_PATH_MODE_PROGRAM NEVER)
set(CMAKE_FIND_ROOT_PATH_MODE_LIBRARY ONLY)
set(CMAKE_FIND_ROOT_PATH_MODE_INCLUDE ONLY)
set(CMAKE_FIND_ROOT_PATH_MODE_PACKAGE ONLY)

set(CMAKE_EXE_LINKER_FLAGS_INIT "-static")
set(CMAKE_CROSSCOMPILING_EMULATOR qemu-arm)

# GCC notes that passing some std types changed ABI in GCC 7.1 (-Wpsabi); that
# matters only when mixing objects with pre-7.1 builds, never here.
set(CMAKE_CXX_FLAGS_INIT "-Wno-psabi")
