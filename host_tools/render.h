// One frame of a scene through the configured core pipeline into taps: the
// part of `camsim run` that `camsim-gige` shares, so both give the same bytes
// for the same configuration, scene and frame index. It also runs the
// per-frame pre-passes some stages need (flare's bright tiles, CCD smear's
// column sums) whenever the scene or the configuration changes.
#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "core/lens/flare.h"
#include "hal/thread_pool.h"
#include "host_tools/config.h"
#include "host_tools/io/float_plane.h"
#include "host_tools/scene_input.h"

namespace camsim::host {

// Rows per strip: `requested` when > 0; else (the default) one strip per
// thread, ceil(height / threads) rows. Every strip starts with empty rings,
// so it recomputes the rows its stages' windows read above and below it
// (with diffusion DoF, 2 x column window + the later stages' windows); more
// strips per thread would balance uneven frames but recompute more, and on
// BM_PipelineDof/1920/1080/2 one strip per thread won (56-63 ms against
// 66-70 ms for four; docs/performance.md). The bytes are the same for any
// strip height.
// A request above the height is one strip.
int StripRows(int requested, int height, int threads);

// A pipeline configured for a renderer but not yet initialised (no tables
// built): FrameRenderer::PlanPipeline's result, for callers that look at the
// plan before they install it.
struct PlannedPipeline {
  RunConfig finished;                  // the configuration, finished for the scene
  std::unique_ptr<Pipeline> pipeline;  // configured with the renderer's threads
};

class FrameRenderer {
 public:
  // strip_rows 0: the default of StripRows for the configured frame height.
  FrameRenderer(int threads, int strip_rows);

  // Finishes a copy of `config` for a scene of scene_width x scene_height,
  // configures and initialises the pipeline and loads the vignetting mask.
  // *finished (optional) receives the finished configuration.
  bool Configure(const RunConfig& config, const Origins& origins, int scene_width, int scene_height,
                 RunConfig* finished, std::string* error);
  // Configure in two steps: PlanPipeline finishes and configures (the
  // renderer is unchanged), Install initialises the plan and puts it in use.
  bool PlanPipeline(const RunConfig& config, const Origins& origins, int scene_width, int scene_height,
                    PlannedPipeline* planned, std::string* error) const;
  bool Install(PlannedPipeline planned, const Origins& origins, std::string* error);

  // Fits a scene to the sensor, runs the pre-passes and checks the frame
  // against the configuration (an error names the key that needs what the
  // frame lacks, and where it was set).
  bool SetScene(const io::SceneFrame& scene, std::string* error);

  // Renders frame `frame` of the current scene into the taps; per-worker
  // statistics are added to *stats when it is non-null (size >= threads).
  void Render(uint32_t frame, const Tap* taps, int tap_count, std::vector<WorkerStats>* stats);

  const Pipeline& pipeline() const { return *pipeline_; }
  // Whether a scene is set for the pipeline in use (Install keeps it while its size and fit hold).
  bool has_scene() const { return has_scene_; }
  const CoreInput& input() const { return input_; }
  // The frame as the core sees it: the scene's planes and the pre-passes' results.
  FrameInput View() const { return view_; }
  int threads() const { return threads_; }
  // Rows per strip of the configured pipeline (StripRows).
  int strip_rows() const;
  // Running index of the sensor stage, -1 when it does not run.
  int SensorIndex() const;

 private:
  int threads_, strip_rows_;
  std::unique_ptr<Pipeline> pipeline_;
  std::vector<uint8_t> workspace_;
  io::FloatPlane mask_;
  void RunPrepasses();

  CoreInput input_;
  bool has_scene_ = false;
  std::vector<FlareSource> flare_sources_;  // the pre-passes' storage (Pipeline::RunPrepasses):
  FlareFrame flare_;                        // flare's bright tiles and haze,
  std::vector<uint32_t> smear_;             // smear's column sums
  FrameInput view_;                         // input_ with them attached (View)
  SceneFit fit_ = SceneFit::kCrop;
  Origins origins_;  // of the installed configuration, for SetScene's errors
  hal::ThreadPool pool_;
  Clock clock_;
};

}  // namespace camsim::host
