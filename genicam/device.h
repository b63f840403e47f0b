// camsim-gige's device: an Aravis fake GigE Vision camera (GVCP + GVSP on
// one address) whose frames come from the core pipeline.
//
// Register writes: a client's write reaches the device's write filter
// (FilterClientWrite, behind genicam/fake_camera_hooks.h) as it arrives, and
// a value a feature never takes, a window off the sensor, an Auto lower
// limit above its upper limit, a window change while acquiring, a change
// the table's availability and lock formulas refuse (genicam/formula.h), or
// a pipeline setting the pipeline cannot run (planned there) is refused with
// its GVCP status. A sync step (every kSyncPeriodMs,
// and before every frame) takes the new values and rebuilds the pipeline for
// pipeline settings. A refused write reads back as the previous value and
// never reaches the pipeline. Settings apply from the next frame.
//
// Frames: the whole sensor is rendered (FrameRenderer, the code `camsim run`
// uses) and the Width x Height window at OffsetX/OffsetY is sent. Raw formats
// carry the sensor's DN (see genicam/register_table.cc PixelFormat), RGB8 the
// ISP's 8-bit output; 16-bit samples are little-endian (GigE Vision).
// Frame index i (SimFrameIndex) renders scene i mod SimSceneCount and keys
// the noise, as `camsim run --first-frame i` does for its first input.
#pragma once

#include <algorithm>
#include <array>
#include <atomic>
#include <chrono>
#include <cstdint>
#include <deque>
#include <map>
#include <memory>
#include <mutex>
#include <set>
#include <string>
#include <thread>
#include <vector>

#include "core/control/auto_exposure.h"
#include "genicam/fake_camera_hooks.h"
#include "genicam/formula.h"
#include "genicam/register_table.h"
#include "hal/gpio.h"
#include "host_tools/config.h"
#include "host_tools/io/exr_scene.h"
#include "host_tools/render.h"

typedef struct _ArvGvFakeCamera ArvGvFakeCamera;
typedef struct _ArvFakeCamera ArvFakeCamera;
typedef struct _ArvBuffer ArvBuffer;

