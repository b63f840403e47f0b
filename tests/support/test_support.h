// Shared helpers for the tests: synthetic scenes, running a pipeline into
// buffers, hashing. Test-only (heap and std:: containers are fine here).
#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "core/base/simd.h"
#include "core/pipeline/pipeline.h"
#include "core/pipeline/stage.h"
#include "host_tools/config.h"

// For a test of lane kernels (AVX2, AVX-512) against their portable twins:
// in a build without them (the debug build's CAMSIM_NO_CPU_CLONES, other
// architectures) or on a CPU without AVX2, both sides are the same code, so
// the test is skipped and says why instead of passing.
#define CAMSIM_SKIP_WITHOUT_LANE_KERNELS()                                   \
  if (!::camsim::CpuHasAvx2())                                               \
  GTEST_SKIP() << "no SIMD lanes in this build or on this CPU: the lanes are " \
                  "the portable code here"

namespace camsim::test {

// 64-bit FNV-1a over bytes: the golden hash (simple, stable, documented).
uint64_t Fnv1a64(const void* data, size_t bytes, uint64_t h = 0xcbf29ce484222325ull);
std::string Hex64(uint64_t v);

// A scene of three Q16.16 planes.
struct Scene {
  int width = 0, height = 0;
  std::vector<uint32_t> plane[3];
  std::vector<uint32_t> inverse_depth;  // Q12.20 1/m (core/lens/dof.h); empty = none
  FrameInput View() const;
};
// Flat field: every pixel has radiance (r, g, b).
Scene FlatScene(int width, int height, double r, double g, double b);
// Deterministic textured HDR scene: gradients, edges, a bright spot (up to ~400).
Scene TexturedScene(int width, int height);

// A configured, initialised pipeline with its workspace.
struct Built {
  Pipeline pipeline;
  std::vector<uint8_t> workspace;
  Status status;
};
// Configures config for `workers` workers and initialises it.
std::unique_ptr<Built> Build(const PipelineConfig& config, int workers = 1);

// RunFrame's fill of its output before the run: a sample still equal to it
// was never written (no stage output of the tests reaches this value).
inline constexpr uint32_t kUnwritten = 0xDEADBEEFu;
// Samples of `out` still kUnwritten.
size_t UnwrittenCount(const std::vector<uint32_t>& out);

// Runs one frame with the given strip height on worker 0 and returns the final
// stage's output as raw uint32 samples (interleaved channels).
std::vector<uint32_t> RunFrame(const Built& b, const Scene& scene, uint32_t frame, int strip_rows,
                               WorkerStats* stats = nullptr);
// The same with `threads` real threads taking strips from a shared counter.
std::vector<uint32_t> RunFrameThreads(const Built& b, const Scene& scene, uint32_t frame, int strip_rows,
                                      int threads);

// The demo configuration (configs/camera.toml) for a frame size.
PipelineConfig DemoConfig(int width, int height);

// The plan's entry for a stage, or null when the configuration does not list it.
const PlanEntry* Find(const Plan& plan, StageId id);

// A stage's table memory, and its Init from it (CountTables' size).
struct StageTables {
  std::vector<uint8_t> memory;
  Arena arena;
};
Status InitStage(Stage& stage, StageTables& t);

}  // namespace camsim::test
