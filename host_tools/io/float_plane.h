// A single-channel float image, row-major without padding: sample (x, y) is
// data[y * width + x]. Host-side only (owns a std::vector).
#pragma once

#include <cstddef>
#include <vector>

namespace camsim::io {

struct FloatPlane {
  int width = 0, height = 0;
  std::vector<float> data;

  float at(int x, int y) const {
    return data[static_cast<size_t>(y) * static_cast<size_t>(width) + static_cast<size_t>(x)];
  }
};

}  // namespace camsim::io
