// Trigger input and strobe output lines. The device sees only these
// interfaces; OpenGpiod* back them with libgpiod (v1 API, Linux GPIO
// character devices), OpenBus* with a loopback trigger bus (UNIX datagram
// sockets in a directory: a multi-camera rig on one host), MemoryLine with a
// variable (tests).
#pragma once

#include <chrono>
#include <condition_variable>
#include <cstddef>
#include <cstdint>
#include <deque>
#include <memory>
#include <mutex>
#include <string>

namespace camsim::hal {

enum class Edge { kRising, kFalling };

class InputLine {
 public:
  virtual ~InputLine() = default;
  // Waits up to timeout_ms for an edge; 1: an edge of kind *edge, 0: timeout,
  // -1: the line failed (error text in *error).
  virtual int WaitEdge(int timeout_ms, Edge* edge, std::string* error) = 0;
  virtual std::string Name() const = 0;
  // The frame index the last edge WaitEdge returned carried (a trigger bus
  // pulse does); false for lines without one (GPIO).
  virtual bool LastEdgeIndex(uint32_t* /*index*/) const { return false; }
  // When the last edge WaitEdge returned happened on the line, on the steady
  // clock: a GPIO line's kernel timestamp, a trigger bus sender's stamp, a
  // MemoryLine's Set; false for lines without one.
  virtual bool LastEdgeTime(std::chrono::steady_clock::time_point* /*time*/) const { return false; }
  // Input the line ignored since the last call, said once (a trigger bus
  // message of another version), or "".
  virtual std::string TakeNotice() { return {}; }
};

// The steady-clock time of an edge stamped `ns` on CLOCK_MONOTONIC. A stamp
// in the future or kMaxEdgeAgeS old or more is another clock's (an old
// kernel's CLOCK_REALTIME, a sender in another time namespace): the time now.
inline constexpr long long kMaxEdgeAgeS = 10;
std::chrono::steady_clock::time_point MonotonicEdgeTime(long long ns);
long long MonotonicNowNs();  // CLOCK_MONOTONIC

class OutputLine {
 public:
  virtual ~OutputLine() = default;
  virtual bool Set(bool high, std::string* error) = 0;
  virtual std::string Name() const = 0;
  // The frame index the next edges carry (a trigger bus sends it; GPIO ignores it).
  virtual void SetEdgeIndex(uint32_t /*index*/) {}
};

// "CHIP:OFFSET": CHIP is a gpiochip name (gpiochip0), number (0) or path
// (/dev/gpiochip0); OFFSET the line number on it.
bool ParseLineSpec(const std::string& spec, std::string* chip, unsigned* offset, std::string* error);

// nullptr and a message naming the spec and the reason when the chip or line
// cannot be opened or requested.
std::unique_ptr<InputLine> OpenGpiodInput(const std::string& spec, const std::string& consumer, std::string* error);
std::unique_ptr<OutputLine> OpenGpiodOutput(const std::string& spec, const std::string& consumer, std::string* error);

// Any line by its spec: "unix:DIR" is a trigger bus (below), anything else
// CHIP:OFFSET for libgpiod.
std::unique_ptr<InputLine> OpenInputLine(const std::string& spec, const std::string& consumer, std::string* error);
std::unique_ptr<OutputLine> OpenOutputLine(const std::string& spec, const std::string& consumer, std::string* error);

// Loopback trigger bus "unix:DIR": a stand-in for a trigger wire shared by the
// cameras of a rig where no GPIO chip exists. Each input (a camera's Line0)
// binds a datagram socket DIR/line-<pid>-<n>.sock, n the first number no live
// input holds (DIR is created if missing, its parent must exist); an output (camsim-trigger, or a master camera's
// strobe) sends every edge to all sockets in DIR. An edge is one datagram
// (TriggerBusMessage) carrying its level, a frame index, so a camera that
// missed pulses still renders the same frame index as the others, and the
// time the sender set it, so a camera times the edge as a GPIO line's
// kernel stamp would, not by when its reader got to it.
inline constexpr char kBusScheme[] = "unix:";
bool IsBusSpec(const std::string& spec);
// The directory of "unix:DIR"; false and a message naming the spec if it is not one.
bool ParseBusSpec(const std::string& spec, std::string* dir, std::string* error);

// One edge on the bus: 24 bytes, little-endian: magic, version, level, 2
// zero bytes, frame index, sequence, edge time. Version 1 (16 bytes) had no
// edge time; an input ignores a message of another version and says so once
// (TakeNotice) rather than misread it.
struct TriggerBusMessage {
  static constexpr uint32_t kMagic = 0x42545343;  // "CSTB" (camsim trigger bus)
  static constexpr uint8_t kVersion = 2;
  static constexpr size_t kSize = 24;
  bool rising = true;
  uint32_t frame_index = 0;
  uint32_t sequence = 0;  // the sender's edge count (diagnostics)
  // When the sender set the edge, CLOCK_MONOTONIC nanoseconds: the bus is
  // UNIX sockets on one host, so senders and inputs share that clock.
  uint64_t edge_time_ns = 0;
  void Encode(uint8_t out[kSize]) const;
  // False for anything but a well-formed message of kVersion.
  static bool Decode(const uint8_t* data, size_t size, TriggerBusMessage* out);
  // The version byte of a datagram that starts with kMagic (any version), else -1.
  static int VersionOf(const uint8_t* data, size_t size);
};

std::unique_ptr<InputLine> OpenBusInput(const std::string& spec, std::string* error);

class BusOutput : public OutputLine {
 public:
  BusOutput(std::string spec, std::string dir) : spec_(std::move(spec)), dir_(std::move(dir)) {}
  ~BusOutput() override;
  // Sends the edge to every input on the bus (no edge when the level is unchanged).
  // An input whose queue is full (its reader is behind) is waited for up to
  // kSendTimeoutMs, so a burst of edges is not lost; one that stays full, or
  // whose process is gone, misses the edge and is not counted.
  bool Set(bool high, std::string* error) override;
  // The same, the edge stamped edge_time_ns (CLOCK_MONOTONIC) instead of
  // now: a sender keeping a schedule (camsim-trigger) stamps each edge at
  // its scheduled time and sends it once that time has come, so the pulse
  // widths and intervals the cameras see are the scheduled ones, however
  // late the sender woke.
  bool SetAt(bool high, long long edge_time_ns, std::string* error);
  static constexpr int kSendTimeoutMs = 100;
  std::string Name() const override { return spec_; }
  void SetEdgeIndex(uint32_t index) override { index_ = index; }
  int last_receivers() const { return receivers_; }  // inputs the last edge reached

