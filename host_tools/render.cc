#include "host_tools/render.h"

#include <atomic>

#include "hal/clock.h"
#include "host_tools/io/image_read.h"

namespace camsim::host {

int StripRows(int requested, int height, int threads) {
  if (requested > 0) return requested < height ? requested : (height > 1 ? height : 1);
  const int strips = threads < 1 ? 1 : threads;
  const int rows = (height + strips - 1) / strips;
  return rows < 1 ? 1 : rows;
}

FrameRenderer::FrameRenderer(int threads, int strip_rows)
    : threads_(threads), strip_rows_(strip_rows), pipeline_(new Pipeline), pool_(threads),
      clock_(hal::NanosecondClock()) {}

bool FrameRenderer::Configure(const RunConfig& config, const Origins& origins, int scene_width, int scene_height,
                              RunConfig* finished, std::string* error) {
  PlannedPipeline planned;
  if (!PlanPipeline(config, origins, scene_width, scene_height, &planned, error)) return false;
  if (finished) *finished = planned.finished;
  return Install(std::move(planned), origins, error);
}

bool FrameRenderer::PlanPipeline(const RunConfig& config, const Origins& origins, int scene_width,
                                 int scene_height, PlannedPipeline* planned, std::string* error) const {
  planned->finished = config;
  RunConfig& rc = planned->finished;
  // The pipeline in use lends what the new one computes the same
  // (Pipeline::Configure); the validation's pipeline is the one planned.
  return FinishConfig(&rc, scene_width, scene_height, origins, threads_, error, pipeline_.get(), &planned->pipeline);
}

bool FrameRenderer::Install(PlannedPipeline planned, const Origins& origins, std::string* error) {
  std::unique_ptr<Pipeline>& p = planned.pipeline;
  const RunConfig& rc = planned.finished;
  std::vector<uint8_t> workspace(p->WorkspaceBytes(), 0);
  const Status si = p->Init(Span<uint8_t>{workspace.data(), workspace.size()}, pipeline_.get());
  if (!si.ok()) {
    *error = DescribeStatus(si, origins);
    return false;
  }
  if (!rc.vignetting_mask.empty()) {
    if (mask_.data.empty() && !ReadWeightImage(KeyWhere(origins, "vignetting.mask"), rc.vignetting_mask, kMaxMaskGain, &mask_, error))
      return false;
    PrepareMask(mask_, p->width(), p->height(), &input_);
  } else {
    input_.mask.clear();
  }
  pipeline_ = std::move(p);
  workspace_ = std::move(workspace);
  origins_ = origins;
  // The scene stays when its size and fit still hold; the pre-passes follow
  // the new settings (smear depends on the exposure time, flare on its threshold).
  has_scene_ = has_scene_ && rc.fit == fit_ && input_.width == pipeline_->width() &&
               input_.height == pipeline_->height();
  fit_ = rc.fit;
  if (has_scene_) RunPrepasses();
  else view_ = FrameInput();
  return true;
}

void FrameRenderer::RunPrepasses() {
  flare_sources_.resize(static_cast<size_t>(pipeline_->PrepassFlareSources()));
  smear_.resize(static_cast<size_t>(pipeline_->PrepassSmearEntries()));
  view_ = pipeline_->RunPrepasses(input_.View(), Span<FlareSource>{flare_sources_.data(), flare_sources_.size()},
                                  &flare_, Span<uint32_t>{smear_.data(), smear_.size()});
}

bool FrameRenderer::SetScene(const io::SceneFrame& scene, std::string* error) {
  PrepareInput(scene, pipeline_->width(), pipeline_->height(), fit_, &input_);
  has_scene_ = true;
  RunPrepasses();
  const Status cs = pipeline_->CheckInput(View());
  if (!cs.ok()) {
    *error = scene.source + ": " + DescribeStatus(cs, origins_);  // names the key and where it was set
    return false;
  }
  return true;
}

void FrameRenderer::Render(uint32_t frame, const Tap* taps, int tap_count, std::vector<WorkerStats>* stats) {
  // Strips go in order to whichever worker is free; the bytes do not depend on who takes which.
  const FrameInput view = View();
  const int h = pipeline_->height();
  const int rows = strip_rows();
  const int strips = (h + rows - 1) / rows;  // rows <= h (StripRows): no overflow
  std::atomic<int> next_strip{0};
  pool_.Run([&](int worker) {
    for (;;) {
      const int strip = next_strip.fetch_add(1);
      if (strip >= strips) break;
      const int y0 = strip * rows;
      pipeline_->ProcessStrip(view, frame, y0, y0 + rows, worker, taps, tap_count,
                              stats ? &(*stats)[static_cast<size_t>(worker)] : nullptr, &clock_);
    }
  });
}

int FrameRenderer::strip_rows() const {
  return StripRows(strip_rows_, pipeline_->height(), threads_);
}

int FrameRenderer::SensorIndex() const {
  const Plan& plan = pipeline_->plan();
  int running = 0;
  for (int i = 0; i < plan.count; ++i)
    if (plan.entries[i].runs) {
      if (plan.entries[i].id == StageId::kSensor) return running;
      ++running;
    }
  return -1;
}

}  // namespace camsim::host
