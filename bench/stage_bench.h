// One stage of a configured pipeline, driven alone over a captured frame of
// its input: what the per-stage benchmarks time. The capture runs the pipeline
// up to the stage once (untimed); the timed part is the stage's ProcessRow over
// every row, split into strips over threads, exactly as the driver would call
// it (reflect-101 rows and margins, the stage's own InputRows window).
#pragma once

#include <cstdint>
#include <vector>

#include "core/pipeline/pipeline.h"
#include "hal/thread_pool.h"

namespace camsim::bench {

class StageRunner {
 public:
  // Captures the input of running stage `index` of `pipeline` for `input`.
  StageRunner(const Pipeline& pipeline, int index, const FrameInput& input, int threads);
  // Runs the stage over the whole frame once; rows land in a per-thread row
  // buffer, and with an output set (SetOutput) also in a whole frame, as a
  // pipeline's tap writes them (what a peer writing an image is compared with).
  void RunFrame(uint32_t frame);
  // Writes every output row to a frame of `format` (interleaved channels);
  // the frame is output_frame().
  void SetOutput(TapFormat format);
  const std::vector<uint8_t>& output_frame() const { return output_; }
  const Stage& stage() const { return stage_; }
  // The captured input: interleaved channels, width x height.
  const std::vector<uint32_t>& input_frame() const { return frame_; }
  int input_channels() const { return channels_; }
  // Replaces the captured input with another frame of the same size and
  // channels (a synthetic test frame).
  void SetInput(const std::vector<uint32_t>& frame);

 private:
  void Pad();  // fills padded_ from frame_

  const Stage& stage_;
  const FrameInput* input_;
  int width_, height_, channels_, margin_;
  int out_channels_;
  std::vector<uint32_t> frame_;
  // padded_[(y * channels + c)] : one input row with Margin() columns each side.
  std::vector<std::vector<uint32_t>> padded_;
  struct Worker {
    std::vector<RowIn> rows;
    std::vector<std::vector<uint32_t>> out;
    std::vector<uint8_t> scratch;
  };
  std::vector<Worker> workers_;
  std::vector<uint8_t> output_;
  Tap tap_;  // tap_.data == nullptr: no output frame
  hal::ThreadPool pool_;
};

}  // namespace camsim::bench