 private:
  std::string spec_, dir_;
  int fd_ = -1;
  bool level_ = false;
  uint32_t index_ = 0, sequence_ = 0;
  int receivers_ = 0;
};
std::unique_ptr<BusOutput> OpenBusOutput(const std::string& spec, std::string* error);

// A line in memory: Set() on it (as an output) wakes WaitEdge() (as an input).
// Edges not yet waited for are queued with their direction and the time of
// their Set; past kMaxPendingEdges the oldest is dropped.
class MemoryLine : public InputLine, public OutputLine {
 public:
  explicit MemoryLine(std::string name) : name_(std::move(name)) {}
  int WaitEdge(int timeout_ms, Edge* edge, std::string* error) override;
  bool Set(bool high, std::string* error) override;
  std::string Name() const override { return name_; }
  bool LastEdgeTime(std::chrono::steady_clock::time_point* time) const override;
  bool level() const;
  int edges() const;  // edges seen so far
  static constexpr size_t kMaxPendingEdges = 64;

 private:
  std::string name_;
  mutable std::mutex mutex_;
  std::condition_variable changed_;
  bool level_ = false;
  int edges_ = 0;
  struct Pending {
    Edge edge;
    std::chrono::steady_clock::time_point time;
  };
  std::deque<Pending> pending_;  // not yet returned by WaitEdge, oldest first
  std::chrono::steady_clock::time_point last_time_{};  // of the edge WaitEdge last returned
};

}  // namespace camsim::hal
