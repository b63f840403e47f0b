// libgpiod v1 backend of hal/gpio.h.
#include <gpiod.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cstdlib>
#include <cstring>
#include <ctime>

#include "hal/gpio.h"

namespace camsim::hal {
namespace {

std::string Reason() { return std::strerror(errno); }

struct Opened {
  gpiod_chip* chip = nullptr;
  gpiod_line* line = nullptr;
};

bool Open(const std::string& spec, Opened* out, std::string* error) {
  std::string chip;
  unsigned offset = 0;
  if (!ParseLineSpec(spec, &chip, &offset, error)) return false;
  errno = 0;
  // libgpiod 1.6's lookup takes a path only under /dev/ (anything else is
  // looked up as /dev/NAME): any other path is opened as given.
  const bool path = chip.find('/') != std::string::npos && chip.rfind("/dev/", 0) != 0;
  out->chip = path ? gpiod_chip_open(chip.c_str()) : gpiod_chip_open_lookup(chip.c_str());
  if (!out->chip) {
    *error = "GPIO line '" + spec + "': cannot open chip '" + chip + "': " + Reason();
    return false;
  }
  const unsigned lines = gpiod_chip_num_lines(out->chip);
  if (offset >= lines) {
    *error = "GPIO line '" + spec + "': chip '" + chip + "' has " + std::to_string(lines) + " lines";
    gpiod_chip_close(out->chip);
    return false;
  }
  out->line = gpiod_chip_get_line(out->chip, offset);
  if (!out->line) {
    *error = "GPIO line '" + spec + "': " + Reason();
    gpiod_chip_close(out->chip);
    return false;
  }
  return true;
}

class GpiodInput : public InputLine {
 public:
  GpiodInput(std::string spec, Opened o) : spec_(std::move(spec)), o_(o) {}
  GpiodInput(const GpiodInput&) = delete;  // owns the chip
  GpiodInput& operator=(const GpiodInput&) = delete;
  ~GpiodInput() override {
    gpiod_line_release(o_.line);
    gpiod_chip_close(o_.chip);
  }
  int WaitEdge(int timeout_ms, Edge* edge, std::string* error) override {
    // libgpiod v1 waits with one ppoll: a signal ends it with EINTR, which is
    // not a line failure. The wait goes on until the deadline.
    using Clock = std::chrono::steady_clock;
    const Clock::time_point deadline = Clock::now() + std::chrono::milliseconds(timeout_ms);
    int r = 0;
    for (;;) {
      const long long left_ns = std::max<long long>(
          0, std::chrono::duration_cast<std::chrono::nanoseconds>(deadline - Clock::now()).count());
      const timespec ts{static_cast<time_t>(left_ns / 1000000000), static_cast<long>(left_ns % 1000000000)};
      errno = 0;
      r = gpiod_line_event_wait(o_.line, &ts);
      if (!(r < 0 && errno == EINTR)) break;
    }
    if (r <= 0) {
      if (r < 0) *error = "GPIO line '" + spec_ + "': " + Reason();
      return r;
    }
    gpiod_line_event ev;
    if (gpiod_line_event_read(o_.line, &ev) != 0) {
      *error = "GPIO line '" + spec_ + "': " + Reason();
      return -1;
    }
    *edge = ev.event_type == GPIOD_LINE_EVENT_RISING_EDGE ? Edge::kRising : Edge::kFalling;
    // The kernel stamps edges with CLOCK_MONOTONIC (the steady clock) since
    // Linux 5.7, before with CLOCK_REALTIME, which MonotonicEdgeTime replaces
    // by the time it was read.
    time_ = MonotonicEdgeTime(static_cast<long long>(ev.ts.tv_sec) * 1000000000 + ev.ts.tv_nsec);
    return 1;
  }
  std::string Name() const override { return spec_; }
  bool LastEdgeTime(std::chrono::steady_clock::time_point* time) const override {
    *time = time_;
    return true;
  }

 private:
  std::string spec_;
  Opened o_;
  std::chrono::steady_clock::time_point time_{};
};

class GpiodOutput : public OutputLine {
 public:
  GpiodOutput(std::string spec, Opened o) : spec_(std::move(spec)), o_(o) {}
  GpiodOutput(const GpiodOutput&) = delete;  // owns the chip
  GpiodOutput& operator=(const GpiodOutput&) = delete;
  ~GpiodOutput() override {
    gpiod_line_release(o_.line);
    gpiod_chip_close(o_.chip);
  }
  bool Set(bool high, std::string* error) override {
    if (gpiod_line_set_value(o_.line, high ? 1 : 0) != 0) {
      *error = "GPIO line '" + spec_ + "': " + Reason();
      return false;
    }
    return true;
  }
  std::string Name() const override { return spec_; }