namespace camsim::genicam {

// The free-run frame period: 1 / AcquisitionFrameRate, or the exposure
// time when that is longer (a frame cannot start before the last exposure
// ends, as on a camera without overlapped exposure).
inline std::chrono::steady_clock::duration FramePeriod(double rate_hz, double exposure_us) {
  const double seconds = std::max(1.0 / rate_hz, exposure_us * 1e-6);
  return std::chrono::duration_cast<std::chrono::steady_clock::duration>(std::chrono::duration<double>(seconds));
}

// Free run at AcquisitionFrameRate: the slot of the next frame given the
// previous frame's slot and the time the device is ready for it. On time or
// early: the previous slot plus one period (wait until then: no drift). Late
// by less than a period: start now, keeping that cadence (the next frame
// catches up). Later still: start now, and the cadence starts again there.
// So a render slower than the period gives frames as fast as it renders
// (Aravis's fake camera instead waits for the next whole multiple of the
// period on the clock: 8.6 fps at 25 fps for an 80 ms render, not 12).
struct FrameSlot {
  std::chrono::steady_clock::time_point slot;   // this frame's slot
  std::chrono::steady_clock::time_point start;  // when it may start (>= ready)
};
inline FrameSlot NextFrameSlot(std::chrono::steady_clock::time_point previous,
                               std::chrono::steady_clock::time_point ready,
                               std::chrono::steady_clock::duration period) {
  const auto due = previous + period;
  if (ready <= due) return {due, due};
  if (ready < due + period) return {due, ready};
  return {ready, ready};
}

inline constexpr int kSyncPeriodMs = 2;
inline constexpr int kMaxLinkMbps = 100000;  // DeviceOptions::link_mbps (100 GbE)
// Triggers taken but not yet made into frames (TakeTrigger); more are dropped.
inline constexpr size_t kMaxPendingTriggers = 16;

struct DeviceOptions {
  std::string config_path;              // empty: defaults
  std::vector<std::string> overrides;   // section.key=value
  std::vector<std::string> inputs;      // EXR files / directories / patterns
  std::string pattern;                  // or a synthetic scene (ScenePatternNames)
  int pattern_width = 640, pattern_height = 480;  // pattern size when [sensor] gives none
  std::string address = "127.0.0.1";
  std::string serial = "CS0001";
  std::string trigger_line, strobe_line;  // CHIP:OFFSET (libgpiod); empty: none
  hal::InputLine* trigger = nullptr;      // or lines owned by the caller (tests, rigs)
  hal::OutputLine* strobe = nullptr;
  int threads = 2, strip_rows = 0;  // strip_rows 0: host::StripRows' default
  std::string xml_path;  // where the generated XML is written; empty: a file in $TMPDIR
  // Send the first frame's GVSP leader ahead of the frame so an Aravis
  // receiver has grown its socket buffer before the burst (GigeDevice::PrimeReceiver).
  bool prime_first_frame = true;
  // The link the stream is paced by (Mb/s; 0: no limit, packets go out as
  // the fake camera sends them). GevSCPD's delay is added either way.
  int link_mbps = 1000;  // 0 .. kMaxLinkMbps
  // Probe the controller's heartbeat (GigeDevice::ProbeHeartbeat); false:
  // only a client's packet ends a silent controller's control (a test of
  // that case), and only its read of the privilege register renews it.
  bool probe_heartbeat = true;
  // UserSetControl's file (--user-set-file): UserSetSave and UserSetDefault
  // write it (atomically), and the start loads it and UserSetDefault's set;
  // empty: user sets live for the process only.
  std::string user_set_file;
  // false: no network and no threads (register logic only: fuzzing, unit
  // tests); drive it with WriteMemory / SyncNow / RenderNow.
  bool serve = true;
};

// Names of --pattern scenes and the scene itself (deterministic, HDR).
std::vector<std::string> ScenePatternNames();
bool MakePatternScene(const std::string& name, int width, int height, io::SceneFrame* out, std::string* error);

// Loads the scenes a DeviceOptions names (inputs or pattern) and the finished
// configuration; shared by the device and the tests' reference renders.
bool LoadDeviceScenes(const DeviceOptions& o, host::RunConfig* config, host::Origins* origins,
                      std::vector<io::SceneFrame>* scenes, std::string* error);

// Converts one frame's taps to the wire format: window (x, y, w, h) of a
// full-sensor raw tap (uint16 DN, adc_bits) or RGB tap (uint8 x3; the
// formats FromIsp(format, cfa) names). out must hold FrameBytes(format, w, h).
void ConvertWindow(uint32_t format, Cfa cfa, int adc_bits, const uint16_t* raw, const uint8_t* rgb, int sensor_width,
                   int x, int y, int w, int h, uint8_t* out);

// ReverseX / ReverseY: mirrors a converted window in place (w x h pixels of
// bytes_per_pixel bytes), as the sensor reads it out mirrored.
void MirrorWindow(uint8_t* out, int w, int h, int bytes_per_pixel, bool reverse_x, bool reverse_y);

class GigeDevice {
 public:
  static std::unique_ptr<GigeDevice> Start(const DeviceOptions& options, std::string* error);
  ~GigeDevice();
  GigeDevice(const GigeDevice&) = delete;
  GigeDevice& operator=(const GigeDevice&) = delete;

  const std::vector<Feature>& table() const { return table_; }
  const std::string& xml_path() const { return xml_path_; }
  const SensorInfo& sensor() const { return sensor_; }
  // The user set the start loaded, for the start-up line: "user set UserSet1
  // from PATH (its UserSetDefault)", or "the Default user set (...)" saying why.
  const std::string& start_user_set() const { return start_user_set_; }
  // The frames the registers now give: "320x480 at (0, 0) in BayerRG12".
  std::string FrameFormat() const;
  uint64_t frames_sent() const { return frames_sent_.load(); }
  // Client writes refused: by the device (values, the window, commands) and
  // by the hooks in front of its camera (fake_camera_hooks.h, WritesRefusedAt).
  uint64_t writes_refused() const;
  // Triggers dropped: beyond kMaxPendingTriggers waiting, or a TriggerSoftware while the acquisition is stopped.
  uint64_t triggers_dropped() const { return triggers_dropped_.load(); }
  uint64_t trigger_edges() const { return trigger_edges_.load(); }  // edges the trigger line delivered, handled
  // Pipelines planned (a client's pipeline write, a sync or auto-exposure
  // step that found no plan kept for its settings, an auto-exposure range check).
  uint64_t pipelines_planned() const { return pipelines_planned_.load(); }
  // Last error of a GPIO line (empty when none).
  std::string line_error() const;

