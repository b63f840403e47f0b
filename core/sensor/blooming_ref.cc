#include "core/sensor/blooming_ref.h"

#include <algorithm>
#include <cmath>

namespace camsim::ref {

std::vector<double> RefBloomColumn(const std::vector<double>& charge, double w) {
  const size_t n = charge.size();
  std::vector<double> level(n), excess(n);
  for (size_t k = 0; k < n; ++k) {
    level[k] = std::min(charge[k], w);
    excess[k] = charge[k] - level[k];
  }
  double carry = 0;
  for (size_t k = 0; k < n; ++k) {
    const double take = std::min(w - level[k], carry);
    level[k] += take;
    carry -= take;
    carry += std::floor(excess[k] * 256.0 / 2.0) / 256.0;  // the down half, as the core splits Q.8 charge
  }
  carry = 0;
  for (size_t k = n; k-- > 0;) {
    const double take = std::min(w - level[k], carry);
    level[k] += take;
    carry -= take;
    carry += excess[k] - std::floor(excess[k] * 256.0 / 2.0) / 256.0;
  }
  return level;
}

}  // namespace camsim::ref
