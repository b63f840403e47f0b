#include "tests/support/test_support.h"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <memory>
#include <thread>

#include "host_tools/config.h"
#include "tests/cross/cases.h"

namespace camsim::test {

uint64_t Fnv1a64(const void* data, size_t bytes, uint64_t h) {
  const uint8_t* p = static_cast<const uint8_t*>(data);
  for (size_t i = 0; i < bytes; ++i) {
    h ^= p[i];
    h *= 0x100000001b3ull;
  }
  return h;
}

std::string Hex64(uint64_t v) {
  char buf[17];
  std::snprintf(buf, sizeof buf, "%016llx", static_cast<unsigned long long>(v));
  return buf;
}

FrameInput Scene::View() const {
  FrameInput in;
  for (int c = 0; c < 3; ++c) in.radiance[c] = MakeImageView<const uint32_t>(plane[c].data(), width, height);
  if (!inverse_depth.empty()) in.inverse_depth = MakeImageView<const uint32_t>(inverse_depth.data(), width, height);
  return in;
}

Scene FlatScene(int width, int height, double r, double g, double b) {
  Scene s;
  s.width = width;
  s.height = height;
  const double v[3] = {r, g, b};
  for (int c = 0; c < 3; ++c)
    s.plane[c].assign(static_cast<size_t>(width) * height, Q<16, 16>::FromDouble(v[c]).raw);
  return s;
}

Scene TexturedScene(int width, int height) {
  Scene s;
  s.width = width;
  s.height = height;
  for (int c = 0; c < 3; ++c) s.plane[c].resize(static_cast<size_t>(width) * height);
  for (int y = 0; y < height; ++y)
    for (int x = 0; x < width; ++x)
      for (int c = 0; c < 3; ++c)
        s.plane[c][static_cast<size_t>(y) * width + x] = cross::TexturedRadiance(width, height, x, y, c);
  return s;
}

std::unique_ptr<Built> Build(const PipelineConfig& config, int workers) {
  auto b = std::make_unique<Built>();
  b->status = b->pipeline.Configure(config, workers, false);
  if (!b->status.ok()) return b;
  b->workspace.assign(b->pipeline.WorkspaceBytes(), 0xA5);  // not 0: the core must not read what it did not write
  b->status = b->pipeline.Init(Span<uint8_t>{b->workspace.data(), b->workspace.size()});
  return b;
}

size_t UnwrittenCount(const std::vector<uint32_t>& out) {
  return static_cast<size_t>(std::count(out.begin(), out.end(), kUnwritten));
}

namespace {
Tap FinalTap(const Built& b, std::vector<uint32_t>* out) {
  const LineFormat f = b.pipeline.plan().output;
  out->assign(static_cast<size_t>(b.pipeline.width()) * b.pipeline.height() * f.channels, kUnwritten);
  Tap t;
  t.stage = -1;
  t.format = TapFormat::kU32;
  t.data = out->data();
  t.stride = static_cast<ptrdiff_t>(b.pipeline.width()) * f.channels;
  return t;
}
}  // namespace

std::vector<uint32_t> RunFrame(const Built& b, const Scene& scene, uint32_t frame, int strip_rows,
                               WorkerStats* stats) {
  std::vector<uint32_t> out;
  const Tap t = FinalTap(b, &out);
  b.pipeline.ProcessFrame(scene.View(), frame, strip_rows, &t, 1, stats, nullptr);
  return out;
}

std::vector<uint32_t> RunFrameThreads(const Built& b, const Scene& scene, uint32_t frame, int strip_rows,
                                      int threads) {
  std::vector<uint32_t> out;
  const Tap t = FinalTap(b, &out);
  const FrameInput in = scene.View();
  std::atomic<int> next{0};
  std::vector<std::thread> pool;
  for (int w = 0; w < threads; ++w)
    pool.emplace_back([&, w] {
      for (;;) {
        const int y0 = next.fetch_add(1) * strip_rows;
        if (y0 >= b.pipeline.height()) break;
        b.pipeline.ProcessStrip(in, frame, y0, y0 + strip_rows, w, &t, 1, nullptr, nullptr);
      }
    });
  for (std::thread& th : pool) th.join();
  return out;
}

const PlanEntry* Find(const Plan& plan, StageId id) {
  for (int i = 0; i < plan.count; ++i)
    if (plan.entries[i].id == id) return &plan.entries[i];
  return nullptr;
}

PipelineConfig DemoConfig(int width, int height) {
  host::RunConfig rc;
  host::Origins origins;
  std::string error;
  if (!host::LoadConfigFile(CAMSIM_SOURCE_DIR "/configs/camera.toml", &rc, &origins, &error) ||
      !host::FinishConfig(&rc, width, height, origins, 1, &error)) {
    std::fprintf(stderr, "DemoConfig(%d, %d): %s\n", width, height, error.c_str());
    std::abort();
  }
  return rc.core;
}

Status InitStage(Stage& stage, StageTables& t) {
  WorkspaceCounter counter;
  stage.CountTables(counter);
  t.memory.assign(counter.bytes(), 0);
  t.arena = Arena(Span<uint8_t>{t.memory.data(), t.memory.size()});
  return stage.Init(t.arena);
}

}  // namespace camsim::test