  // Register access as a client's would do it (false: refused, in part or
  // whole, or outside the memory map), one sync, one frame
  // rendered into *frame (as the fake camera fills a buffer), and the device's
  // invariants (empty when they hold: every writable register holds its value
  // in use, every value in use is valid, the window is on the sensor, Gain
  // and GainRaw agree, Line0 has no source).
  bool WriteMemory(uint32_t address, const void* data, uint32_t size);
  bool ReadMemory(uint32_t address, void* data, uint32_t size) const;  // as a client's read
  void SyncNow();
  bool RenderNow(std::vector<uint8_t>* frame);
  std::string CheckInvariants() const;

 private:
  using Registers = std::map<uint32_t, uint64_t>;  // address -> value (Float: the double's bits)
  GigeDevice() = default;
  bool Init(const DeviceOptions& o, std::string* error);
  uint32_t Read(uint32_t address) const;
  void Write(uint32_t address, uint32_t value);
  double ReadDouble(uint32_t address) const;
  void WriteDouble(uint32_t address, double value);
  uint64_t ReadFeature(const Feature& f) const;
  void WriteFeature(const Feature& f, uint64_t value);
  // readout: ReverseX + 2 * ReverseY a Bayer PixelFormat must match; -1: the registers'.
  bool Valid(const Feature& f, uint64_t value, int readout = -1) const;
  int Readout() const;  // ReverseX + 2 * ReverseY in the registers
  void WriteReadoutMax();  // WidthMax, HeightMax from the binning and decimation registers
  double AppliedDouble(uint32_t address) const;
  uint32_t Applied(uint32_t address) const { return static_cast<uint32_t>(applied_.at(address)); }
  void SetApplied(uint32_t address, uint64_t value);  // register and applied value
  void Sync();                                            // under mutex_
  // The pipeline for registers r (SimStageEnable's included), configured
  // and checked but without tables; the renderer in use is not touched.
  // Reconfigure installs it.
  bool PlanFor(const Registers& r, host::PlannedPipeline* planned, std::string* error) const;
  // The registers PlanFor reads, in a fixed order: equal keys, equal plans.
  std::vector<uint64_t> PlanKey(const Registers& r) const;
  // Installs the plan kept for r's key (and lets it go), or else PlanFor's;
  // under mutex_ and the camera's client-write lock.
  bool Reconfigure(const Registers& r, std::string* error);
  bool IsPipelineRegister(uint32_t address) const;  // a change reconfigures the pipeline
  // A register's feature for messages: a selected one by its selector's
  // entry (SimStageEnable[Stage_demosaic]), not its index.
  std::string RegisterName(const Feature& r) const;
  // Whether the pipeline can run the registers once a client's write (its
  // bytes as the filter left them) is stored: true when it changes no
  // pipeline register. A plan it makes is kept for the sync (kept_plan_).
  // Under the camera's client-write lock.
  bool PipelineTakes(uint32_t address, uint32_t size, const uint8_t* data) const;
  bool Install(host::PlannedPipeline planned, std::string* error);  // puts a plan in use; under mutex_
  void WriteDerived();  // registers that follow from the applied values
  void WriteResultingFrameRate();  // AcquisitionResultingFrameRate
  uint64_t PacketDelayNs() const;   // GevSCPD in ns (its ticks at the timestamp tick frequency)
  void WriteLineStatus();  // each line's level
  // Sets the strobe line active (true) or idle, inverted on the wire by
  // LineInverter[Line1]; a failure goes to line_error_.
  void DriveStrobe(bool active);
  void Fill(ArvBuffer* buffer, uint32_t pixel_format);
  // Free run (under mutex_): the fake camera stays in its trigger mode and
  // makes a frame when asked, so its one thread keeps answering control
  // packets between frames. PaceFreeRun asks for the next frame when its
  // slot has come (NextFrameSlot at AcquisitionFrameRate) and returns when
  // the next slot starts; TakeFrameSlot records the slot of the frame begun.
  std::chrono::steady_clock::time_point PaceFreeRun();
  void TakeFrameSlot();
  // Under mutex_: a client's stop since the last look ends the acquisition
  // (the next frame is a new one's first), and a withdrawn free-run request
  // is no longer pending, however soon the next start came.
  void TakeClientStops();
  // From FilterClientWrite: the fake camera's trigger flag cleared (and, at a
  // stop, the queued triggers) before its thread can act on them.
  void WithdrawFreeRun(bool stop);
  std::chrono::steady_clock::duration FreeRunPeriod() const;  // 0: the next frame goes at once
  void FillLocked(ArvBuffer* buffer, uint32_t pixel_format);  // under mutex_
  void PrimeReceiver(ArvBuffer* buffer, uint64_t dest, bool chunks);  // not under mutex_
  // In chunk mode: the frame's chunks, for the hooks to send after its image (under mutex_).
  void QueueChunks(ArvBuffer* buffer, uint32_t pixel_format);
  void AutoAdjust(double mean_fraction);  // under mutex_: ExposureAuto / GainAuto
  // Under mutex_: BalanceWhiteAuto on the frame just rendered (raw_, the
  // window x, y, w, h): gray world, the gains applied from the next frame.
  void BalanceWhite(int x, int y, int w, int h);
  Registers AutoRegisters(const ExposureSettings& s) const;  // applied_ with the controller's settings
  bool RestartAuto();                       // the controller afresh on auto_config_ from the applied values
  void StopAuto(const std::string& error);  // both Auto features Off, the error logged
  // Narrows auto_config_ to what the pipeline accepts between the applied settings and a refused request.
  void LimitAutoRange(const ExposureSettings& want);
  void LogOnce(const std::string& key, const std::string& message);  // to stderr, once per key
  // UserSetControl. A set holds the registers UserSetRegisters lists
  // (address -> value); user_sets_[0] is Default, the start-up
  // configuration; a UserSetN never saved holds Default's values.
  struct UserSet {
    bool saved = false;
    Registers values;
  };
  std::array<UserSet, kUserSetCount> user_sets_;
  std::string user_set_file_;
  std::string start_user_set_;  // start_user_set()
  std::vector<const Feature*> UserSetRegisters() const;  // registers_ a set holds, in table order
  Registers UserSetNow() const;  // their values in memory (as the client's writes left them)
  void RestoreRegisters(const Registers& r);  // device writes of r's values
  // Under the camera's client-write lock: the set's values written as a
  // client would (the Auto features Off first, then the format, the window,
  // the rest, the Auto features last), each through FilterClientWrite. All
  // or nothing: at the first refusal every register goes back, and *why
  // names the write and the reason.
  GevStatus LoadUserSet(int64_t set, std::string* why);
  bool WriteUserSetFile(uint64_t default_set, std::string* error) const;
  // At Init: the file's sets (each checked by a trial load) and UserSetDefault's set loaded.
  bool ReadUserSetFile(std::string* error);
  std::string UserSetValueText(const Feature& f, uint64_t v) const;  // the file's text of a value
  mutable std::string* refusal_capture_ = nullptr;  // set: LogRefusal also keeps its first "what: why" here
  // One line on stderr per refused write: "refused NAME = VALUE: WHY" (or
  // per dropped trigger: verb "dropped"), at most kRefusalLinesPerSecond a
  // second (a client could flood it); the next line logged, or else
  // FlushRefusalLog, says how many were left out. Thread-safe.
  void LogRefusal(const std::string& what, const std::string& why, const char* verb = "refused") const;
  // The count of lines left out, said once their second is over (every
  // sync) or at the end (the destructor), so a flood's last lines are never
  // lost without a trace. Thread-safe.
  void FlushRefusalLog(bool at_end) const;
  // Why a feature never takes v (empty when it does): its range, increment, entries.
  std::string WhyInvalid(const Feature& f, uint64_t v) const;
  std::string ValueText(const Feature& f, uint64_t v) const;  // v as a client wrote it
  // A trigger taken (under trigger_mutex_): queued, with the frame index a
  // bus pulse carries (kNextIndex: the next SimFrameIndex). line0_high: the
  // trigger input's level just after the trigger (after a Line0 edge, the
  // level that edge left): the frame's LineStatus bit 0. Its exposure starts
  // TriggerDelay from `at`, or when the previous trigger's exposure ends if
  // that is later, and lasts ExposureTime; the fake camera is asked for its frame when it has ended
  // (FireDueTrigger), as a camera reads a frame out after its exposure.
  // `at`: when the trigger came (a Line0 edge's time plus LineDebouncerTime).
  // width (ExposureMode TriggerWidth): the exposure lasts until EndTriggerWidth.
  void TakeTrigger(int64_t index, bool line0_high, std::chrono::steady_clock::time_point at, bool width = false);
  // Under trigger_mutex_: the open TriggerWidth exposure (if any) ends at `at`
  // (Line0's opposite edge), TriggerDelay later as it began.
  void EndTriggerWidth(std::chrono::steady_clock::time_point at);
  // Under trigger_mutex_: Line0's electrical level `electrical` taken (stable
  // for LineDebouncerTime) at `at`: LineStatus, and a trigger on the
  // activation edge. index: the frame index its edge carried (or kNextIndex).
  void TakeLine0Level(bool electrical, std::chrono::steady_clock::time_point at, int64_t index);
  // Under trigger_mutex_: asks the fake camera for the oldest trigger's frame
  // once its exposure has ended; returns when to call again (max: no trigger waits).
  std::chrono::steady_clock::time_point FireDueTrigger(std::chrono::steady_clock::time_point now);
  static constexpr int64_t kNextIndex = -1;
  void RestartStream();  // not under mutex_
  // While a client is in control: every kHeartbeatProbeMs, a GVCP read
  // sent to the camera from the device's own socket (not under mutex_). Of
  // the privilege register when the controller sent any command since the
  // last probe (ControllerPackets): that read renews its heartbeat, as GigE
  // Vision has every command do. Else, while it acquires, of the version
  // register: the fake camera checks its controller's heartbeat only when a
  // packet comes, so a silent controller loses control (and the sync stops
  // the acquisition) within the heartbeat timeout and a probe period, not at
  // the next client's packet.
  void ProbeHeartbeat(bool acquiring);
  bool probe_heartbeat_ = true;
  int probe_fd_ = -1;
  uint64_t controller_packets_ = 0;  // ControllerPackets at the last probe
  std::chrono::steady_clock::time_point last_probe_{};
  void SyncLoop();
  void TriggerLoop();
  static void FillThunk(ArvBuffer* buffer, void* self, uint32_t exposure_us, uint32_t gain, uint32_t pixel_format);
  // The write filter (fake_camera_hooks.h) on clients' writes, as they arrive.
  static WriteVerdict FilterClientWrite(void* self, uint32_t address, uint32_t size, uint8_t* data);
  // Why a command's register (TriggerSoftware, UserSetSave) is not
  // available now (its rule, RuleWhy), or "" when it is.
  std::string CommandRefusal(uint32_t address) const;

