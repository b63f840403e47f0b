// Bare-metal smoke program: the core linked for a Cortex-M7 with
// arm-none-eabi-g++ (scripts/baremetal.sh), no operating system, no heap.
//
// It does what firmware would do with the core: configures the demo pipeline
// (tests/cross/cases.h) at 1920x1080 and at 640x480 to learn WorkspaceBytes(),
// initialises the 640x480 one in a static workspace array, and processes the
// first rows of a synthetic frame into a static 8-bit output band. Nothing in
// it allocates: scripts/baremetal.sh fails if the link map shows malloc,
// operator new or exception throwing.
//
// Results are left in the global `g_result` (read it with a debugger). With
// -DCAMSIM_BAREMETAL_CANARY the program also calls operator new: the build
// the script uses to prove that its link-map check does find an allocation.
#include <cstddef>
#include <cstdint>

#include "core/pipeline/pipeline.h"
#include "tests/cross/cases.h"

namespace {

using namespace camsim;

constexpr int kWidth = 640;
constexpr int kHeight = 480;
constexpr int kRows = 4;  // output rows processed: [0, kRows)

// The workspace, sized for the demo pipeline at 640x480 with one worker
// (215 360 bytes on 2026-11-25) plus headroom; Init() refuses a
// workspace that is too small, so growth shows up as a non-zero status.
constexpr size_t kWorkspaceBytes = 224 * 1024;
alignas(kWorkspaceAlign) uint8_t g_workspace[kWorkspaceBytes];

// The input frame (R, G, B radiance planes, Q16.16, 3.5 MiB): the caller's
// memory, not the core's. A device would have it in external SDRAM, filled by
// DMA; the size report (scripts/baremetal.sh) lists it apart from the rest.
uint32_t g_frame[3][kHeight * kWidth];

uint8_t g_output[kRows * kWidth * 3];  // RGB8 rows [0, kRows)

// Both pipelines are static: a Pipeline holds its stages' configuration
// (about 2 KiB), too big to be worth a place on a small stack.
Pipeline g_pipeline_1080p;
Pipeline g_pipeline;

}  // namespace

// What the program found, for a debugger (or a semihosting print).
struct BaremetalResult {
  uint32_t workspace_640x480 = 0;    // WorkspaceBytes(), one worker
  uint32_t tables_640x480 = 0;
  uint32_t worker_640x480 = 0;
  uint32_t workspace_1920x1080 = 0;
  uint32_t tables_1920x1080 = 0;
  uint32_t worker_1920x1080 = 0;
  uint32_t output_hash = 0;          // FNV-1a 32 of the RGB8 output rows
  int status = -1;                   // 0 = every step succeeded
};
volatile BaremetalResult g_result;

#ifdef CAMSIM_BAREMETAL_CANARY
// Deliberately allocates, so that the link map must show operator new.
int* volatile g_canary;
#endif

namespace {
int Fail(int step) {
  g_result.status = step;
  return step;
}
}  // namespace

int main() {
  BaremetalResult r;
  // 1920x1080: configure only, for its workspace size.
  if (!g_pipeline_1080p.Configure(cross::DemoConfig(1920, 1080), 1, false).ok()) return Fail(1);
  r.workspace_1920x1080 = static_cast<uint32_t>(g_pipeline_1080p.WorkspaceBytes());
  r.tables_1920x1080 = static_cast<uint32_t>(g_pipeline_1080p.TableBytes());
  r.worker_1920x1080 = static_cast<uint32_t>(g_pipeline_1080p.WorkerBytes());

  // 640x480: configure, bind the static workspace (builds the tables), run.
  if (!g_pipeline.Configure(cross::DemoConfig(kWidth, kHeight), 1, false).ok()) return Fail(2);
  r.workspace_640x480 = static_cast<uint32_t>(g_pipeline.WorkspaceBytes());
  r.tables_640x480 = static_cast<uint32_t>(g_pipeline.TableBytes());
  r.worker_640x480 = static_cast<uint32_t>(g_pipeline.WorkerBytes());
  if (!g_pipeline.Init(Span<uint8_t>{g_workspace, sizeof g_workspace}).ok()) return Fail(3);

  // The synthetic frame: the TexturedScene formula of the host tests.
  for (int c = 0; c < 3; ++c)
    for (int y = 0; y < kHeight; ++y)
      for (int x = 0; x < kWidth; ++x) g_frame[c][y * kWidth + x] = cross::TexturedRadiance(kWidth, kHeight, x, y, c);
  FrameInput input;
  for (int c = 0; c < 3; ++c) input.radiance[c] = MakeImageView<const uint32_t>(g_frame[c], kWidth, kHeight);
  if (!g_pipeline.CheckInput(input).ok()) return Fail(4);

  Tap tap;
  tap.stage = -1;
  tap.format = TapFormat::kU8;
  tap.data = g_output;
  tap.stride = kWidth * 3;
  g_pipeline.ProcessStrip(input, /*frame=*/1, 0, kRows, /*worker=*/0, &tap, 1, nullptr, nullptr);

  uint32_t h = 0x811c9dc5u;  // FNV-1a 32
  for (uint8_t b : g_output) h = (h ^ b) * 0x01000193u;
  r.output_hash = h;
  r.status = 0;

#ifdef CAMSIM_BAREMETAL_CANARY
  g_canary = new int[kRows];
#endif

  g_result.workspace_640x480 = r.workspace_640x480;
  g_result.tables_640x480 = r.tables_640x480;
  g_result.worker_640x480 = r.worker_640x480;
  g_result.workspace_1920x1080 = r.workspace_1920x1080;
  g_result.tables_1920x1080 = r.tables_1920x1080;
  g_result.worker_1920x1080 = r.worker_1920x1080;
  g_result.output_hash = r.output_hash;
  g_result.status = r.status;
  return 0;
}
