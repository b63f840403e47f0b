// Trigger input and strobe output lines. The device sees only these
// interfaces; OpenGpiod* back them with libgpiod (v1 API, Linux GPIO
// character devices), MemoryLine with a variable (tests, rigs in one process).
#pragma once

#include <condition_variable>
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
};

class OutputLine {
 public:
  virtual ~OutputLine() = default;
  virtual bool Set(bool high, std::string* error) = 0;
  virtual std::string Name() const = 0;
};

// "CHIP:OFFSET": CHIP is a gpiochip name (gpiochip0), number (0) or path
// (/dev/gpiochip0); OFFSET the line number on it.
bool ParseLineSpec(const std::string& spec, std::string* chip, unsigned* offset, std::string* error);

// nullptr and a message naming the spec and the reason when the chip or line
// cannot be opened or requested.
std::unique_ptr<InputLine> OpenGpiodInput(const std::string& spec, const std::string& consumer, std::string* error);
std::unique_ptr<OutputLine> OpenGpiodOutput(const std::string& spec, const std::string& consumer, std::string* error);

// A line in memory: Set() on it (as an output) wakes WaitEdge() (as an input).
class MemoryLine : public InputLine, public OutputLine {
 public:
  explicit MemoryLine(std::string name) : name_(std::move(name)) {}
  int WaitEdge(int timeout_ms, Edge* edge, std::string* error) override;
  bool Set(bool high, std::string* error) override;
  std::string Name() const override { return name_; }
  bool level() const;
  int edges() const;  // edges seen so far

 private:
  std::string name_;
  mutable std::mutex mutex_;
  std::condition_variable changed_;
  bool level_ = false;
  int edges_ = 0, consumed_ = 0;
  Edge last_ = Edge::kRising;
};

}  // namespace camsim::hal