  std::vector<Feature> table_;
  std::vector<Feature> registers_;  // FeatureRegisters(table_): what Sync reads and checks
  // The table's availability and lock formulas on registers_ (RegisterRules):
  // the write filter refuses what they refuse.
  std::vector<RegisterRule> rules_;
  SensorInfo sensor_;
  std::string xml_path_;
  bool own_xml_ = false;
  host::RunConfig base_config_;  // as loaded (unfinished)
  host::Origins origins_;
  host::Origins register_origins_;  // origins_ with the keys registers set named by register (PlanFor's errors)
  std::vector<io::SceneFrame> scenes_;
  int current_scene_ = -1;
  std::vector<StageId> configured_stages_;
  std::unique_ptr<host::FrameRenderer> renderer_;
  // The last plan the write filter made that the pipeline can run, for the
  // sync that installs those settings (under the camera's client-write
  // lock; Reconfigure takes it when the keys match, and an auto-exposure
  // step in between leaves it). A plan depends only on its key and the
  // device's fixed configuration: the renderer in use lends copies of what
  // would come out the same.
  struct KeptPlan {
    std::vector<uint64_t> key;
    host::PlannedPipeline planned;
  };
  mutable std::unique_ptr<KeptPlan> kept_plan_;
  Registers applied_;
  uint64_t seed_register_at_start_ = 0;
  std::vector<uint16_t> raw_;   // full-sensor taps
  std::vector<uint8_t> rgb_;
  std::vector<uint16_t> reduced_raw_;  // the taps binned and decimated (WidthMax x HeightMax)
  std::vector<uint8_t> reduced_rgb_;
  // TestPattern's codes in place of the taps (RGB: R = G = B) for the
  // whole sensor, kept while the pattern and the sensor stay the same.
  // GreyHorizontalRampMoving holds the horizontal ramp and then its first
  // SensorWidth - 1 codes again: every row is the same ramp, so the frame
  // read from code i mod SensorWidth on is frame i's. KeepPatternCodes fills them.
  struct PatternCodes {
    int64_t pattern = kTestPatternOff;
    int width = 0, height = 0, bits = 0;
    bool has_rgb = false;
    std::vector<uint16_t> raw;
    std::vector<uint8_t> rgb;
  };
  PatternCodes pattern_codes_;
  void KeepPatternCodes(int64_t pattern, bool with_rgb);  // under mutex_
  AutoExposure auto_exposure_;  // state of ExposureAuto / GainAuto between frames
  AutoExposureConfig auto_config_;  // its configuration (ranges narrowed by LimitAutoRange)
  std::set<std::string> logged_;    // LogOnce keys
  bool auto_state_valid_ = false;
  // Modes, target, exposure, gain and f-number applied: a change the
  // controller did not make restarts it.
  std::array<uint64_t, 10> AutoKey() const;  // under mutex_
  std::array<uint64_t, 10> auto_key_{};      // AutoKey() as the controller last left it

