# Cross build for 64-bit ARM Linux (aarch64) with Debian's cross compiler
# (package g++-aarch64-linux-gnu). Programs are linked statically so that
# qemu-aarch64 (package qemu-user) runs them without a target sysroot; ctest
# runs them through qemu automatically (CMAKE_CROSSCOMPILING_EMULATOR).
# Only the core builds for this target (CAMSIM_CORE_ONLY=ON): OpenEXR, toml++
# and GoogleTest are host-only. Used by the "aarch64" preset and scripts/cross.sh.
set(CMAKE_SYSTEM_NAME Linux)
set(CMAKE_SYSTEM_PROCESSOR aarch64)

set(CMAKE_C_COMPILER aarch64-linux-gnu-gcc)
set(CMAKE_CXX_COMPILER aarch64-linux-gnu-g++)

# Look for libraries and headers only in the target's tree, programs on the host.
set(CMAKE_FIND_ROOT_PATH /usr/aarch64-linux-gnu)
set(CMAKE_FIND_ROOT_PATH_MODE_PROGRAM NEVER)
set(CMAKE_FIND_ROOT_PATH_MODE_LIBRARY ONLY)
set(CMAKE_FIND_ROOT_PATH_MODE_INCLUDE ONLY)
set(CMAKE_FIND_ROOT_PATH_MODE_PACKAGE ONLY)

set(CMAKE_EXE_LINKER_FLAGS_INIT "-static")
set(CMAKE_CROSSCOMPILING_EMULATOR qemu-aarch64)
