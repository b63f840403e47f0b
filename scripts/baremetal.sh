#!/usr/bin/env bash
# Bare metal: builds the core for an Arm Cortex-M7 with arm-none-eabi-g++
# (-mcpu=cortex-m7 -mthumb -mfpu=fpv5-d16 -mfloat-abi=hard -fno-exceptions
# -fno-rtti -Os, newlib-nano, --specs=nosys.specs) and links
# tests/cross/baremetal_main.cc (preset "cortex-m7", build/cortex-m7). Then:
#
#   1. checks the link map and the symbol table: no heap (malloc & co, _sbrk),
#      no operator new / delete, no exception throwing may be linked in;
#   2. checks that check: camsim_baremetal_canary, the same program plus one
#      `new int[]`, must be caught, or the script fails;
#   3. prints a size report: text / data / bss of the program, the core's
#      share of it (from the link map), the largest RAM objects, and the demo
#      pipeline's workspace at 640x480 and 1920x1080 (WorkspaceBytes(), one
#      worker, from a native core-only build: the sizes are the same on
#      32-bit targets, which scripts/cross.sh's armhf run prints).
#
# The program is linked, not run (no board here). The report is also written
# to build/cortex-m7/baremetal-report.txt; docs/portability.md quotes it.
set -euo pipefail
cd "$(dirname "$0")/.."
# The arm-none-eabi toolchain and newlib (the --baremetal group); nothing to
# do when scripts/test.sh installed them.
bash scripts/install-deps.sh --baremetal

jobs=$(nproc)
cmake --preset cortex-m7 >/dev/null
cmake --build --preset cortex-m7 -j"$jobs"
dir=build/cortex-m7/tests/cross
elf=$dir/camsim_baremetal
canary=$dir/camsim_baremetal_canary

# Symbols that must not be in a heap-free, exception-free image (mangled
# names; the map is linked with --no-demangle; size_t is `unsigned int`, j).
forbidden='malloc|_malloc_r|calloc|_calloc_r|realloc|_realloc_r|free|_free_r|memalign|_memalign_r|_sbrk|_sbrk_r'
forbidden+='|_Zn[wa]j[A-Za-z0-9_]*|_Zd[la]Pv[A-Za-z0-9_]*'            # operator new / delete (all forms)
forbidden+='|__cxa_throw|__cxa_allocate_exception|__cxa_begin_catch|__cxa_rethrow|__gxx_personality_v0|_Unwind_Resume'

# Prints every forbidden symbol that program $1 links in, from three sources:
# the map's "Archive member included to satisfy reference by file (symbol)"
# lines, the map's symbol definitions, and nm's defined symbols of the ELF.
# (The map's cross-reference table also names symbols only referenced, e.g.
# newlib's atexit refers to malloc weakly without pulling it in: not counted.)
linked_forbidden() {
  local map="$1.map"
  {
    sed -n '/^Archive member included/,/^Memory Configuration/p' "$map" |
      grep -oE "\(($forbidden)\)$" | tr -d '()' || true
    sed -n '/^Linker script and memory map/,/^Cross Reference Table/p' "$map" |
      grep -E "^ +0x[0-9a-f]+ +($forbidden)$" | awk '{print $2}' || true
    arm-none-eabi-nm --defined-only "$1" | awk '{print $3}' | grep -xE "$forbidden" || true
  } | sort -u
}

status=0
bad=$(linked_forbidden "$elf")
if [ -n "$bad" ]; then
  echo "baremetal: FAIL: $elf links in heap or exception symbols:" $bad
  echo "baremetal: who references them (cross-reference table of $elf.map):"
  for s in $bad; do sed -n '/^Cross Reference Table/,$p' "$elf.map" | grep -A3 -E "^$s( |$)" || true; done
  status=1
else
  echo "baremetal: OK: no malloc / operator new / __cxa_throw (or other heap or exception symbol) in $elf"
