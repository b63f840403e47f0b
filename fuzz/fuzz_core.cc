// fuzz_core: a compact binary description of a PipelineConfig plus raw
// radiance samples (fuzz_common.h has the layout). Configuring may fail; when
// it succeeds the frame is run twice with different strip heights (and on two
// workers) and the outputs of every stage must be identical and in range.
#include <cstddef>
#include <cstdint>

#include "fuzz/fuzz_common.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const camsim::fuzz::CoreCase k = camsim::fuzz::DecodeCoreCase(data, size);
  const int h = k.config.geometry.height;
  // Strip heights from the frame size so both runs cut the frame differently:
  // whole frame vs 1..3 rows.
  camsim::fuzz::RunChecked(k.config, k.View(), k.has_mask, h, 1 + h % 3);
  return 0;
}
