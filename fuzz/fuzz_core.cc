// fuzz_core: a compact binary description of a PipelineConfig plus raw
// radiance samples (fuzz_common.h has the layout). Configuring may fail; when
// it succeeds the frame is run twice with different strip heights (and on two
// workers) and the outputs of every stage must be identical and in range.
#include <algorithm>
#include <cstddef>
#include <cstdint>

#include "fuzz/fuzz_common.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const camsim::fuzz::CoreCase k = camsim::fuzz::DecodeCoreCase(data, size);
  const int h = k.config.geometry.height;
  // Strip heights from the frame size so both runs cut the frame differently:
  // the whole frame vs 1..3 rows, always fewer than h (at least two strips on
  // alternating workers) when h >= 2. A 1-row frame is a single strip in
  // both runs.
  const int rows_b = std::min(1 + h % 3, std::max(h - 1, 1));
  camsim::fuzz::RunChecked(k.config, k.View(), k.has_mask, h, rows_b);
  return 0;
}
