// Workspace: caller-owned memory that the core carves into tables and line
// buffers. Carving never allocates; running out is a configuration error.
#pragma once

#include <cstddef>
#include <cstdint>

#include "core/base/span.h"
#include "core/base/status.h"

namespace camsim {

// Every block handed out is aligned to this (a cache line; enough for SIMD).
inline constexpr size_t kWorkspaceAlign = 64;

constexpr size_t AlignUp(size_t n) { return (n + kWorkspaceAlign - 1) & ~(kWorkspaceAlign - 1); }

// The largest count whose bytes, aligned, size_t holds: a block of more
// elements cannot exist on this platform (on 32-bit ones, 4 GiB).
template <typename T>
constexpr size_t MaxWorkspaceCount() {
  return (static_cast<size_t>(-1) - (kWorkspaceAlign - 1)) / sizeof(T);
}

// Bump allocator over a caller-provided buffer.
class Arena {
 public:
  Arena() = default;
  explicit Arena(Span<uint8_t> memory) : base_(memory.data), size_(memory.size) {
    // Start at the first aligned address.
    const uintptr_t p = reinterpret_cast<uintptr_t>(base_);
    skew_ = static_cast<size_t>((kWorkspaceAlign - (p % kWorkspaceAlign)) % kWorkspaceAlign);
    used_ = skew_ > size_ ? size_ : skew_;
  }

  // Returns nullptr when the arena is exhausted; callers turn that into a Status.
  template <typename T>
  T* Take(size_t count) {
    if (count > MaxWorkspaceCount<T>()) return nullptr;
    const size_t bytes = AlignUp(count * sizeof(T));
    if (bytes > size_ - used_) return nullptr;
    T* out = reinterpret_cast<T*>(base_ + used_);
    used_ += bytes;
    return out;
  }

  size_t used() const { return used_; }

 private:
  uint8_t* base_ = nullptr;
  size_t size_ = 0;
  size_t used_ = 0;
  size_t skew_ = 0;
};

// The bytes a caller must provide so that Take() of the counted blocks succeeds,
// whatever the buffer's alignment. A total that size_t cannot hold sets
// overflowed() (the configuration is refused) instead of wrapping.
class WorkspaceCounter {
 public:
  template <typename T>
  void Add(size_t count) {
    if (count > MaxWorkspaceCount<T>()) overflowed_ = true;
    else AddBytes(count * sizeof(T));
  }
  void AddBytes(size_t n) {
    if (n > MaxWorkspaceCount<uint8_t>() || AlignUp(n) > static_cast<size_t>(-1) - kWorkspaceAlign - bytes_)
      overflowed_ = true;
    else bytes_ += AlignUp(n);
  }
  bool overflowed() const { return overflowed_; }
  size_t bytes() const { return bytes_ + kWorkspaceAlign; }  // + worst-case skew
  size_t raw_bytes() const { return bytes_; }

 private:
  size_t bytes_ = 0;
  bool overflowed_ = false;
};

}  // namespace camsim