 private:
  std::string spec_;
  Opened o_;
};

}  // namespace

long long MonotonicNowNs() {
  timespec t{};
  clock_gettime(CLOCK_MONOTONIC, &t);
  return static_cast<long long>(t.tv_sec) * 1000000000 + t.tv_nsec;
}

std::chrono::steady_clock::time_point MonotonicEdgeTime(long long ns) {
  const long long now_ns = MonotonicNowNs();
  const auto now = std::chrono::steady_clock::now();
  if (ns > now_ns || now_ns - ns >= kMaxEdgeAgeS * 1000000000LL) return now;
  // libstdc++ and libc++ read the steady clock from CLOCK_MONOTONIC on Linux:
  // then the stamp is a steady time point, exactly (checked once: both
  // clocks read alike). Else: its age, from two reads.
  static const bool steady_is_monotonic = [] {
    const long long m = MonotonicNowNs();
    const long long s =
        std::chrono::duration_cast<std::chrono::nanoseconds>(std::chrono::steady_clock::now().time_since_epoch()).count();
    return s - m >= 0 && s - m < 1000000;
  }();
  if (steady_is_monotonic)
    return std::chrono::steady_clock::time_point(
        std::chrono::duration_cast<std::chrono::steady_clock::duration>(std::chrono::nanoseconds(ns)));
  return now - std::chrono::nanoseconds(now_ns - ns);
}

bool ParseLineSpec(const std::string& spec, std::string* chip, unsigned* offset, std::string* error) {
  const size_t colon = spec.rfind(':');
  if (colon == std::string::npos || colon == 0 || colon + 1 == spec.size()) {
    *error = "GPIO line '" + spec + "': expected CHIP:OFFSET (e.g. gpiochip0:17)";
    return false;
  }
  const std::string num = spec.substr(colon + 1);
  char* end = nullptr;
  errno = 0;
  const unsigned long v = std::strtoul(num.c_str(), &end, 10);
  // Digits only: strtoul alone would take " 17", "+17" and "-1" (as a huge number).
  if (*end != '\0' || !(num[0] >= '0' && num[0] <= '9') || errno != 0 || v > 65535) {
    *error = "GPIO line '" + spec + "': offset '" + num + "' is not a line number (0..65535)";
    return false;
  }
  *chip = spec.substr(0, colon);
  *offset = static_cast<unsigned>(v);
  return true;
}

std::unique_ptr<InputLine> OpenGpiodInput(const std::string& spec, const std::string& consumer, std::string* error) {
  Opened o;
  if (!Open(spec, &o, error)) return nullptr;
  // Both edges: TriggerActivation may change while the line is held.
  if (gpiod_line_request_both_edges_events(o.line, consumer.c_str()) != 0) {
    *error = "GPIO line '" + spec + "': cannot request edge events: " + Reason();
    gpiod_chip_close(o.chip);
    return nullptr;
  }
  return std::make_unique<GpiodInput>(spec, o);
}

std::unique_ptr<OutputLine> OpenGpiodOutput(const std::string& spec, const std::string& consumer,
                                            std::string* error) {
  Opened o;
  if (!Open(spec, &o, error)) return nullptr;
  if (gpiod_line_request_output(o.line, consumer.c_str(), 0) != 0) {
    *error = "GPIO line '" + spec + "': cannot request as output: " + Reason();
    gpiod_chip_close(o.chip);
    return nullptr;
  }
  return std::make_unique<GpiodOutput>(spec, o);
}

int MemoryLine::WaitEdge(int timeout_ms, Edge* edge, std::string*) {
  std::unique_lock<std::mutex> lock(mutex_);
  if (!changed_.wait_for(lock, std::chrono::milliseconds(timeout_ms), [&] { return !pending_.empty(); })) return 0;
  *edge = pending_.front().edge;
  last_time_ = pending_.front().time;
  pending_.pop_front();
  return 1;
}

bool MemoryLine::LastEdgeTime(std::chrono::steady_clock::time_point* time) const {
  std::lock_guard<std::mutex> lock(mutex_);
  *time = last_time_;
  return true;
}

bool MemoryLine::Set(bool high, std::string*) {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    if (high == level_) return true;
    level_ = high;
    if (pending_.size() == kMaxPendingEdges) pending_.pop_front();
    pending_.push_back({high ? Edge::kRising : Edge::kFalling, std::chrono::steady_clock::now()});
    ++edges_;
  }
  changed_.notify_all();
  return true;
}

bool MemoryLine::level() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return level_;
}

int MemoryLine::edges() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return edges_;
}

}  // namespace camsim::hal
