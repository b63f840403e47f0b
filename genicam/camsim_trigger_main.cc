// camsim-trigger: fires pulses on a loopback trigger bus (hal/gpio.h,
// "unix:DIR") so the camsim-gige cameras of a rig take the same frames.
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <thread>

#include "hal/gpio.h"

namespace {

const char kUsage[] =
    "usage: camsim-trigger unix:DIR [--count K] [--first-index N] [--interval-ms MS] [--width-ms W]\n"
    "  Sends K pulses (a rising edge, W ms later a falling edge; one every MS ms)\n"
    "  to every camera whose --trigger-line is unix:DIR. Pulse k carries frame\n"
    "  index N + k: with TriggerMode On, TriggerSource Line0 each camera renders\n"
    "  that frame, so the rig stays on one frame index even if a camera missed\n"
    "  a pulse. Defaults: K 1, N 0, MS 100, W 1.\n";

bool ParseInt(const char* s, long min, long max, long* out) {
  char* end = nullptr;
  const long v = std::strtol(s, &end, 10);
  if (!*s || *end || v < min || v > max) return false;
  *out = v;
  return true;
}

}  // namespace

int main(int argc, char** argv) {
  std::string bus;
  long count = 1, first = 0, interval_ms = 100, width_ms = 1;
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
    long* target = a == "--count" ? &count : a == "--first-index" ? &first : a == "--interval-ms" ? &interval_ms
                 : a == "--width-ms" ? &width_ms : nullptr;
    if (!target) {
      std::fprintf(stderr, "camsim-trigger: unknown option '%s'\n%s", a.c_str(), kUsage);
      return 1;
    }
    // Ranges: frame indices are 31-bit (SimFrameIndex); an hour at most between pulses.
    const long min = target == &count ? 1 : 0;
    const long max = target == &first ? 0x7fffffffL : target == &count ? 1000000L : 3600000L;
    if (i + 1 >= argc || !ParseInt(argv[i + 1], min, max, target)) {
      std::fprintf(stderr, "camsim-trigger: %s needs an integer %ld..%ld\n", a.c_str(), min, max);
      return 1;
    }
    ++i;
  }
  if (bus.empty()) {
    std::fputs(kUsage, stderr);
    return 1;
  }
  if (width_ms >= interval_ms && count > 1) {
    std::fprintf(stderr, "camsim-trigger: --width-ms (%ld) must be shorter than --interval-ms (%ld)\n", width_ms,
                 interval_ms);
    return 1;
  }
  std::string error;
  auto line = camsim::hal::OpenBusOutput(bus, &error);
  if (!line) {
    std::fprintf(stderr, "camsim-trigger: %s\n", error.c_str());
    return 1;
  }
  for (long k = 0; k < count; ++k) {
    const auto t0 = std::chrono::steady_clock::now();
    line->SetEdgeIndex(static_cast<uint32_t>((first + k) & 0x7fffffff));
    if (!line->Set(true, &error)) {
      std::fprintf(stderr, "camsim-trigger: %s\n", error.c_str());
      return 1;
    }
    const int receivers = line->last_receivers();
    std::this_thread::sleep_for(std::chrono::milliseconds(width_ms));
    if (!line->Set(false, &error)) {
      std::fprintf(stderr, "camsim-trigger: %s\n", error.c_str());
      return 1;
    }
    std::printf("pulse %ld: frame index %ld, %d camera(s)\n", k, (first + k) & 0x7fffffff, receivers);
    std::fflush(stdout);
    if (k + 1 < count) std::this_thread::sleep_until(t0 + std::chrono::milliseconds(interval_ms));
  }
  return 0;
}
