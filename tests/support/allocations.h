// Heap allocations through operator new in the test binary (the replacement
// lives in allocations.cc): how many, and the largest single request.
#pragma once

#include <cstddef>

namespace camsim::test {

long AllocationCount();
// The largest request since the last ResetLargestAllocation().
size_t LargestAllocation();
void ResetLargestAllocation();

}  // namespace camsim::test
