// Status and Result: the only way anything in the core reports failure.
// Only configuration (validate/init) returns them; per-row processing cannot fail.
#pragma once

#include <cstdint>

namespace camsim {

enum class StatusCode : uint8_t {
  kOk = 0,
  kInvalidArgument,    // a configuration value is out of range or inconsistent
  kOutOfRange,         // a size or index beyond what the core supports
  kResourceExhausted,  // the caller's workspace is too small
  kFailedPrecondition  // called in the wrong order (e.g. process before init)
};

// A status with a static message (no allocation: the message is a literal, and
// an optional field name says which parameter it concerns).
class [[nodiscard]] Status {
 public:
  constexpr Status() = default;
  constexpr Status(StatusCode code, const char* message, const char* field = "")
      : code_(code), message_(message), field_(field) {}
  static constexpr Status Ok() { return Status(); }

  constexpr bool ok() const { return code_ == StatusCode::kOk; }
  constexpr StatusCode code() const { return code_; }
  constexpr const char* message() const { return message_; }
  constexpr const char* field() const { return field_; }

 private:
  StatusCode code_ = StatusCode::kOk;
  const char* message_ = "";
  const char* field_ = "";
};

constexpr Status InvalidArgument(const char* field, const char* message) {
  return Status(StatusCode::kInvalidArgument, message, field);
}

template <typename T>
class [[nodiscard]] Result {
 public:
  constexpr Result(T value) : value_(value) {}
  constexpr Result(Status status) : status_(status) {}
  constexpr bool ok() const { return status_.ok(); }
  constexpr const Status& status() const { return status_; }
  constexpr const T& value() const { return value_; }

 private:
  Status status_;
  T value_{};
};

// Propagate a failing status to the caller.
#define CAMSIM_TRY(expr)              \
  do {                                \
    ::camsim::Status s_ = (expr);     \
    if (!s_.ok()) return s_;          \
  } while (0)

}  // namespace camsim
