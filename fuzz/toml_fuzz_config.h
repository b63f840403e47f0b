// Force-included before host_tools/config.cc in fuzz_config (see CMakeLists.txt):
// toml++ compiled header-only, with its internal assertions off as in Debian's
// release libtomlplusplus.so.
#pragma once
#define TOML_HEADER_ONLY 1
#define TOML_ASSERT(expr) static_cast<void>(0)
