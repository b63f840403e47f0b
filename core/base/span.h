// Non-owning views: a span of elements and a 2-D image view with a row stride.
#pragma once

#include <cstddef>
#include <cstdint>

namespace camsim {

template <typename T>
struct Span {
  T* data = nullptr;
  size_t size = 0;
  constexpr T& operator[](size_t i) const { return data[i]; }
  constexpr bool empty() const { return size == 0; }
};

// A single-plane image: `channels` interleaved samples per pixel; `stride` is the
// distance between rows in samples (not bytes), >= width * channels.
template <typename T>
struct ImageView {
  T* data = nullptr;
  int width = 0;
  int height = 0;
  int channels = 1;
  ptrdiff_t stride = 0;

  constexpr bool empty() const { return data == nullptr; }
  constexpr T* row(int y) const { return data + static_cast<ptrdiff_t>(y) * stride; }
};

template <typename T>
constexpr ImageView<T> MakeImageView(T* data, int width, int height, int channels = 1) {
  return ImageView<T>{data, width, height, channels, static_cast<ptrdiff_t>(width) * channels};
}

}  // namespace camsim
