// Double-precision reference of blooming (core/sensor/blooming.h): the
// two-pass spill on a whole column, no window. Charge in electrons.
#pragma once

#include <vector>

namespace camsim::ref {

// Returns the charge of each pixel of a column after blooming; charge spilled
// past either end of the column is lost.
std::vector<double> RefBloomColumn(const std::vector<double>& charge, double full_well);

}  // namespace camsim::ref
