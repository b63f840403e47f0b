// camsim-trigger: fires pulses on a loopback trigger bus (hal/gpio.h,
// "unix:DIR") so the camsim-gige cameras of a rig take the same frames.
#include <time.h>

#include <cerrno>
#include <cstdio>
#include <cstdlib>
#include <string>

#include "hal/gpio.h"

namespace {

const char kUsage[] =
    "usage: camsim-trigger unix:DIR [--count K] [--first-index N] [--interval-ms MS]\n"
    "                      [--width-ms W | --width-us U]\n"
    "  Sends K pulses (a rising edge, W ms or U us later a falling edge; one\n"
    "  every MS ms) to every camera whose --trigger-line is unix:DIR. Pulse k\n"
    "  carries frame index N + k: with TriggerMode On, TriggerSource Line0 each\n"
    "  camera renders that frame, so the rig stays on one frame index even if a\n"
    "  camera missed a pulse. Each edge is stamped with its scheduled time (the\n"
    "  first rising edge's plus k MS, plus the width), so ExposureMode\n"
    "  TriggerWidth exposes exactly the width. Defaults: K 1, N 0, MS 100, W 1.\n";

bool ParseInt(const char* s, long long min, long long max, long long* out) {
  char* end = nullptr;
  errno = 0;
  const long long v = std::strtoll(s, &end, 10);
  if (errno != 0) return false;
  if (!*s || *end || v < min || v > max) return false;
  *out = v;
  return true;
}

}  // namespace

int main(int argc, char** argv) {
  std::string bus;
  long long count = 1, first = 0, interval_ms = 100, width_ms = -1, width_us = -1;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--help" || a == "-h") {
      std::fputs(kUsage, stdout);
      return 0;
    }
    if (a.rfind("--", 0) != 0) {
      if (!bus.empty()) {
        std::fprintf(stderr, "camsim-trigger: one bus only ('%s' and '%s')\n%s", bus.c_str(), a.c_str(), kUsage);
        return 1;
      }
      bus = a;
      continue;
    }
    long long* target = a == "--count"         ? &count
                        : a == "--first-index" ? &first
                        : a == "--interval-ms" ? &interval_ms
                        : a == "--width-ms"    ? &width_ms
                        : a == "--width-us"    ? &width_us
                                               : nullptr;
    if (!target) {
      std::fprintf(stderr, "camsim-trigger: unknown option '%s'\n%s", a.c_str(), kUsage);
      return 1;
    }
    // Ranges: frame indices are 31-bit (SimFrameIndex); an hour at most between pulses.
    const long long min = target == &count ? 1 : 0;
    const long long max = target == &first       ? 0x7fffffffLL
                          : target == &count     ? 1000000LL
                          : target == &width_us ? 3600000000LL
                                                 : 3600000LL;
    if (i + 1 >= argc || !ParseInt(argv[i + 1], min, max, target)) {
      std::fprintf(stderr, "camsim-trigger: %s needs an integer %lld..%lld\n", a.c_str(), min, max);
      return 1;
    }
    ++i;
  }
  if (bus.empty()) {
    std::fputs(kUsage, stderr);
    return 1;
  }
  if (width_ms >= 0 && width_us >= 0) {
    std::fprintf(stderr, "camsim-trigger: give --width-ms or --width-us, not both\n");
    return 1;
  }
  const long long width_ns = width_us >= 0 ? width_us * 1000 : (width_ms >= 0 ? width_ms : 1) * 1000000;
  const long long interval_ns = interval_ms * 1000000;
  if (width_ns >= interval_ns && count > 1) {
    std::fprintf(stderr, "camsim-trigger: the width (%lld us) must be shorter than --interval-ms (%lld)\n",
                 width_ns / 1000, interval_ms);
    return 1;
  }
  std::string error;
  auto line = camsim::hal::OpenBusOutput(bus, &error);
  if (!line) {
    std::fprintf(stderr, "camsim-trigger: %s\n", error.c_str());
    return 1;
  }
  // Each edge at its scheduled time on CLOCK_MONOTONIC, stamped with it
  // (BusOutput::SetAt): a late wake delays the edge's sending, not its time.
  const auto edge = [&](bool high, long long at_ns) {
    const timespec at{static_cast<time_t>(at_ns / 1000000000), static_cast<long>(at_ns % 1000000000)};
    while (clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &at, nullptr) == EINTR) {
    }
    if (line->SetAt(high, at_ns, &error)) return true;
    std::fprintf(stderr, "camsim-trigger: %s\n", error.c_str());
    return false;
  };
  const long long start_ns = camsim::hal::MonotonicNowNs();
  for (long long k = 0; k < count; ++k) {
    const long long rise_ns = start_ns + k * interval_ns;
    line->SetEdgeIndex(static_cast<uint32_t>((first + k) & 0x7fffffff));
    if (!edge(true, rise_ns)) return 1;
    const int receivers = line->last_receivers();
    if (!edge(false, rise_ns + width_ns)) return 1;
    std::printf("pulse %lld: frame index %lld, %d camera(s)\n", k, (first + k) & 0x7fffffff, receivers);
    std::fflush(stdout);
  }
  return 0;
}
