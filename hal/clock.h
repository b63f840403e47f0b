// Monotonic clock for the host side, and an adapter to the core's Clock hook.
#pragma once

#include <chrono>
#include <cstdint>

#include "core/pipeline/pipeline.h"

namespace camsim::hal {

inline uint64_t NowNs() {
  return static_cast<uint64_t>(
      std::chrono::duration_cast<std::chrono::nanoseconds>(std::chrono::steady_clock::now().time_since_epoch())
          .count());
}

// A core Clock whose ticks are nanoseconds.
inline Clock NanosecondClock() {
  Clock c;
  c.now = [](void*) { return NowNs(); };
  return c;
}

}  // namespace camsim::hal
