#include "core/pipeline/pipeline.h"

#include <cstring>

#include "core/base/simd.h"
#include "core/sensor/smear.h"

namespace camsim {
namespace {

constexpr int kMaxDimension = 16384;  // keeps squared radii and offsets inside 32 bits
constexpr int kMaxWorkers = 64;

constexpr const char* kStageNames[kStageCount] = {
    "dof_gather", "dof_rows", "dof_columns", "motion_blur", "distortion", "flare", "exposure", "vignetting", "cfa",
    "blooming", "sensor", "black_level", "white_balance", "demosaic", "color_matrix", "gamma"};

// Sum of samples per colour for the report.
void AddRowStats(const uint32_t* const* rows, int channels, bool mosaic, Cfa cfa, int y, int width,
                 StageStats* s) {
  if (channels == 3) {
    for (int c = 0; c < 3; ++c) {
      int64_t sum = 0;
      for (int x = 0; x < width; ++x) sum += rows[c][x];
      s->sum[c] += sum;
      s->count[c] += width;
    }
    return;
  }
  if (!mosaic) {
    int64_t sum = 0;
    for (int x = 0; x < width; ++x) sum += rows[0][x];
    s->sum[kGreen] += sum;
    s->count[kGreen] += width;
    return;
  }
  // A mosaic row alternates two colours: sum even and odd columns apart.
  const uint32_t* row = rows[0];
  int64_t even = 0, odd = 0;
  int x = 0;
  for (; x + 1 < width; x += 2) {
    even += row[x];
    odd += row[x + 1];
  }
  if (x < width) even += row[x];
  const Colour even_colour = CfaColour(cfa, 0, y), odd_colour = CfaColour(cfa, 1, y);
  s->sum[even_colour] += even;
  s->count[even_colour] += (width + 1) / 2;
  s->sum[odd_colour] += odd;
  s->count[odd_colour] += width / 2;
}

// Q0.16 full scale to 8 bits: round(v * 255 / 65535), ties up. As
// 65535 = 255 * 257 that is round(v / 257) = floor((v + 128.5) / 257),
// which is (v + 128) / 257: no multiple of 257 lies in (v + 128, v + 128.5].
// For t = v + 128 <= 65663 that quotient is (t - (t >> 8)) >> 8 (checked for
// every v by Pipeline.TapRowsConvertEverySample): shifts, which
// vectorise, where compilers would not vectorise the division.
inline uint8_t ToU8(uint32_t v) {
  const uint32_t t = (v > 0xFFFFu ? 0xFFFFu : v) + 128u;
  return static_cast<uint8_t>((t - (t >> 8)) >> 8);
}

inline uint16_t ToU16(uint32_t v) { return static_cast<uint16_t>(v > 0xFFFFu ? 0xFFFFu : v); }
inline uint32_t ToU32(uint32_t v) { return v; }

// A row's planes (1 or 3) converted and interleaved into dst. The row
// pointers are locals: a store through dst, a uint8_t store in particular,
// could alias them and would make the compiler reload them every sample.
template <typename T, typename Convert>
inline void Interleave(const uint32_t* const* rows, int channels, T* __restrict dst, int width, Convert convert) {
  const uint32_t* __restrict r0 = rows[0];
  if (channels == 1) {
    for (int x = 0; x < width; ++x) dst[x] = convert(r0[x]);
    return;
  }
  const uint32_t* __restrict r1 = rows[1];
  const uint32_t* __restrict r2 = rows[2];
  for (int x = 0; x < width; ++x) {
    dst[3 * x] = convert(r0[x]);
    dst[3 * x + 1] = convert(r1[x]);
    dst[3 * x + 2] = convert(r2[x]);
  }
}

// One per tap format, each compiled for AVX2 too, where GCC vectorises the
// three-plane interleave with permutes.
CAMSIM_CPU_CLONES
void InterleaveU32(const uint32_t* const* rows, int channels, uint32_t* dst, int width) {
  Interleave(rows, channels, dst, width, ToU32);
}
CAMSIM_CPU_CLONES
void InterleaveU16(const uint32_t* const* rows, int channels, uint16_t* dst, int width) {
  Interleave(rows, channels, dst, width, ToU16);
}
CAMSIM_CPU_CLONES
void InterleaveU8(const uint32_t* const* rows, int channels, uint8_t* dst, int width) {
  Interleave(rows, channels, dst, width, ToU8);
}

}  // namespace

void WriteTapRow(const Tap& tap, const uint32_t* const* rows, int channels, int y, int width) {
  CAMSIM_DCHECK(channels == 1 || channels == 3);
  const ptrdiff_t offset = static_cast<ptrdiff_t>(y) * tap.stride;
  switch (tap.format) {
    case TapFormat::kU32: InterleaveU32(rows, channels, static_cast<uint32_t*>(tap.data) + offset, width); break;
    case TapFormat::kU16: InterleaveU16(rows, channels, static_cast<uint16_t*>(tap.data) + offset, width); break;
    case TapFormat::kU8: InterleaveU8(rows, channels, static_cast<uint8_t*>(tap.data) + offset, width); break;
  }
}

namespace {

// The lowest and highest frame rows that a window reads once reflected.
void ReflectedSpan(RowWindow w, int height, int* lo, int* hi) {
  *lo = height;
  *hi = -1;
  for (int k = w.first; k <= w.last; ++k) {
    const int r = Reflect101(k, height);
    if (r < *lo) *lo = r;
    if (r > *hi) *hi = r;
  }
}

}  // namespace

const char* StageName(StageId id) {
  const int i = static_cast<int>(id);
  return i >= 0 && i < kStageCount ? kStageNames[i] : "?";
}

bool StageFromName(const char* name, StageId* id) {
  for (int i = 0; i < kStageCount; ++i)
    if (std::strcmp(name, kStageNames[i]) == 0) {
      *id = static_cast<StageId>(i);
      return true;
    }
  return false;
}

const char* DomainName(Domain d) {
  switch (d) {
    case Domain::kRadiance: return "radiance Q16.16";
    case Domain::kPhotons: return "photons Q24.8";
    case Domain::kDigital: return "digital DN";
    case Domain::kLinear: return "linear Q0.16";
    case Domain::kEncoded: return "encoded Q0.16";
  }
  return "?";
}

int DomainFracBits(Domain d) {
  switch (d) {
    case Domain::kRadiance: return 16;
    case Domain::kPhotons: return 8;
    case Domain::kDigital: return 0;
    case Domain::kLinear:
    case Domain::kEncoded: return 16;
  }
  return 0;
}

const char* CfaName(Cfa cfa) {
  switch (cfa) {
    case Cfa::kMono: return "Mono";
    case Cfa::kBayerRG: return "BayerRG";
    case Cfa::kBayerGR: return "BayerGR";
    case Cfa::kBayerGB: return "BayerGB";
    case Cfa::kBayerBG: return "BayerBG";
  }
  return "?";
}

Stage* Pipeline::StageFor(StageId id) {
  return const_cast<Stage*>(static_cast<const Pipeline*>(this)->StageFor(id));
}

const Stage* Pipeline::StageFor(StageId id) const {
  switch (id) {
    case StageId::kDofGather: return &dof_gather_;
    case StageId::kDofRows: return &dof_rows_;
    case StageId::kDofColumns: return &dof_columns_;
    case StageId::kMotionBlur: return &motion_blur_;
    case StageId::kDistortion: return &distortion_;
    case StageId::kFlare: return &flare_;
    case StageId::kExposure: return &exposure_;
    case StageId::kVignetting: return &vignetting_;
    case StageId::kCfa: return &cfa_;
    case StageId::kBlooming: return &blooming_;
    case StageId::kSensor: return &sensor_;
    case StageId::kBlackLevel: return &black_level_;
    case StageId::kWhiteBalance: return &white_balance_;
    case StageId::kDemosaic: return &demosaic_;
    case StageId::kColorMatrix: return &color_matrix_;
    case StageId::kGamma: return &gamma_;
    case StageId::kCount: break;
  }
  return nullptr;
}

namespace {

constexpr const char* kCfaInDistortionReason =
    "distortion before it computes only each Bayer site's colour and writes the mosaic itself";
constexpr const char* kCfaMovedNote =
    "runs ahead of the exposure and vignetting configured before it, which then process its one colour per pixel "
    "(the same bytes)";

// A Bayer CFA keeps one colour per pixel. Exposure and vignetting are
// pointwise and do the same to every colour, so they commute with it bit for
// bit: order[] is `in` with each Bayer CFA moved ahead of the exposure and
// vignetting entries right before it, which then process one plane instead
// of three. Returns the index the CFA moved to, or -1 when it did not move.
int MoveCfaAhead(const StageId* in, int count, Cfa cfa, StageId* order) {
  for (int i = 0; i < count; ++i) order[i] = in[i];
  int moved_to = -1;
  if (cfa == Cfa::kMono) return moved_to;  // a weighted sum of the colours: rounded differently
  for (int k = 0; k < count; ++k) {
    if (order[k] != StageId::kCfa) continue;
    int j = k;
    while (j > 0 && (order[j - 1] == StageId::kExposure || order[j - 1] == StageId::kVignetting)) --j;
    for (int m = k; m > j; --m) order[m] = order[m - 1];
    order[j] = StageId::kCfa;
    if (j < k) moved_to = j;
  }
  return moved_to;
}

}  // namespace

// The first stage of order[from, count) that is not left out, or kCount.
StageId Pipeline::NextRunning(const StageId* order, int from, int count) const {
  for (int i = from; i < count; ++i) {
    const Stage* stage = StageFor(order[i]);
    if (stage != nullptr && stage->IdentityReason() == nullptr) return order[i];
  }
  return StageId::kCount;
}

const Stage* Pipeline::InitialisedStage(StageId id) const {
  if (!initialised_) return nullptr;
  for (int i = 0; i < run_count_; ++i)
    if (run_[i] == StageFor(id)) return run_[i];
  return nullptr;
}

double PipelineWhiteLevel(const PipelineConfig& c) {
  return WhiteLevel(SensorSaturationDn(c.sensor, c.geometry), BlackLevelInUse(c.black_level, c.sensor.black_level_dn),
                    c.geometry.adc_bits);
}

Status Pipeline::Configure(const PipelineConfig& config, int workers, bool has_vignetting_mask,
                           const Pipeline* previous) {
  if (previous == this) previous = nullptr;  // its state is about to be replaced
  initialised_ = false;
  configured_ = false;
  config_ = config;
  const SensorGeometry& g = config.geometry;
  if (g.width < 1 || g.width > kMaxDimension) return InvalidArgument("sensor.width", "must be in [1, 16384]");
  if (g.height < 1 || g.height > kMaxDimension) return InvalidArgument("sensor.height", "must be in [1, 16384]");
  if (g.adc_bits < 8 || g.adc_bits > 16) return InvalidArgument("sensor.adc_bits", "must be 8 to 16");
  if (static_cast<uint8_t>(g.cfa) > static_cast<uint8_t>(Cfa::kBayerBG))
    return InvalidArgument("sensor.cfa", "must be Mono, BayerRG, BayerGR, BayerGB or BayerBG");
  if (workers < 1 || workers > kMaxWorkers) return InvalidArgument("threads", "must be in [1, 64]");
  if (config.order_count < 1 || config.order_count > kStageCount)
    return InvalidArgument("pipeline.stages", "must name 1 to all stages");
  workers_ = workers;

  // Each stage validates its own section.
  CAMSIM_TRY(dof_gather_.Configure(config.dof, g, config.exposure.f_number));
  CAMSIM_TRY(dof_rows_.Configure(config.dof, g, config.exposure.f_number));
  CAMSIM_TRY(dof_columns_.Configure(config.dof, g, &dof_rows_));
  CAMSIM_TRY(motion_blur_.Configure(config.motion_blur, g, config.exposure.exposure_time_us));
  // A configured pipeline (initialised or not) lends its band ranges.
  const DistortionStage* previous_distortion =
      previous != nullptr && previous->configured_ ? &previous->distortion_ : nullptr;
  CAMSIM_TRY(distortion_.Configure(config.distortion, g, previous_distortion));
  CAMSIM_TRY(flare_.Configure(config.flare, g));
  CAMSIM_TRY(exposure_.Configure(config.exposure));
  CAMSIM_TRY(vignetting_.Configure(config.vignetting, g, has_vignetting_mask));
  CAMSIM_TRY(cfa_.Configure(config.cfa, g));
  CAMSIM_TRY(sensor_.Configure(config.sensor, g, config.exposure.exposure_time_us, config.seed));
  CAMSIM_TRY(blooming_.Configure(config.blooming, config.sensor, g));
  CAMSIM_TRY(black_level_.Configure(config.black_level, g, config.sensor.black_level_dn));
  CAMSIM_TRY(white_balance_.Configure(config.white_balance, g, PipelineWhiteLevel(config)));
  CAMSIM_TRY(demosaic_.Configure(config.demosaic, g));
  CAMSIM_TRY(color_matrix_.Configure(config.color_matrix, g));
  CAMSIM_TRY(gamma_.Configure(config.gamma, g));
  for (int i = 0; i < kStageCount; ++i) StageFor(static_cast<StageId>(i))->set_skip_idle(config.skip_idle);

  // Plan: follow the format through the configured order, leaving out stages
  // that would change nothing.
  plan_ = Plan();
  plan_.input = LineFormat{Domain::kRadiance, 3, false};
  LineFormat format = plan_.input;
  bool seen[kStageCount] = {};
  run_count_ = 0;
  distortion_.SetSiteOnly(false);
  StageId order[kStageCount];
  const int cfa_moved_to = MoveCfaAhead(config.order, config.order_count, g.cfa, order);
  for (int i = 0; i < config.order_count; ++i) {
    const StageId id = order[i];
    const int idx = static_cast<int>(id);
    if (idx < 0 || idx >= kStageCount) return InvalidArgument("pipeline.stages", "unknown stage");
    if (seen[idx]) return InvalidArgument("pipeline.stages", "a stage is listed twice");
    seen[idx] = true;
    PlanEntry& e = plan_.entries[plan_.count++];
    e.id = id;
    const Stage* stage = StageFor(id);
    if (const char* reason = stage->IdentityReason()) {
      e.runs = false;
      e.reason = reason;
      continue;
    }
    // Distortion right before a Bayer CFA computes only the colour each site
    // keeps and writes the mosaic itself (core/lens/distortion.h).
    if (id == StageId::kDistortion)
      distortion_.SetSiteOnly(g.cfa != Cfa::kMono && NextRunning(order, i + 1, config.order_count) == StageId::kCfa);
    if (id == StageId::kCfa && distortion_.site_only()) {  // set above only when the CFA runs next
      e.runs = false;
      e.reason = kCfaInDistortionReason;
      continue;
    }
    if (i == cfa_moved_to) e.note = kCfaMovedNote;
    Result<LineFormat> out = stage->Plan(format);
    if (!out.ok()) return out.status();
    e.runs = true;
    e.out = out.value();
    format = e.out;
    run_format_[run_count_] = e.out;
    run_[run_count_++] = stage;
  }
  if (run_count_ == 0) return InvalidArgument("pipeline.stages", "every listed stage was left out");
  // dof_columns reads the coefficient tables dof_rows builds at Init (found by fuzz_core).
  bool rows_run = false;
  for (int i = 0; i < run_count_; ++i) {
    if (run_[i] == &dof_rows_) rows_run = true;
    if (run_[i] == &dof_columns_ && !rows_run)
      return InvalidArgument("pipeline.stages", "dof_columns needs dof_rows running before it");
    // Flare's pre-pass finds the bright tiles in the frame input: the stage must see that image.
    if (run_[i] == &flare_ && i > 0)
      return InvalidArgument("pipeline.stages", "flare must run first: its bright tiles are found in the frame input");
  }
  plan_.running = run_count_;
  plan_.output = format;

  // The sensor's fixed-pattern table has an entry per pixel of each input channel.
  for (int i = 1; i < run_count_; ++i)
    if (run_[i] == &sensor_) sensor_.SetInputChannels(run_format_[i - 1].channels);

  // Rings: the input ring (index 0) and each stage's output ring (index i + 1)
  // hold as many rows as their consumer's widest window spans; the last
  // stage's, one.
  margin_ = 0;
  max_window_ = 1;
  for (int i = 0; i < run_count_; ++i)
    if (run_[i]->Margin() > margin_) margin_ = run_[i]->Margin();
  input_direct_ = run_[0]->Margin() == 0;
  for (int j = 0; j <= run_count_; ++j) {
    ring_slots_[j] = 1;
    if (j < run_count_) CAMSIM_TRY(SizeRing(j, &ring_slots_[j], &max_window_));
  }
  if (input_direct_) ring_slots_[0] = 0;

  WorkspaceCounter tables;
  for (int i = 0; i < run_count_; ++i) run_[i]->CountTables(tables);
  table_bytes_ = tables.raw_bytes();

  WorkspaceCounter worker;
  const size_t pitch = static_cast<size_t>(g.width + 2 * margin_);
  scratch_bytes_ = 0;
  int channels_of_ring[kStageCount + 1] = {3};
  {
    int r = 1;
    for (int i = 0; i < plan_.count; ++i)
      if (plan_.entries[i].runs) channels_of_ring[r++] = plan_.entries[i].out.channels;
  }
  for (int j = 0; j <= run_count_; ++j) {
    worker.Add<uint32_t>(static_cast<size_t>(ring_slots_[j]) * channels_of_ring[j] * pitch);
    worker.Add<int32_t>(static_cast<size_t>(ring_slots_[j]));  // row tag per slot
    ring_channels_[j] = channels_of_ring[j];
  }
  for (int i = 0; i < run_count_; ++i) {
    const size_t s = run_[i]->ScratchBytes(g.width);
    if (s > scratch_bytes_) scratch_bytes_ = s;
  }
  worker.AddBytes(scratch_bytes_);
  state_bytes_ = 0;
  for (int i = 0; i < run_count_; ++i) {
    state_offset_[i] = state_bytes_;
    state_bytes_ += AlignUp(run_[i]->StateBytes(g.width));
  }
  worker.AddBytes(state_bytes_);
  worker.Add<RowIn>(static_cast<size_t>(max_window_));
  worker_bytes_ = worker.raw_bytes();
  // WorkspaceBytes() must not wrap either (size_t is 32 bits on armhf).
  WorkspaceCounter total;
  total.AddBytes(table_bytes_);
  for (int i = 0; i < workers_ && !total.overflowed(); ++i) total.AddBytes(worker_bytes_);
  if (tables.overflowed() || worker.overflowed() || total.overflowed())
    return Status(StatusCode::kResourceExhausted,
                  "needs a workspace larger than this platform's address space (smaller sensor, fewer workers, "
                  "or sensor.fixed_pattern_table off)",
                  "pipeline");
  configured_ = true;
  return Status::Ok();
}

// Checks running stage i's windows over every output row (each within
// kMaxWindowRows, neither end going back as y grows) and gives the ring depth
// its input needs: the widest span of reflected rows one output row reads.
// Raises *widest to the widest window (in rows, before reflection).
Status Pipeline::SizeRing(int i, int* slots, int* widest) const {
  const int h = config_.geometry.height;
  const Stage* stage = run_[i];
  int span = 1, prev_lo = 0, prev_hi = 0;
  RowWindow prev{};
  for (int y = 0; y < h; ++y) {
    const RowWindow w = stage->InputRows(y, h);
    const int rows = w.last - w.first + 1;
    if (rows < 1 || rows > kMaxWindowRows)
      return Status(StatusCode::kOutOfRange, "reads a window of rows that is empty or wider than kMaxWindowRows (1024)",
                    stage->name());
    if (rows > *widest) *widest = rows;
    int lo = 0, hi = 0;
    ReflectedSpan(w, h, &lo, &hi);
    if (y > 0 && (w.first < prev.first || w.last < prev.last || lo < prev_lo || hi < prev_hi))
      return Status(StatusCode::kFailedPrecondition, "has a window of rows that moves backwards as y grows",
                    stage->name());
    if (hi - lo + 1 > span) span = hi - lo + 1;
    prev = w;
    prev_lo = lo;
    prev_hi = hi;
  }
  *slots = span;
  return Status::Ok();
}

size_t Pipeline::WorkspaceBytes() const {
  return table_bytes_ + static_cast<size_t>(workers_) * worker_bytes_ + kWorkspaceAlign;
}

Status Pipeline::Init(Span<uint8_t> workspace, const Pipeline* previous) {
  initialised_ = false;
  if (previous == this) previous = nullptr;
  if (workspace.size < WorkspaceBytes())
    return Status(StatusCode::kResourceExhausted, "workspace smaller than WorkspaceBytes()");
  Arena arena(workspace);
  int running = 0;
  for (int e = 0; e < plan_.count; ++e) {
    if (!plan_.entries[e].runs) continue;
    const int i = running++;
    Stage* stage = const_cast<Stage*>(run_[i]);
    const Stage* before = previous != nullptr ? previous->InitialisedStage(plan_.entries[e].id) : nullptr;
    copied_tables_[i] = 0;
    CAMSIM_TRY(before != nullptr ? stage->InitFrom(arena, *before, &copied_tables_[i]) : stage->Init(arena));
  }
  workers_base_ = arena.Take<uint8_t>(static_cast<size_t>(workers_) * worker_bytes_);
  if (workers_base_ == nullptr) return Status(StatusCode::kResourceExhausted, "workspace too small for line rings");
  initialised_ = true;
  return Status::Ok();
}

bool Pipeline::Runs(StageId id) const {
  for (int i = 0; i < plan_.count; ++i)
    if (plan_.entries[i].id == id) return plan_.entries[i].runs;
  return false;
}

// The pre-passes serve their stage only: none for a stage left out.
bool Pipeline::FlarePrepass() const { return config_.flare.enabled && Runs(StageId::kFlare); }
bool Pipeline::SmearPrepass() const { return SmearEnabled(config_) && Runs(StageId::kSensor); }

int Pipeline::PrepassFlareSources() const { return FlarePrepass() ? FlareMaxSources(config_.geometry) : 0; }

int Pipeline::PrepassSmearEntries() const { return SmearPrepass() ? SmearEntries(config_) : 0; }

FrameInput Pipeline::RunPrepasses(const FrameInput& input, Span<FlareSource> flare_sources, FlareFrame* flare,
                                  Span<uint32_t> smear) const {
  FrameInput out = input;
  if (FlarePrepass()) {
    CAMSIM_DCHECK(flare_sources.size >= static_cast<size_t>(PrepassFlareSources()) && flare != nullptr);
    ComputeFlare(config_.flare, config_.geometry, input, flare_sources, flare);
    out.flare = flare;
  }
  if (SmearPrepass()) {
    CAMSIM_DCHECK(smear.size >= static_cast<size_t>(PrepassSmearEntries()));
    ComputeSmear(config_, input, smear);
    out.smear_e = smear.data;
  }
  return out;
}

Status Pipeline::CheckInput(const FrameInput& input) const {
  const int w = config_.geometry.width, h = config_.geometry.height;
  for (int c = 0; c < 3; ++c) {
    const ImageView<const uint32_t>& v = input.radiance[c];
    if (v.data == nullptr || v.width != w || v.height != h || v.channels != 1 || v.stride < w)
      return InvalidArgument("input.radiance", "each colour plane must be sensor-sized, 1 channel");
  }
  if (config_.vignetting.mode == VignettingMode::kMask && plan_.count > 0) {
    const ImageView<const uint16_t>& m = input.vignetting_mask;
    if (m.data == nullptr || m.width != w || m.height != h || m.stride < w)
      return InvalidArgument("vignetting.mask", "mask must be sensor-sized");
  }
  // The depth plane, when a running stage reads it: depth of field, or motion
  // blur from camera translation.
  bool depth = false;
  bool motion_runs = false;
  for (int i = 0; i < plan_.count; ++i) {
    const PlanEntry& e = plan_.entries[i];
    if (!e.runs) continue;
    if (e.id == StageId::kDofGather) depth = true;
    if (e.id == StageId::kDofRows && config_.dof.method == DofMethod::kDiffusion && !config_.dof.structural_only)
      depth = true;
    if (e.id == StageId::kMotionBlur) motion_runs = true;
  }
  const ImageView<const uint32_t>& d = input.inverse_depth;
  const bool has_depth = d.data != nullptr && d.width == w && d.height == h && d.channels == 1 && d.stride >= w;
  if (depth && !has_depth)
    return InvalidArgument("dof.method", "depth of field needs a sensor-sized depth plane (input has none)");
  if (motion_runs && motion_blur_.NeedsInverseDepth() && !has_depth)
    return InvalidArgument("motion.linear_velocity_m_s", "camera translation needs a sensor-sized depth plane");
  if (motion_runs && motion_blur_.NeedsVectors())
    for (int c = 0; c < 2; ++c) {
      const ImageView<const int32_t>& m = input.motion_vectors[c];
      if (m.data == nullptr || m.width != w || m.height != h || m.channels != 1 || m.stride < w)
        return InvalidArgument("motion.source", "'vectors' needs sensor-sized motion vector planes (x and y)");
    }
  if (FlarePrepass() && input.flare == nullptr)
    return InvalidArgument("flare.enabled", "flare needs FrameInput::flare (ComputeFlare)");
  if (SmearPrepass() && input.smear_e == nullptr)
    return InvalidArgument("sensor.smear_row_transfer_us", "smear needs FrameInput::smear_e (ComputeSmear)");
  return Status::Ok();
}

// The state of one ProcessStrip call: where each ring lives and which rows it
// has produced. Local to the call, so strips on different workers never share it.
struct Pipeline::StripState {
  const FrameInput* input;
  uint32_t frame;
  int y0, y1;
  uint8_t* scratch;
  uint8_t* state;  // state_bytes_: every running stage's strip state
  RowIn* rows;  // max_window_ slots: the window of the row being produced
  // Whose window `rows` holds: stage rows_stage's rows [rows_first, rows_last].
  // A block stage (the DoF passes) reads one window for a block of rows, so
  // it is listed once per block, not once per row.
  int rows_stage, rows_first, rows_last;
  uint32_t* ring[kStageCount + 1];
  int32_t* tag[kStageCount + 1];
  int next[kStageCount + 1];
  const Tap* taps;
  int tap_count;
  WorkerStats* stats;
  const Clock* clock;
};

uint32_t* Pipeline::RingRow(const StripState& s, int j, int row, int channel) const {
  const int slot = row % ring_slots_[j];
  const size_t pitch = static_cast<size_t>(config_.geometry.width + 2 * margin_);
  return s.ring[j] + (static_cast<size_t>(slot) * ring_channels_[j] + channel) * pitch + margin_;
}

void Pipeline::FillMargins(uint32_t* row) const {
  const int w = config_.geometry.width;
  if (margin_ < w) {  // reflect-101 within the row: -m -> m, w - 1 + m -> w - 1 - m
    for (int m = 1; m <= margin_; ++m) {
      row[-m] = row[m];
      row[w - 1 + m] = row[w - 1 - m];
    }
    return;
  }
  for (int m = 1; m <= margin_; ++m) {  // narrower than the margin: reflect repeatedly
    row[-m] = row[Reflect101(-m, w)];
    row[w - 1 + m] = row[Reflect101(w - 1 + m, w)];
  }
}

// Row pointers of ring j (0 = input) for `row`, which must be available.
RowIn Pipeline::RowOf(const StripState& s, int j, int row) const {
  RowIn r{};
  if (j == 0 && input_direct_) {
    for (int c = 0; c < 3; ++c) r.ch[c] = s.input->radiance[c].row(row);
    return r;
  }
  CAMSIM_DCHECK(s.tag[j][row % ring_slots_[j]] == row);
  for (int c = 0; c < ring_channels_[j]; ++c) r.ch[c] = RingRow(s, j, row, c);
  return r;
}

// Makes ring j hold rows up to `row` (inclusive).
void Pipeline::Produce(StripState& s, int j, int row) const {
  if (j == 0) {
    if (input_direct_) return;
    for (; s.next[0] <= row; ++s.next[0]) {
      const int r = s.next[0];
      for (int c = 0; c < 3; ++c) {
        uint32_t* dst = RingRow(s, 0, r, c);
        std::memcpy(dst, s.input->radiance[c].row(r), sizeof(uint32_t) * config_.geometry.width);
        FillMargins(dst);
      }
      s.tag[0][r % ring_slots_[0]] = r;
    }
    return;
  }
  const int h = config_.geometry.height, w = config_.geometry.width;
  const Stage* stage = run_[j - 1];
  for (; s.next[j] <= row; ++s.next[j]) {
    const int r = s.next[j];
    // The input rows this row reads, reflected into the frame.
    const RowWindow window = stage->InputRows(r, h);
    int lowest = 0, needed = 0;
    ReflectedSpan(window, h, &lowest, &needed);
    Produce(s, j - 1, needed);
    const int count = window.last - window.first + 1;
    if (s.rows_stage != j || s.rows_first != window.first || s.rows_last != window.last) {
      for (int k = 0; k < count; ++k) s.rows[k] = RowOf(s, j - 1, Reflect101(window.first + k, h));
      s.rows_stage = j;
      s.rows_first = window.first;
      s.rows_last = window.last;
    }

    const bool in_strip = r >= s.y0 && r < s.y1;
    StageStats* st = (s.stats != nullptr && in_strip) ? &s.stats->stage[j - 1] : nullptr;
    RowArgs args;
    args.y = r;
    args.width = w;
    args.frame = s.frame;
    args.rows = s.rows;
    args.first_row = window.first;
    args.row_count = count;
    args.input = s.input;
    args.scratch = s.scratch;
    args.state = stage->StateBytes(w) > 0 ? s.state + state_offset_[j - 1] : nullptr;
    args.stats = st;
    for (int c = 0; c < ring_channels_[j]; ++c) args.out[c] = RingRow(s, j, r, c);
    const uint64_t t0 = s.clock != nullptr ? s.clock->now(s.clock->context) : 0;
    stage->ProcessRow(args);
    if (s.clock != nullptr && st != nullptr) st->ticks += s.clock->now(s.clock->context) - t0;
    for (int c = 0; c < ring_channels_[j]; ++c) FillMargins(args.out[c]);
    s.tag[j][r % ring_slots_[j]] = r;

    if (!in_strip) continue;
    const LineFormat& f = run_format_[j - 1];
    if (st != nullptr) AddRowStats(args.out, f.channels, f.mosaic, config_.geometry.cfa, r, w, st);
    for (int t = 0; t < s.tap_count; ++t) {
      const int tap_stage = s.taps[t].stage < 0 ? run_count_ - 1 : s.taps[t].stage;
      if (tap_stage == j - 1) WriteTapRow(s.taps[t], args.out, f.channels, r, w);
    }
  }
}

void Pipeline::ProcessStrip(const FrameInput& input, uint32_t frame, int y0, int y1, int worker,
                            const Tap* taps, int tap_count, WorkerStats* stats, const Clock* clock) const {
  if (!initialised_ || worker < 0 || worker >= workers_) return;
  const int h = config_.geometry.height;
  if (y0 < 0) y0 = 0;
  if (y1 > h) y1 = h;
  if (y0 >= y1) return;

  StripState s{};
  s.input = &input;
  s.frame = frame;
  s.y0 = y0;
  s.y1 = y1;
  s.taps = taps;
  s.tap_count = tap_count;
  s.stats = stats;
  s.clock = clock;
  // Carve this worker's memory exactly as Configure counted it.
  Arena arena(Span<uint8_t>{workers_base_ + static_cast<size_t>(worker) * worker_bytes_, worker_bytes_});
  const size_t pitch = static_cast<size_t>(config_.geometry.width + 2 * margin_);
  for (int j = 0; j <= run_count_; ++j) {
    s.ring[j] = arena.Take<uint32_t>(static_cast<size_t>(ring_slots_[j]) * ring_channels_[j] * pitch);
    s.tag[j] = arena.Take<int32_t>(static_cast<size_t>(ring_slots_[j]));
    for (int k = 0; k < ring_slots_[j]; ++k) s.tag[j][k] = -1;
  }
  s.scratch = arena.Take<uint8_t>(scratch_bytes_);
  s.state = arena.Take<uint8_t>(state_bytes_);
  for (int i = 0; i < run_count_; ++i)
    if (run_[i]->StateBytes(config_.geometry.width) > 0) run_[i]->BeginStrip(s.state + state_offset_[i]);
  s.rows = arena.Take<RowIn>(static_cast<size_t>(max_window_));
  s.rows_stage = -1;

  // Every ring produces at least the strip's rows [y0, y1) (its taps and
  // statistics cover them even where no later stage reads them, e.g. rows a
  // distortion window skips), plus what the next stage's windows read. The
  // first row a ring produces: the lower of y0 and the lowest row the next
  // stage reads for its own first row (windows never move back).
  int first = y0;
  for (int j = run_count_; j >= 0; --j) {
    if (first > y0) first = y0;
    s.next[j] = first;
    if (j > 0) {
      int hi = 0;
      ReflectedSpan(run_[j - 1]->InputRows(first, h), h, &first, &hi);
    }
  }
  for (int y = y0; y < y1; ++y) Produce(s, run_count_, y);
  // Rows of the strip no later stage needed: from the last ring down, so a
  // ring only moves on once every stage reading it is done.
  for (int j = run_count_ - 1; j >= 1; --j) Produce(s, j, y1 - 1);
}

void Pipeline::ProcessFrame(const FrameInput& input, uint32_t frame, int strip_rows, const Tap* taps,
                            int tap_count, WorkerStats* stats, const Clock* clock) const {
  if (strip_rows < 1) strip_rows = height();
  for (int y = 0; y < height(); y += strip_rows)
    ProcessStrip(input, frame, y, y + strip_rows, 0, taps, tap_count, stats, clock);
}

}  // namespace camsim