fi
caught=$(linked_forbidden "$canary")
if ! grep -qx malloc <<<"$caught" || ! grep -qE '^_Zn[wa]j' <<<"$caught"; then
  echo "baremetal: FAIL: the check missed the canary's operator new (found: ${caught:-nothing}): the check is broken"
  status=1
else
  echo "baremetal: OK: the check catches the canary's allocation:" $caught
fi

# Native core-only build, for WorkspaceBytes() (core_golden --workspace).
cmake --preset core-only >/dev/null
cmake --build --preset core-only -j"$jobs" --target core_golden >/dev/null

# Sums the sizes of the input sections from libcamsim_core.a that the link
# kept, by kind (from the map; section names may stand on a line of their own
# with address, size and file on the next).
core_share() {
  sed -n '/^Linker script and memory map/,/^Cross Reference Table/p' "$1" | awk '
    function hex(s,   i, c, v) { v = 0; s = tolower(substr(s, 3));
      for (i = 1; i <= length(s); i++) { c = index("0123456789abcdef", substr(s, i, 1)) - 1; v = v * 16 + c }
      return v }
    /^ \.[^ ]+$/ { pending = $1; next }
    /^ \.[^ ]+ +0x[0-9a-f]+ +0x[0-9a-f]+ / { name = $1; size = $3; file = $4 }
    /^ +0x[0-9a-f]+ +0x[0-9a-f]+ / && pending != "" { name = pending; size = $2; file = $3 }
    { pending = "" }
    file ~ /libcamsim_core\.a/ && name != "" {
      if (name ~ /^\.(text|rodata)/) text += hex(size);
      else if (name ~ /^\.data/) data += hex(size);
      else if (name ~ /^\.bss/) bss += hex(size);
    }
    { name = ""; file = "" }
    END { printf "%7d %7d %7d   the core (libcamsim_core.a members kept by the linker)\n", text, data, bss }'
}

report=build/cortex-m7/baremetal-report.txt
{
  echo "Bare-metal Cortex-M7 build: bash scripts/baremetal.sh"
  echo "  $(arm-none-eabi-g++ --version | head -1)"
  echo "  flags: $(sed -n 's/^CMAKE_CXX_FLAGS:STRING=//p' build/cortex-m7/CMakeCache.txt)" \
       "$(sed -n 's/^CMAKE_CXX_FLAGS_MINSIZEREL:STRING=//p' build/cortex-m7/CMakeCache.txt)"
  echo "  link:  $(sed -n 's/^CMAKE_EXE_LINKER_FLAGS:STRING=//p' build/cortex-m7/CMakeCache.txt)"
  echo
  echo "arm-none-eabi-size (bytes):"
  echo "   text    data     bss"
  arm-none-eabi-size "$elf" | awk 'NR == 2 {printf "%7d %7d %7d   the whole program\n", $1, $2, $3}'
  core_share "$elf.map"
  echo
  echo "Largest RAM objects (arm-none-eabi-nm; d = .data, b = .bss):"
  arm-none-eabi-nm -S --size-sort -C "$elf" | awk '$3 ~ /^[dDbB]$/' | tail -5 |
    while read -r _ size kind name; do printf "%9d %s %s\n" "$((16#$size))" "$kind" "$name"; done
  echo "  (g_frame: the caller's input frame, 3 x 640 x 480 uint32, in SDRAM on a device;"
  echo "   g_workspace: the static workspace array; g_pipeline*: Pipeline objects)"
  echo
  echo "C/C++ runtime members linked (besides the core and the program):"
  sed -n '/^Archive member included/,/^Memory Configuration/p' "$elf.map" |
    grep -oE 'lib(c_nano|m|gcc|nosys|stdc\+\+_nano|supc\+\+_nano|c|stdc\+\+)\.a\([^)]*\)' | sort -u |
    sed 's/^/  /'
  echo
  echo "Demo pipeline workspace, WorkspaceBytes() for one worker (tables are shared by all workers):"
  ./build/core-only/tests/cross/core_golden --workspace | sed 's/^# /  /'
} > "$report"
cat "$report"
exit $status
