# Bare-metal build for an Arm Cortex-M7 with double-precision FPU (e.g. STM32F7
# / STM32H7, i.MX RT1060) using Debian's arm-none-eabi GCC and newlib (packages
# gcc-arm-none-eabi, libstdc++-arm-none-eabi-newlib, libnewlib-arm-none-eabi).
# No operating system and no heap: the core must link without malloc,
# operator new or exceptions. Used by the "cortex-m7" preset and
# scripts/baremetal.sh, which builds camsim_core and tests/cross/baremetal_main.cc
# (core only: configure with CAMSIM_CORE_ONLY=ON).
set(CMAKE_SYSTEM_NAME Generic)
set(CMAKE_SYSTEM_PROCESSOR arm)

set(CMAKE_C_COMPILER arm-none-eabi-gcc)
set(CMAKE_CXX_COMPILER arm-none-eabi-g++)
# CMake's compiler checks cannot link a program without a board's startup
# code and linker script: let them build a static library instead.
set(CMAKE_TRY_COMPILE_TARGET_TYPE STATIC_LIBRARY)

# The target, and the embedded ground rules: no exceptions, no RTTI. Function
# and data sections let the linker drop what is unused (--gc-sections), as
# firmware builds do, so the size report counts only what is reachable.
set(CMAKE_CXX_FLAGS_INIT
    "-mcpu=cortex-m7 -mthumb -mfpu=fpv5-d16 -mfloat-abi=hard -fno-exceptions -fno-rtti -ffunction-sections -fdata-sections")
# newlib with stub system calls (nosys): links without any OS. nano.specs
# selects newlib-nano, the small C library firmware uses.
set(CMAKE_EXE_LINKER_FLAGS_INIT "--specs=nano.specs --specs=nosys.specs -Wl,--gc-sections")

set(CMAKE_FIND_ROOT_PATH /usr/lib/arm-none-eabi)
set(CMAKE_FIND_ROOT_PATH_MODE_PROGRAM NEVER)
set(CMAKE_FIND_ROOT_PATH_MODE_LIBRARY ONLY)
set(CMAKE_FIND_ROOT_PATH_MODE_INCLUDE ONLY)
set(CMAKE_FIND_ROOT_PATH_MODE_PACKAGE ONLY)
