#include "bench/stage_bench.h"

#include <atomic>
#include <cstdlib>

namespace camsim::bench {

StageRunner::StageRunner(const Pipeline& pipeline, int index, const FrameInput& input, int threads)
    : stage_(pipeline.running_stage(index)),
      input_(&input),
      width_(pipeline.width()),
      height_(pipeline.height()),
      channels_(index == 0 ? 3 : pipeline.running_format(index - 1).channels),
      margin_(stage_.Margin()),
      out_channels_(pipeline.running_format(index).channels),
      pool_(threads) {
  const size_t w = static_cast<size_t>(width_), h = static_cast<size_t>(height_);
  // The stage's input frame: the scene, or the previous stage's output.
  frame_.resize(w * h * static_cast<size_t>(channels_));
  if (index == 0) {
    for (size_t y = 0; y < h; ++y)
      for (size_t x = 0; x < w; ++x)
        for (int c = 0; c < 3; ++c) frame_[(y * w + x) * 3 + c] = input.radiance[c].row(static_cast<int>(y))[x];
  } else {
    Tap tap;
    tap.stage = index - 1;
    tap.format = TapFormat::kU32;
    tap.data = frame_.data();
    tap.stride = static_cast<ptrdiff_t>(w) * channels_;
    pipeline.ProcessFrame(input, 0, height_, &tap, 1, nullptr, nullptr);
  }
  Pad();
  workers_.resize(static_cast<size_t>(threads));
  for (Worker& wk : workers_) {
    wk.rows.resize(kMaxWindowRows);
    wk.out.assign(static_cast<size_t>(out_channels_), std::vector<uint32_t>(w + 2 * static_cast<size_t>(margin_)));
    wk.scratch.resize(stage_.ScratchBytes(width_) + 64);
  }
}

void StageRunner::SetInput(const std::vector<uint32_t>& frame) {
  if (frame.size() != frame_.size()) std::abort();
  frame_ = frame;
  Pad();
}

void StageRunner::Pad() {
  const size_t w = static_cast<size_t>(width_), h = static_cast<size_t>(height_);
  padded_.resize(h * static_cast<size_t>(channels_));
  for (size_t y = 0; y < h; ++y)
    for (int c = 0; c < channels_; ++c) {
      std::vector<uint32_t>& row = padded_[y * channels_ + c];
      row.resize(w + 2 * static_cast<size_t>(margin_));
      for (int i = -margin_; i < width_ + margin_; ++i)
        row[static_cast<size_t>(i + margin_)] = frame_[(y * w + static_cast<size_t>(Reflect101(i, width_))) * channels_ + c];
    }
}

void StageRunner::SetOutput(TapFormat format) {
  const size_t bytes = format == TapFormat::kU8 ? 1 : (format == TapFormat::kU16 ? 2 : 4);
  output_.assign(static_cast<size_t>(width_) * height_ * out_channels_ * bytes, 0);
  tap_.format = format;
  tap_.data = output_.data();
  tap_.stride = static_cast<ptrdiff_t>(width_) * out_channels_;
}

void StageRunner::RunFrame(uint32_t frame) {
  constexpr int kStripRows = 16;
  std::atomic<int> next{0};
  pool_.Run([&](int worker) {
    Worker& wk = workers_[static_cast<size_t>(worker)];
    RowArgs args;
    args.width = width_;
    args.frame = frame;
    args.input = input_;
    args.scratch = wk.scratch.data();
    args.rows = wk.rows.data();
    for (int c = 0; c < out_channels_; ++c) args.out[c] = wk.out[static_cast<size_t>(c)].data() + margin_;
    for (int y0; (y0 = next.fetch_add(1) * kStripRows) < height_;) {
      for (int y = y0; y < y0 + kStripRows && y < height_; ++y) {
        const RowWindow win = stage_.InputRows(y, height_);
        args.y = y;
        args.first_row = win.first;
        args.row_count = win.last - win.first + 1;
        for (int k = 0; k < args.row_count; ++k) {
          const size_t src = static_cast<size_t>(Reflect101(win.first + k, height_));
          for (int c = 0; c < channels_; ++c) wk.rows[static_cast<size_t>(k)].ch[c] = padded_[src * channels_ + c].data() + margin_;
        }
        stage_.ProcessRow(args);
        if (tap_.data != nullptr) WriteTapRow(tap_, args.out, out_channels_, y, width_);
      }
    }
  });
}

}  // namespace camsim::bench