  std::unique_ptr<hal::InputLine> own_trigger_;
  std::unique_ptr<hal::OutputLine> own_strobe_;
  hal::InputLine* trigger_ = nullptr;
  hal::OutputLine* strobe_ = nullptr;
  std::string line_error_;
  // LineStatus: the trigger input after its last edge (low before one) and
  // LineInverter[Line0], the strobe output as last driven on the wire.
  std::atomic<bool> trigger_level_{false};
  bool strobe_level_ = false;
  // Under trigger_mutex_: Line0's electrical level after its last edge, and
  // LineInverter[Line0] as of the last sync.
  bool line0_electrical_ = false;
  bool line0_inverted_ = false;
  std::chrono::steady_clock::duration line0_debounce_{};  // LineDebouncerTime as of the last sync

  ArvGvFakeCamera* gv_ = nullptr;
  ArvFakeCamera* fake_ = nullptr;
  mutable std::mutex mutex_;
  std::thread sync_thread_, trigger_thread_;
  std::atomic<bool> stop_{false};
  std::atomic<bool> ready_{false};  // Init has set the values in use (FilterClientWrite refuses writes before)
  std::atomic<uint64_t> frames_sent_{0}, writes_refused_{0}, triggers_dropped_{0}, trigger_edges_{0};
  mutable std::atomic<uint64_t> pipelines_planned_{0};
  // The trigger thread takes edges under its own lock, never waiting for a
  // frame being rendered (mutex_): the line's queue stays drained.
  mutable std::mutex trigger_mutex_;
  // Under trigger_mutex_: triggers not yet made into frames, oldest first
  // (frame index or kNextIndex). The fake camera has one trigger flag and,
  // before a stream's first frame, reads it only every 100 ms: the queue
  // gives each trigger its own frame.
  struct PendingTrigger {
    int64_t index;    // frame index or kNextIndex
    bool line0_high;  // Line0's level at the trigger (ChunkLineStatusAll of its frame)
    std::chrono::steady_clock::time_point exposure_start, exposure_end;
    bool width = false;       // ExposureMode TriggerWidth: the exposure is exposure_end - exposure_start
    bool width_open = false;  // its end (Line0's opposite edge) not yet come: exposure_end is max()
  };
  std::deque<PendingTrigger> pending_triggers_;
  // Under trigger_mutex_: when the last trigger's exposure ends (the next
  // one's starts no earlier), and ExposureTime and TriggerDelay as of the
  // last sync (the triggers' exposure and delay; written under mutex_ and trigger_mutex_).
  std::chrono::steady_clock::time_point exposure_busy_until_{};
  std::chrono::steady_clock::duration trigger_exposure_{}, trigger_delay_{};
  bool trigger_requested_ = false;  // under trigger_mutex_: the oldest trigger's frame asked of the fake camera
  // Under trigger_mutex_, as of the last sync: TriggerMode On with source
  // Line0, and the edge that triggers (TriggerActivation).
  bool line0_armed_ = false;
  bool line0_rising_ = true;
  bool line0_width_ = false;  // and ExposureMode TriggerWidth
  std::atomic<bool> overrun_logged_{false};
  uint32_t frames_in_acquisition_ = 0;
  bool was_acquiring_ = false;
  std::chrono::steady_clock::time_point frame_slot_{};  // the last frame's slot (NextFrameSlot)
  bool free_run_requested_ = false;  // a free-run frame asked of the fake camera and not yet begun
  uint64_t stream_dest_ = 0;         // stream destination at the last sync
  bool sync_saw_acquiring_ = false;  // acquisition at the last sync
  bool restart_stream_ = false;
  // RestartStream clears the acquisition register for a moment: the window stays locked.
  std::atomic<bool> restarting_{false};
  std::atomic<uint64_t> acquisition_stops_{0};  // clients' stops (FilterClientWrite)
  // Free-run requests FilterClientWrite withdrew (a stop, TriggerMode On):
  // it clears the fake camera's flag at once, as the write arrives.
  std::atomic<uint64_t> free_run_withdrawn_{0};
  // Under mutex_: the counts TakeClientStops last saw.
  uint64_t stops_seen_ = 0, withdrawn_seen_ = 0;
  std::string address_;
  uint64_t hooks_refused_before_ = 0;  // WritesRefusedAt(address_) before the camera served
  bool prime_first_frame_ = true;
  double last_render_s_ = 0;  // the last frame's rendering time (0: none yet)
  double last_send_s_ = 0;    // the last frame's paced sending time (FrameSendSeconds)
  uint64_t link_bits_per_s_ = 0;  // DeviceOptions::link_mbps
  // What the last frame was rendered with (its chunks).
  double frame_exposure_us_ = 0, frame_gain_db_ = 0, frame_black_level_dn_ = 0;
  uint32_t frame_index_ = 0;
  uint32_t frame_line_status_ = 0;  // ChunkLineStatusAll: bit i = line i as the frame started
  uint64_t primed_dest_ = 0;  // stream destination the last primed frame went to
  // GVSP block IDs: 1 for the first frame after a client writes the stream
  // channel's port or destination (opens a stream), then on, 65535 -> 1 (0
  // is not a block ID). Aravis's fake camera counts from 65400 and never resets.
  std::atomic<uint64_t> stream_opens_{0};  // FilterClientWrite: writes of GevSCPHostPort / GevSCDA
  uint64_t stream_opens_seen_ = 0;         // under mutex_
  uint32_t block_id_ = 0;                  // the last frame's (under mutex_)
  // The device's timestamp (frame timestamps, GevTimestampValue), in ns:
  // the steady clock plus clock_offset_ns_ (set at Init so that the clock
  // then reads the host's real time since the epoch) less the origin (0; a
  // GevTimestampControlReset moves it to the time of the reset). On the
  // steady clock, so a frame's time is its slot's or edge's, to the ns, and
  // the host's clock being set does not move it.
  int64_t clock_offset_ns_ = 0;
  std::atomic<int64_t> timestamp_origin_ns_{0};
  uint64_t DeviceTime(std::chrono::steady_clock::time_point t) const;
  uint64_t TimestampNow() const { return DeviceTime(std::chrono::steady_clock::now()); }
  // LogRefusal's rate limit: lines in the current second, and those left out.
  static constexpr int kRefusalLinesPerSecond = 20;
  mutable std::mutex refusal_log_mutex_;
  mutable std::chrono::steady_clock::time_point refusal_window_{};
  mutable int refusal_lines_ = 0;
  mutable uint64_t refusals_unlogged_ = 0;
};

}  // namespace camsim::genicam
