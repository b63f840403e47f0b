// fuzz_config: the bytes as TOML text for host::ParseConfig + FinishConfig
// (input 64 x 48). A configuration that is accepted must also survive
// ConfigToToml -> ParseConfig unchanged, and is run on a small synthetic frame
// through the core (fuzz_common.h RunChecked: two strip heights, two workers,
// outputs identical and in range).
#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "fuzz/fuzz_common.h"
#include "host_tools/config.h"

namespace {

constexpr int kInputWidth = 64, kInputHeight = 48;
constexpr int64_t kMaxProcessedPixels = 128 * 128;  // larger sensors (scene_fit = scale) are only configured

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using namespace camsim;
  const std::string text(reinterpret_cast<const char*>(data), size);
  host::RunConfig rc;
  host::Origins origins;
  std::string error;
  if (!host::ParseConfig(text, "fuzz.toml", &rc, &origins, &error)) {
    FUZZ_CHECK(!error.empty(), "ParseConfig failed without an error message");
    return 0;
  }
  // What `camsim config` prints for this configuration must read back as the same configuration.
  const std::string printed = host::ConfigToToml(rc, false);
  {
    host::RunConfig again;
    host::Origins o;
    std::string e;
    FUZZ_CHECK(host::ParseConfig(printed, "printed.toml", &again, &o, &e), "%s\n--- printed:\n%s", e.c_str(),
               printed.c_str());
    FUZZ_CHECK(host::ConfigToToml(again, false) == printed, "round trip changed the configuration:\n%s",
               printed.c_str());
  }
  if (!host::FinishConfig(&rc, kInputWidth, kInputHeight, origins, 1, &error)) {
    FUZZ_CHECK(!error.empty(), "FinishConfig failed without an error message");
    return 0;
  }
  const int w = rc.core.geometry.width, h = rc.core.geometry.height;
  FUZZ_CHECK(w >= 1 && h >= 1, "FinishConfig accepted %d x %d", w, h);
  if (static_cast<int64_t>(w) * h > kMaxProcessedPixels) {
    // Still configure and initialise: the workspace of a huge sensor must be sized sanely.
    Pipeline p;
    const Status s = p.Configure(rc.core, 1, !rc.vignetting_mask.empty());
    FUZZ_CHECK(s.ok(), "Configure refused what FinishConfig accepted: %s", s.message());
    FUZZ_CHECK(p.WorkspaceBytes() < (size_t{1} << 30), "workspace %zu bytes", p.WorkspaceBytes());
    std::vector<uint8_t> ws(p.WorkspaceBytes());
    const Status init = p.Init(Span<uint8_t>{ws.data(), ws.size()});
    FUZZ_CHECK(init.ok(), "Init: %s", init.message());
    return 0;
  }
  // A synthetic frame: a ramp over the whole Q16.16 range, black, and the
  // largest sample, plus a mask (when the configuration names one) of gains 0..3.99.
  fuzz::CoreCase k;
  k.config = rc.core;
  k.has_mask = !rc.vignetting_mask.empty();
  const size_t n = static_cast<size_t>(w) * h;
  for (int c = 0; c < 3; ++c) {
    k.radiance[c].resize(n);
    for (size_t i = 0; i < n; ++i) {
      const uint32_t v = static_cast<uint32_t>((i * 2654435761u + c * 40503u) % 0x200000u);  // 0 .. 32
      k.radiance[c][i] = i % 17 == 3 ? 0xFFFFFFFFu : (i % 13 == 5 ? 0u : v);
    }
  }
  k.mask.resize(n);
  for (size_t i = 0; i < n; ++i) k.mask[i] = static_cast<uint16_t>(i * 977u);
  FUZZ_CHECK(fuzz::RunChecked(k.config, k.View(), k.has_mask, h, 2),
             "Configure refused what FinishConfig accepted");
  return 0;
}
