#include "genicam/device.h"

#include <arv.h>

#include <arpa/inet.h>
#include <ifaddrs.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>

#include "core/isp/gamma.h"
#include "genicam/fake_camera_hooks.h"
#include "host_tools/io/image_write.h"
#include "host_tools/io/sequence.h"

namespace camsim::genicam {
namespace {

// Registers the pipeline depends on: a change reconfigures it.
constexpr uint32_t kPipelineRegisters[] = {reg::kExposureTime, reg::kGain,   reg::kBlackLevel,
                                           reg::kSimFNumber,   reg::kSimSeed, reg::kSimFocusDistance};
// The payload's registers: frozen while acquiring (the stream's buffers are
// sized) and while TLParamsLocked is 1: the window, the format and chunk mode
// with every ChunkEnable.
// (ReverseX and ReverseY change a Bayer format's phase.)
// (Binning and decimation change the readout the window is cut from.)
constexpr uint32_t kWindowRegisters[] = {reg::kWidth,
                                         reg::kHeight,
                                         reg::kOffsetX,
                                         reg::kOffsetY,
                                         reg::kPixelFormat,
                                         reg::kChunkModeActive,
                                         reg::kReverseX,
                                         reg::kReverseY,
                                         reg::kBinningHorizontal,
                                         reg::kBinningVertical,
                                         reg::kBinningHorizontalMode,
                                         reg::kBinningVerticalMode,
                                         reg::kDecimationHorizontal,
                                         reg::kDecimationVertical};
// The binning and decimation registers (factors and modes).
constexpr uint32_t kReductionRegisters[] = {reg::kBinningHorizontal, reg::kBinningVertical,
                                            reg::kBinningHorizontalMode, reg::kBinningVerticalMode,
                                            reg::kDecimationHorizontal, reg::kDecimationVertical};
// The readout's extent on axis a (0: x, 1: y), WidthMax or HeightMax, for
// the factors `at` gives (a register's value; clamped to the factors' range).
template <class At>
int ReadoutExtent(const SensorInfo& s, int a, At at) {
  const auto factor = [&](uint32_t r) { return std::clamp(static_cast<int>(at(r)), 1, reg::kMaxReduction); };
  const int step = s.cfa == Cfa::kMono ? 1 : 2;
  return a == 0 ? ReducedExtent(s.width, step, factor(reg::kBinningHorizontal), factor(reg::kDecimationHorizontal))
                : ReducedExtent(s.height, step, factor(reg::kBinningVertical), factor(reg::kDecimationVertical));
}
constexpr auto kGeometryRegisters = [] {
  std::array<uint32_t, std::size(kWindowRegisters) + kChunkCount> r{};
  size_t n = 0;
  for (const uint32_t w : kWindowRegisters) r[n++] = w;
  for (int i = 0; i < kChunkCount; ++i) r[n++] = reg::SelectedAddress(reg::kChunkEnable, static_cast<size_t>(i));
  return r;
}();
// Gamma's range is the core's gamma range (1 / x maps it onto itself).
static_assert(reg::kMinGamma == GammaStage::kMinGamma && reg::kMaxGamma == GammaStage::kMaxGamma &&
              reg::kMinGamma * reg::kMaxGamma == 1.0);
// A frame's chunk bytes after its image: at most 3 bytes of padding, the image's tag and every chunk.
static_assert(3 + kChunkTagBytes + kChunkCount * (kChunkDataBytes + kChunkTagBytes) <= kMaxChunkTail);
// The Auto features' limits (Float registers, SFNC names <name>LowerLimit
// and <name>UpperLimit): the lower one stays at or below the upper one.
struct AutoLimits {
  uint32_t lower, upper;
  const char* name;
};
constexpr AutoLimits kAutoLimits[] = {
    {reg::kAutoExposureTimeLowerLimit, reg::kAutoExposureTimeUpperLimit, "AutoExposureTime"},
    {reg::kAutoGainLowerLimit, reg::kAutoGainUpperLimit, "AutoGain"}};

// The features a user set holds (SFNC UserSetControl): the writable
// settings of the image, acquisition, trigger, analog, line, chunk and
// simulation features, not the transport layer's, the selectors, commands
// or SimFrameIndex (a running count). Each selected one with every selection.
constexpr const char* kUserSetFeatures[] = {
    "Width", "Height", "OffsetX", "OffsetY", "ReverseX", "ReverseY", "BinningHorizontal", "BinningVertical",
    "BinningHorizontalMode", "BinningVerticalMode", "DecimationHorizontal", "DecimationVertical", "PixelFormat",
    "TestPattern",
    "AcquisitionMode", "AcquisitionFrameCount", "AcquisitionFrameRate", "AcquisitionFrameRateEnable", "ExposureMode",
    "ExposureTime", "ExposureAuto",
    "AutoExposureTimeLowerLimit", "AutoExposureTimeUpperLimit", "TriggerMode", "TriggerSource", "TriggerActivation",
    "TriggerDelay", "Gain", "GainAuto", "AutoGainLowerLimit", "AutoGainUpperLimit", "BlackLevel", "BalanceRatio",
    "BalanceWhiteAuto", "Gamma", "GammaEnable", "LineSource", "LineInverter", "LineDebouncerTime", "ChunkModeActive",
    "ChunkEnable", "SimFNumber",
    "SimFocusDistance", "SimSeed", "SimStageEnable", "SimAutoTarget"};

// A stable MAC address for a serial number: locally administered unicast
// (first byte 0x02) and 40 bits of the serial's FNV-1a hash, so the
// cameras of a rig (one serial each) differ.
uint64_t MacOfSerial(const std::string& serial) {
  uint64_t hash = 14695981039346656037ull;
  for (const char c : serial) hash = (hash ^ static_cast<unsigned char>(c)) * 1099511628211ull;
  return uint64_t{0x02} << 40 | (hash & 0xffffffffffull);
}
int64_t RealTimeNs() { return g_get_real_time() * 1000; }
int64_t SteadyNs(std::chrono::steady_clock::time_point t) {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(t.time_since_epoch()).count();
}
// A masked feature's value (Feature::low_bits, shift) in its register's bits v.
uint64_t MaskedValue(const Feature& f, uint64_t v) {
  return f.low_bits > 0 ? (v >> f.shift) & ((uint64_t{1} << f.low_bits) - 1) : v;
}
// A feature whose value the device checks: writable, its register's own
// (not an alias), and a value (not a string, command or formula).
bool Checked(const Feature& f) {
  return f.writable && f.alias_of.empty() && f.kind != Kind::kString && f.kind != Kind::kCommand &&
         f.kind != Kind::kSwissKnife;
}
// Registers only the device writes: the fake camera's that camsim derives
// from its own (exposure, frame period, the trigger block), and camsim's
// range (its first register up to the XML after the register memory), of
// which a client writes only what the XML describes. (The fake camera's acquisition register stays a
// client's: its writes are the stops the filter counts.)
bool IsDeviceRange(uint32_t r) {
  using namespace reg;
  return r == kFakeExposureUs || r == kFakeFramePeriodUs || (r >= kFakeTriggerMode && r <= kFakeTriggerSoftware) ||
         (r >= kWidthMax && r < ARV_FAKE_CAMERA_MEMORY_SIZE);
}
// A client write of `size` bytes at `address` (whole registers,
// fake_camera_hooks.h): whether it covers register r, and r's value in it.
bool Covers(uint32_t address, uint32_t size, uint32_t r) {
  return address <= r && uint64_t{r} + 4 <= uint64_t{address} + size;
}
uint32_t ValueAt(uint32_t address, const uint8_t* data, uint32_t r) {
  const uint8_t* v = data + (r - address);
  return uint32_t{v[0]} << 24 | uint32_t{v[1]} << 16 | uint32_t{v[2]} << 8 | v[3];
}
using reg::kControlChannelPrivilege, reg::kStreamPort, reg::kStreamDestAddress;
// The fake camera polls its software-trigger register at this rate when in
// trigger mode (its own default is 25 Hz): 1 kHz keeps trigger latency ~1 ms.
constexpr double kTriggerPollHz = 1000.0;
// The first frame of a stream: the leader goes out this long before the
// frame's burst (PrimeReceiver). Aravis's receiver gives up on a frame whose
// next packet is 20 ms late (packet-timeout default; it then asks for resends)
// and drops it after 100 ms (frame-retention): 10 ms is well inside both and
// far longer than a receiver thread's wake-up.
constexpr int kPrimeDelayMs = 10;
constexpr int kGvspLeaderBytes = kGvspHeaderBytes + 36;  // GVSP header + image data leader
// RestartStream: rounds, and how long the fake camera's thread may take to
// answer a read (it answers between frames; a debug build renders slowly).
constexpr int kRestartRounds = 4;
constexpr int kRestartAnswerMs = 2000;
// ProbeHeartbeat's period: a silent controller's acquisition stops within
// its heartbeat timeout, this, and the fake camera's answer (between frames);
// a controller's command renews its heartbeat at most this much later.
constexpr int kHeartbeatProbeMs = 100;

uint64_t DoubleBits(double v) {
  uint64_t b;
  std::memcpy(&b, &v, 8);
  return b;
}
double BitsDouble(uint64_t b) {
  double v;
  std::memcpy(&v, &b, 8);
  return v;
}
// Gain (dB) and GainRaw (0.1 dB steps): one setting in two units.
uint64_t GainRawOf(double db) { return static_cast<uint64_t>(std::lround(db * 10)); }
double GainDbOf(uint64_t raw) { return static_cast<double>(raw) / 10.0; }
// A camera applies Gain in its raw steps: the nearest one is the Gain in use
// and the one read back (GainDbOf(GainRawOf(x)) is its own quantisation).
double QuantiseGain(double db) { return GainDbOf(GainRawOf(db)); }
constexpr double kMaxGainDb = 48.0;  // Gain's Max in the XML
// A register's feature in the table (a selected one's, before its "[i]"),
// with every entry: what a refusal message names.
const Feature& TableFeature(const std::vector<Feature>& table, const Feature& r) {
  const Feature* f = FindFeature(table, r.name.substr(0, r.name.find('[')));
  return f != nullptr ? *f : r;
}
std::string HexAddress(uint32_t a) {  // "0x80a0": a register a refusal names by address
  char b[16];
  std::snprintf(b, sizeof b, "0x%x", a);
  return b;
}
std::string Fmt(double v) {
  char b[32];
  std::snprintf(b, sizeof b, "%.6g", v);
  return b;
}

// The sensor's entry in a plan, or nullptr when it does not run.
const PlanEntry* RunningSensor(const Plan& plan) {
  for (int i = 0; i < plan.count; ++i)
    if (plan.entries[i].runs && plan.entries[i].id == StageId::kSensor) return &plan.entries[i];
  return nullptr;
}
// The raw tap (raw_) and the raw formats hold one sample per pixel, which
// the sensor gives only after the cfa stage.
constexpr const char* kSensorNeedsCfa =
    "the sensor must give one sample per pixel (the raw formats): the cfa stage stays on";

// Whether a network interface has exactly this IPv4 address. Aravis's fake
// camera serves only on an interface's own address; bind() alone would
// accept any address of 127.0.0.0/8 on Linux.
bool InterfaceHasAddress(const in_addr& address) {
  ifaddrs* list = nullptr;
  if (getifaddrs(&list) != 0) return true;  // cannot tell: let the fake camera report it
  bool found = false;
  for (const ifaddrs* i = list; i && !found; i = i->ifa_next)
    found = i->ifa_addr && i->ifa_addr->sa_family == AF_INET &&
            reinterpret_cast<const sockaddr_in*>(i->ifa_addr)->sin_addr.s_addr == address.s_addr;
  freeifaddrs(list);
  return found;
}

// Aravis's fake camera starts even when it cannot bind its GVCP port (it
// then answers nobody), so the address is tried first: one camera per
// address, and only addresses an interface has.
bool CheckGvcpAddress(const std::string& address, std::string* error) {
  sockaddr_in a{};
  a.sin_family = AF_INET;
  a.sin_port = htons(kGvcpPort);
  if (inet_pton(AF_INET, address.c_str(), &a.sin_addr) != 1) {
    *error = "--address '" + address + "': not an IPv4 address";
    return false;
  }
  // A camera answers on one interface's address: not the wildcard, nor a
  // broadcast or multicast group. A loopback address can be added to lo.
  const uint32_t host = ntohl(a.sin_addr.s_addr);
  if (host == INADDR_ANY || host == INADDR_BROADCAST || (host >> 28) == 0xE) {
    *error = "--address " + address + ": a camera serves on one interface's address, not " +
             (host == INADDR_ANY ? "the wildcard" : host == INADDR_BROADCAST ? "the broadcast address" : "a multicast group") +
             " (ip -4 addr lists this host's addresses)";
    return false;
  }
  const bool loopback = (host >> 24) == 127;
  const std::string no_interface =
      "cannot serve on " + address + ": no network interface has that address (" +
      (loopback ? "on Linux: ip addr add " + address + "/8 dev lo, or a private namespace, see scripts/netns-run.sh"
                : "ip -4 addr lists this host's addresses") +
      ")";
  if (!InterfaceHasAddress(a.sin_addr)) {
    *error = no_interface;
    return false;
  }
  const int fd = socket(AF_INET, SOCK_DGRAM | SOCK_CLOEXEC, 0);
  if (fd < 0) return true;  // let the fake camera report it
  const int r = bind(fd, reinterpret_cast<sockaddr*>(&a), sizeof a);
  const int e = errno;
  close(fd);
  if (r == 0) return true;
  if (e == EADDRINUSE)
    *error = "cannot serve on " + address + ": its GVCP port 3956 is in use (another camera on this address?)";
  else if (e == EADDRNOTAVAIL)
    *error = no_interface;
  else
    *error = "cannot serve on " + address + ": GVCP port 3956: " + std::strerror(e);
  return false;
}

// One GVCP read of the version register from a fresh socket, and its ack.
// True when the fake camera's thread answered within timeout_ms.
bool GvcpRoundTrip(const std::string& address, int timeout_ms) {
  const int fd = socket(AF_INET, SOCK_DGRAM | SOCK_CLOEXEC, 0);
  if (fd < 0) return false;
  sockaddr_in to{};
  to.sin_family = AF_INET;
  to.sin_port = htons(kGvcpPort);
  inet_pton(AF_INET, address.c_str(), &to.sin_addr);
  // GVCP READREG_CMD: key 0x42, flags 0x01 (ack), command 0x0080, length 4, request id, address 0.
  const uint8_t cmd[12] = {0x42, 0x01, 0x00, 0x80, 0x00, 0x04, 0xca, 0x5e, 0, 0, 0, 0};
  bool answered = false;
  if (sendto(fd, cmd, sizeof cmd, 0, reinterpret_cast<sockaddr*>(&to), sizeof to) == sizeof cmd) {
    pollfd p{fd, POLLIN, 0};
    uint8_t ack[64];
    int r;
    do r = poll(&p, 1, timeout_ms);
    while (r < 0 && errno == EINTR);
    answered = r > 0 && recv(fd, ack, sizeof ack, 0) > 0;
  }
  close(fd);
  return answered;
}

}  // namespace

std::vector<std::string> ScenePatternNames() { return {"gradient", "checker", "flat"}; }

bool MakePatternScene(const std::string& name, int width, int height, io::SceneFrame* out, std::string* error) {
  if (width < 2 || height < 2 || width > 16384 || height > 16384) {
    *error = "--pattern: size must be 2..16384 (set [sensor] width and height)";
    return false;
  }
  io::SceneFrame s;
  s.width = width;
  s.height = height;
  s.source = "pattern:" + name;
  s.layout = "pattern";
  for (io::FloatPlane* p : {&s.r, &s.g, &s.b, &s.depth}) {
    p->width = width;
    p->height = height;
    p->data.assign(static_cast<size_t>(width) * height, 0.0f);
  }
  s.has_depth = true;
  // Radiance levels: mid grey 0.18 is a normal exposure for the demo camera;
  // the gradient's highlights (2.0) clip, so both ends of the range show.
  for (int y = 0; y < height; ++y)
    for (int x = 0; x < width; ++x) {
      const size_t i = static_cast<size_t>(y) * width + x;
      float r = 0.18f, g = 0.18f, b = 0.18f;
      if (name == "gradient") {
        const float fx = static_cast<float>(x) / (width - 1), fy = static_cast<float>(y) / (height - 1);
        r = 2.0f * fx;
        g = 2.0f * fx * (1.0f - 0.5f * fy);
        b = 2.0f * (1.0f - fx) * fy;
      } else if (name == "checker") {
        const bool on = ((x / 32) + (y / 32)) % 2 == 0;
        r = g = b = on ? 0.8f : 0.05f;
      } else if (name != "flat") {
        *error = "--pattern: unknown pattern '" + name + "' (gradient, checker, flat)";
        return false;
      }
      s.r.data[i] = r;
      s.g.data[i] = g;
      s.b.data[i] = b;
      // Depth (for the dof stage): a plane that recedes from 0.5 m at the
      // left edge to 8 m at the right.
      s.depth.data[i] = 0.5f + 7.5f * static_cast<float>(x) / static_cast<float>(width - 1);
    }
  *out = std::move(s);
  return true;
}

bool LoadDeviceScenes(const DeviceOptions& o, host::RunConfig* rc, host::Origins* origins,
                      std::vector<io::SceneFrame>* scenes, std::string* error) {
  if (!o.config_path.empty() && !host::LoadConfigFile(o.config_path, rc, origins, error)) return false;
  for (const std::string& s : o.overrides)
    if (!host::ApplyOverride(s, rc, origins, error)) return false;
  if (o.inputs.empty() == o.pattern.empty()) {
    *error = "give either --input EXR... or --pattern NAME";
    return false;
  }
  scenes->clear();
  if (!o.pattern.empty()) {
    io::SceneFrame s;
    const int w = rc->width > 0 ? rc->width : o.pattern_width, h = rc->height > 0 ? rc->height : o.pattern_height;
    if (!MakePatternScene(o.pattern, w, h, &s, error)) return false;
    scenes->push_back(std::move(s));
    return true;
  }
  std::vector<std::string> files;
  if (!io::ExpandInputs(o.inputs, &files, error)) return false;
  for (const std::string& f : files) {
    io::SceneFrame s;
    if (!io::LoadSceneExr(f, "", &s, error)) return false;
    for (const std::string& w : s.warnings) std::fprintf(stderr, "camsim-gige: warning: %s\n", w.c_str());
    if (!scenes->empty() && (s.width != scenes->front().width || s.height != scenes->front().height)) {
      *error = f + ": is " + std::to_string(s.width) + "x" + std::to_string(s.height) + " but the first input is " +
               std::to_string(scenes->front().width) + "x" + std::to_string(scenes->front().height);
      return false;
    }
    scenes->push_back(std::move(s));
  }
  return true;
}

// Mirrors the window [x, x + w) x [y, y + h) of a frame of `stride`
// elements of `n` bytes in place: ReverseX mirrors its columns, ReverseY its
// rows. Done to the rendered frames (raw codes, RGB8) before a window is
// converted, so that every format, packed ones too, carries the mirrored
// readout; done again after, which restores them (a mirror is its own inverse).
void MirrorWindow(uint8_t* frame, size_t stride, size_t n, int x, int y, int w, int h, bool reverse_x, bool reverse_y) {
  const size_t row = static_cast<size_t>(w) * n;
  uint8_t* origin = frame + (static_cast<size_t>(y) * stride + static_cast<size_t>(x)) * n;
  if (reverse_x)
    for (int r = 0; r < h; ++r) {
      uint8_t* p = origin + static_cast<size_t>(r) * stride * n;
      for (size_t a = 0, b = static_cast<size_t>(w) - 1; w > 0 && a < b; ++a, --b)
        std::swap_ranges(p + a * n, p + a * n + n, p + b * n);
    }
  if (reverse_y)
    for (size_t a = 0, b = static_cast<size_t>(h) - 1; h > 0 && a < b; ++a, --b)
      std::swap_ranges(origin + a * stride * n, origin + a * stride * n + row, origin + b * stride * n);
}

// Binning and decimation of one readout (BinningHorizontal, ...).
struct Reduction {
  int bin_x = 1, bin_y = 1, dec_x = 1, dec_y = 1;
  bool average_x = false, average_y = false;  // BinningHorizontalMode / BinningVerticalMode Average
};
// Reduces a frame of `channels` samples per pixel (stride `stride` pixels)
// to out_w x out_h pixels, per `cell` x `cell` CFA cell (1: per pixel):
// binning first (cell I sums the same-colour samples of cells I x bin ..
// I x bin + bin - 1 of the frame), then decimation (every dec-th binned
// cell), so output cell I comes from frame cells I x dec x bin + k, k < bin,
// on each axis. The sum of the bin_x x bin_y samples is divided by bin_x for
// Average horizontally and by bin_y for Average vertically, rounded half up
// ((s + d / 2) / d), then clamped at `full`.
template <class T>
void ReduceReadout(const T* in, int stride, int channels, int cell, const Reduction& r, int full, int out_w, int out_h,
                   T* out) {
  const auto first = [cell](int i, int bin, int dec) { return (i / cell) * dec * bin * cell + i % cell; };
  const uint32_t divisor = static_cast<uint32_t>((r.average_x ? r.bin_x : 1) * (r.average_y ? r.bin_y : 1));
  for (int j = 0; j < out_h; ++j) {
    const int row = first(j, r.bin_y, r.dec_y);
    for (int i = 0; i < out_w; ++i) {
      const int col = first(i, r.bin_x, r.dec_x);
      for (int c = 0; c < channels; ++c) {
        uint32_t sum = 0;
        for (int l = 0; l < r.bin_y; ++l)
          for (int k = 0; k < r.bin_x; ++k)
            sum += in[(static_cast<size_t>(row + l * cell) * stride + col + k * cell) * channels + c];
        const uint32_t v = std::min<uint32_t>((sum + divisor / 2) / divisor, static_cast<uint32_t>(full));
        out[(static_cast<size_t>(j) * out_w + i) * channels + c] = static_cast<T>(v);
      }
    }
  }
}

void ConvertWindow(uint32_t format, Cfa cfa, int adc_bits, const uint16_t* raw, const uint8_t* rgb, int sensor_width,
                   int x, int y, int w, int h, uint8_t* out) {
  if (format == kRGB8) {
    for (int r = 0; r < h; ++r)
      std::memcpy(out + static_cast<size_t>(r) * w * 3, rgb + (static_cast<size_t>(y + r) * sensor_width + x) * 3,
                  static_cast<size_t>(w) * 3);
    return;
  }
  if (format == kBGR8) {  // RGB8 with each pixel's R and B swapped
    for (int r = 0; r < h; ++r) {
      const uint8_t* src = rgb + (static_cast<size_t>(y + r) * sensor_width + x) * 3;
      uint8_t* dst = out + static_cast<size_t>(r) * w * 3;
      for (int i = 0; i < w; ++i) {
        dst[3 * i] = src[3 * i + 2];
        dst[3 * i + 1] = src[3 * i + 1];
        dst[3 * i + 2] = src[3 * i];
      }
    }
    return;
  }
  if (Is422(format)) {
    // Full-range BT.601 from Kr = 0.299, Kb = 0.114 (Kg = 1 - Kr - Kb =
    // 0.587): Y = Kr R + Kg G + Kb B, Cb = 128 + (B - Y) / (2 (1 - Kb)),
    // Cr = 128 + (R - Y) / (2 (1 - Kr)). In thousandths these are exact
    // integer ratios: Y = (299 R + 587 G + 114 B) / 1000, Cb = 128 +
    // (886 B - 299 R - 587 G) / 1772, Cr = 128 + (701 R - 587 G - 114 B) / 1402,
    // each rounded half up (numerators made non-negative by the offset 128)
    // and clamped at 255 (Cb, Cr reach 255.5). Cb and Cr are co-sited: those
    // of each pair's even pixel (the window's, after ReverseX).
    const auto y_of = [](int r, int g, int b) { return (299 * r + 587 * g + 114 * b + 500) / 1000; };
    const auto cb_of = [](int r, int g, int b) {
      return std::min((886 * b - 299 * r - 587 * g + 886 + 128 * 1772) / 1772, 255);
    };
    const auto cr_of = [](int r, int g, int b) {
      return std::min((701 * r - 587 * g - 114 * b + 701 + 128 * 1402) / 1402, 255);
    };
    const bool uyvy = format == kYUV422_8_UYVY;  // else Y Cb Y Cr (YCbCr422_8 and YUV422_8 alike)
    for (int r = 0; r < h; ++r) {
      const uint8_t* src = rgb + (static_cast<size_t>(y + r) * sensor_width + x) * 3;
      uint8_t* dst = out + static_cast<size_t>(r) * w * 2;
      for (int i = 0; i + 1 < w; i += 2, src += 6, dst += 4) {
        const uint8_t y0 = static_cast<uint8_t>(y_of(src[0], src[1], src[2]));
        const uint8_t y1 = static_cast<uint8_t>(y_of(src[3], src[4], src[5]));
        const uint8_t cb = static_cast<uint8_t>(cb_of(src[0], src[1], src[2]));
        const uint8_t cr = static_cast<uint8_t>(cr_of(src[0], src[1], src[2]));
        if (uyvy) {
          dst[0] = cb, dst[1] = y0, dst[2] = cr, dst[3] = y1;
        } else {
          dst[0] = y0, dst[1] = cb, dst[2] = y1, dst[3] = cr;
        }
      }
    }
    return;
  }
  if (FromIsp(format, cfa)) {
    // Mono8 on a colour sensor: BT.601 luma of RGB8, (77 R + 150 G + 29 B + 128) >> 8 (weights sum to 256).
    for (int r = 0; r < h; ++r) {
      const uint8_t* src = rgb + (static_cast<size_t>(y + r) * sensor_width + x) * 3;
      uint8_t* dst = out + static_cast<size_t>(r) * w;
      for (int i = 0; i < w; ++i)
        dst[i] = static_cast<uint8_t>((77 * src[3 * i] + 150 * src[3 * i + 1] + 29 * src[3 * i + 2] + 128) >> 8);
    }
    return;
  }
  const Packing packing = PackingOf(format);
  if (packing != Packing::kNone) {
    // The window's DN at the format's depth (as the unpacked formats: shifted
    // up for a smaller ADC), row after row, as one stream (rows need not start on a byte).
    const int bits = PixelBits(format), shift = bits - adc_bits;
    size_t n = 0;
    uint32_t acc = 0;  // PFNC: bits not yet written, LSB first
    int held = 0;
    for (int r = 0; r < h; ++r) {
      const uint16_t* src = raw + static_cast<size_t>(y + r) * sensor_width + x;
      for (int i = 0; i < w; ++i) {
        const uint32_t v = static_cast<uint32_t>(src[i]) << shift;
        if (packing == Packing::kPfnc) {
          acc |= v << held;
          for (held += bits; held >= 8; held -= 8, acc >>= 8) out[n++] = static_cast<uint8_t>(acc);
        } else if (held == 0) {  // GigE Vision 12Packed, the first of a pair
          out[n++] = static_cast<uint8_t>(v >> 4);
          out[n++] = static_cast<uint8_t>(v & 0xf);
          held = 1;
        } else {  // the second: its low nibble in the shared byte's bits 4..7
          out[n - 1] = static_cast<uint8_t>(out[n - 1] | (v & 0xf) << 4);
          out[n++] = static_cast<uint8_t>(v >> 4);
          held = 0;
        }
      }
    }
    if (packing == Packing::kPfnc && held > 0) out[n] = static_cast<uint8_t>(acc);  // a last partial byte
    return;
  }
  const int bits = SampleBits(format);
  for (int r = 0; r < h; ++r) {
    const uint16_t* src = raw + static_cast<size_t>(y + r) * sensor_width + x;
    if (bits == 8) {
      // The top 8 ADC bits (truncated, as a sensor's 8-bit mode drops LSBs).
      const int shift = adc_bits - 8;
      uint8_t* dst = out + static_cast<size_t>(r) * w;
      for (int i = 0; i < w; ++i) dst[i] = static_cast<uint8_t>(src[i] >> shift);
    } else {
      // 10- and 12-bit: the DN at that depth; 16-bit: MSB-aligned. Little-endian words.
      const int shift = bits - adc_bits;
      uint8_t* dst = out + static_cast<size_t>(r) * w * 2;
      for (int i = 0; i < w; ++i) {
        const uint16_t v = static_cast<uint16_t>(src[i] << shift);
        dst[2 * i] = static_cast<uint8_t>(v & 0xff);
        dst[2 * i + 1] = static_cast<uint8_t>(v >> 8);
      }
    }
  }
}

std::unique_ptr<GigeDevice> GigeDevice::Start(const DeviceOptions& o, std::string* error) {
  std::unique_ptr<GigeDevice> d(new GigeDevice);
  if (!d->Init(o, error)) return nullptr;
  return d;
}

uint32_t GigeDevice::Read(uint32_t address) const {
  guint32 v = 0;
  arv_fake_camera_read_register(fake_, address, &v);
  return v;
}
void GigeDevice::Write(uint32_t address, uint32_t value) {
  DeviceWrites own;
  arv_fake_camera_write_register(fake_, address, value);
}
double GigeDevice::ReadDouble(uint32_t address) const {
  uint8_t b[8];
  arv_fake_camera_read_memory(fake_, address, 8, b);
  uint64_t v = 0;
  for (int i = 0; i < 8; ++i) v = (v << 8) | b[i];
  return BitsDouble(v);
}
void GigeDevice::WriteDouble(uint32_t address, double value) {
  const uint64_t v = DoubleBits(value);
  uint8_t b[8];
  for (int i = 0; i < 8; ++i) b[i] = static_cast<uint8_t>(v >> (56 - 8 * i));
  DeviceWrites own;
  arv_fake_camera_write_memory(fake_, address, 8, b);
}
uint64_t GigeDevice::ReadFeature(const Feature& f) const {
  return f.kind == Kind::kFloat ? DoubleBits(ReadDouble(f.address)) : Read(f.address);
}
void GigeDevice::WriteFeature(const Feature& f, uint64_t v) {
  if (f.kind == Kind::kFloat) WriteDouble(f.address, BitsDouble(v));
  else Write(f.address, static_cast<uint32_t>(v));
}
double GigeDevice::AppliedDouble(uint32_t address) const { return BitsDouble(applied_.at(address)); }
void GigeDevice::SetApplied(uint32_t address, uint64_t value) {
  applied_[address] = value;
  for (const Feature& f : registers_)
    if (f.address == address && f.alias_of.empty() && f.kind != Kind::kString && f.kind != Kind::kSwissKnife) {
      WriteFeature(f, value);
      return;
    }
}

void GigeDevice::WriteReadoutMax() {
  const auto at = [this](uint32_t r) { return Read(r); };
  Write(reg::kWidthMax, static_cast<uint32_t>(ReadoutExtent(sensor_, 0, at)));
  Write(reg::kHeightMax, static_cast<uint32_t>(ReadoutExtent(sensor_, 1, at)));
}

int GigeDevice::Readout() const { return static_cast<int>((Read(reg::kReverseX) & 1) | (Read(reg::kReverseY) & 1) << 1); }

bool GigeDevice::Valid(const Feature& f, uint64_t v, int readout) const {
  switch (f.kind) {
    case Kind::kInteger: {
      // A masked register (SCPS0): the other bits are the client's flags
      // (bit 31 fires a test packet during packet-size negotiation).
      const double x = static_cast<double>(MaskedValue(f, v));
      return x >= f.min && x <= f.max && std::fmod(x - f.min, f.inc) == 0.0;
    }
    case Kind::kFloat: {
      const double x = BitsDouble(v);
      return std::isfinite(x) && x >= f.min && x <= f.max;
    }
    case Kind::kEnum:
      for (const EnumEntry& e : f.entries)
        if (static_cast<uint64_t>(e.value) == v && (e.readout < 0 || e.readout == (readout < 0 ? Readout() : readout)))
          return true;
      return false;
    case Kind::kBoolean: return v <= 1;
    default: return false;
  }
}

bool GigeDevice::Init(const DeviceOptions& o, std::string* error) {
  clock_offset_ns_ = RealTimeNs() - SteadyNs(std::chrono::steady_clock::now());
  if (!LoadDeviceScenes(o, &base_config_, &origins_, &scenes_, error)) return false;
  // PlanFor's settings come from the registers, whatever the file said.
  register_origins_ = origins_;
  register_origins_["exposure.exposure_time_us"] = "ExposureTime";
  register_origins_["exposure.f_number"] = "SimFNumber";
  register_origins_["dof.focus_distance_m"] = "SimFocusDistance";
  register_origins_["sensor.gain_db"] = "Gain";
  register_origins_["sensor.black_level_dn"] = "BlackLevel";
  register_origins_["pipeline.seed"] = "SimSeed";
  register_origins_["pipeline.stages"] = "SimStageEnable";
  register_origins_["white_balance.gain"] = "BalanceRatio";
  register_origins_["gamma.gamma"] = "Gamma";
  register_origins_["gamma.curve"] = "GammaEnable";
  address_ = o.address;
  prime_first_frame_ = o.prime_first_frame;
  if (o.link_mbps < 0 || o.link_mbps > kMaxLinkMbps) {
    *error = "--link-mbps: must be 0 (no limit) .. " + std::to_string(kMaxLinkMbps) + ", not " +
             std::to_string(o.link_mbps);
    return false;
  }
  link_bits_per_s_ = static_cast<uint64_t>(o.link_mbps) * 1'000'000;
  probe_heartbeat_ = o.probe_heartbeat;
  renderer_ = std::make_unique<host::FrameRenderer>(o.threads, o.strip_rows);
  // The configured gain on GainRaw's 0.1 dB steps, as every later Gain (QuantiseGain).
  double& gain_db = base_config_.core.sensor.gain_db;
  if (std::isfinite(gain_db) && gain_db >= 0 && gain_db <= kMaxGainDb) gain_db = QuantiseGain(gain_db);
  host::RunConfig finished;
  if (!renderer_->Configure(base_config_, origins_, scenes_[0].width, scenes_[0].height, &finished, error))
    return false;
  if (finished.environment_data)
    for (const std::string& w : finished.environment_data->warnings)
      std::fprintf(stderr, "camsim-gige: warning: flare.environment_map %s\n", w.c_str());
  const Pipeline& p = renderer_->pipeline();
  const PlanEntry* sensor = RunningSensor(p.plan());
  if (sensor == nullptr || sensor->out.channels != 1) {
    *error = "[pipeline] stages: " +
             std::string(sensor == nullptr ? "camsim-gige needs the sensor stage" : kSensorNeedsCfa);
    return false;
  }
  for (int i = 0; i < base_config_.core.order_count; ++i) configured_stages_.push_back(base_config_.core.order[i]);

  sensor_.width = p.width();
  sensor_.height = p.height();
  sensor_.cfa = finished.core.geometry.cfa;
  sensor_.adc_bits = finished.core.geometry.adc_bits;
  // BlackLevel range: up to a quarter of full scale, or the configured value if higher.
  sensor_.max_black_level_dn =
      std::max(std::floor(((1 << sensor_.adc_bits) - 1) / 4.0), finished.core.sensor.black_level_dn);
  sensor_.scene_count = static_cast<int>(scenes_.size());
  const LineFormat out = p.plan().output;
  sensor_.has_isp_rgb = out.channels == 3 && (out.domain == Domain::kEncoded || out.domain == Domain::kLinear);
  if (finished.core.dof.method != DofMethod::kOff)  // the focus must exceed the focal length (core/lens/dof.cc)
    sensor_.min_focus_distance_m =
        std::max(reg::kMinFocusDistanceM, (std::floor(finished.core.dof.focal_length_mm) + 1) / 1000.0);
  for (StageId id : configured_stages_) sensor_.stage_names.push_back(StageName(id));
  sensor_.has_white_balance =
      sensor_.has_isp_rgb && sensor_.cfa != Cfa::kMono &&
      std::find(configured_stages_.begin(), configured_stages_.end(), StageId::kWhiteBalance) != configured_stages_.end();
  sensor_.has_gamma = sensor_.has_isp_rgb && std::find(configured_stages_.begin(), configured_stages_.end(),
                                                       StageId::kGamma) != configured_stages_.end();
  if (sensor_.width % 2 || sensor_.height % 2) {
    if (sensor_.cfa != Cfa::kMono) {
      *error = "sensor size " + std::to_string(sensor_.width) + "x" + std::to_string(sensor_.height) +
               ": a Bayer camera needs an even width and height";
      return false;
    }
  }
  // Aravis's fake camera counts a frame's bits in 32 bits and its packets in
  // 16: a larger frame would wrap (and overrun the buffer it sizes).
  const uint64_t max_payload = MaxPayloadBytes(sensor_);
  if (max_payload * 8 > kMaxFakeCameraPayloadBits || MinPacketSize(sensor_) > kMaxPacketSize) {
    *error = "sensor size " + std::to_string(sensor_.width) + "x" + std::to_string(sensor_.height) + ": its largest frame (" +
             std::to_string(max_payload) + " bytes with chunks) is beyond what Aravis's fake camera sends (" +
             std::to_string(kMaxFakeCameraPayloadBits / 8) + " bytes, and 65534 packets of at most 9000 bytes)";
    return false;
  }
  // Lines: a requested line that cannot be opened is an error; none is fine.
  trigger_ = o.trigger;
  strobe_ = o.strobe;
  if (!o.trigger_line.empty()) {
    own_trigger_ = hal::OpenInputLine(o.trigger_line, "camsim-gige trigger", error);
    if (!own_trigger_) return false;
    trigger_ = own_trigger_.get();
  }
  if (!o.strobe_line.empty()) {
    own_strobe_ = hal::OpenOutputLine(o.strobe_line, "camsim-gige strobe", error);
    if (!own_strobe_) return false;
    strobe_ = own_strobe_.get();
  }
  sensor_.has_trigger_line = trigger_ != nullptr;  // without one, TriggerSource Line0 is refused

  table_ = RegisterTable(sensor_);
  registers_ = FeatureRegisters(table_);
  if (!RegisterRules(registers_, &rules_, error)) {
    *error = "register table: " + *error;
    return false;
  }
  raw_.assign(static_cast<size_t>(sensor_.width) * sensor_.height, 0);
  rgb_.assign(static_cast<size_t>(sensor_.width) * sensor_.height * 3, 0);

  DeviceStrings strings;
  strings.serial = o.serial;
  if (o.serial.empty() || o.serial.size() > 15) {
    *error = "--serial: 1..15 characters";
    return false;
  }
  const std::string xml = GenerateXml(table_, strings);
  xml_path_ = o.xml_path;
  if (xml_path_.empty()) {
    const char* tmp = std::getenv("TMPDIR");
    xml_path_ = std::string(tmp && *tmp ? tmp : "/tmp") + "/camsim-gige-" + o.serial + "-" +
                std::to_string(getpid()) + ".xml";
    own_xml_ = true;
  }
  if (!io::WriteTextFile(xml_path_, xml, error)) return false;

  // Tried on a camera that serves nothing, before one that does.
  ArvFakeCamera* trial = arv_fake_camera_new_full(o.serial.c_str(), xml_path_.c_str());
  const bool hooked = trial != nullptr && FakeCameraHooksInForce(trial);
  if (trial != nullptr) g_object_unref(trial);
  if (!hooked) {
    *error = "libaravis's accesses to the fake camera's memory, its GLib socket calls or its trigger "
             "acknowledgement do not go through "
             "camsim's hooks (genicam/fake_camera_hooks.cc: camsim_genicam linked into a shared library, or a "
             "libaravis linked with -Bsymbolic): without them one GVCP packet outside the memory map would crash "
             "the camera, refused writes would not be refused as they arrive, and clients would see them "
             "acknowledged as successes";
    return false;
  }
  // The camera serves from its creation: client writes are refused until its
  // filter is set (and this thread's writes are the device's).
  const UnfilteredWritesRefused until_filtered;
  if (o.serve) {
    if (!CheckGvcpAddress(o.address, error)) return false;
    hooks_refused_before_ = WritesRefusedAt(o.address.c_str());  // an earlier camera's, at this address
    gv_ = arv_gv_fake_camera_new_full(o.address.c_str(), o.serial.c_str(), xml_path_.c_str());
    if (!gv_ || !arv_gv_fake_camera_is_running(gv_)) {
      *error = "cannot serve on " + o.address +
               ": no network interface has that address, or another camera already uses its GVCP port 3956";
      return false;
    }
    fake_ = arv_gv_fake_camera_get_fake_camera(gv_);
  } else {
    fake_ = arv_fake_camera_new_full(o.serial.c_str(), xml_path_.c_str());
    if (!fake_) {
      *error = "cannot create the register memory";
      return false;
    }
  }
  arv_fake_camera_set_trigger_frequency(fake_, kTriggerPollHz);
  SetWriteFilter(fake_, &GigeDevice::FilterClientWrite, this);

  // Bootstrap strings, then every register's initial value.
  auto put_string = [&](uint32_t address, const std::string& s, size_t size) {
    std::vector<char> b(size, 0);
    std::memcpy(b.data(), s.data(), std::min(s.size(), size - 1));
    DeviceWrites own;
    arv_fake_camera_write_memory(fake_, address, static_cast<guint32>(size), b.data());
  };
  put_string(reg::kVendorName, strings.vendor, 32);
  put_string(reg::kModelName, strings.model, 32);
  put_string(reg::kDeviceVersion, strings.version, 32);
  put_string(reg::kManufacturerInfo, "camsim camera emulator", 48);
  put_string(reg::kUserId, "", 16);
  // What the device is and can do. WRITEMEM is the only way to write an
  // 8-byte Float register; PACKETRESEND is the hooks' (fake_camera_hooks.h,
  // kResendFrames); the fake camera has no concatenation or events, so they
  // are not claimed.
  Write(reg::kDeviceMode, reg::kDeviceModeBigEndianUtf8);
  Write(reg::kGvcpCapability, reg::kCapabilityUserName | reg::kCapabilitySerialNumber | reg::kCapabilityWriteMem |
                                  reg::kCapabilityPacketResend);
  Write(reg::kVersion, reg::kGigeVisionVersion);
  const uint64_t mac = MacOfSerial(o.serial);
  Write(reg::kMacHigh, static_cast<uint32_t>(mac >> 32));
  Write(reg::kMacLow, static_cast<uint32_t>(mac));

  using namespace reg;
  const auto& c = finished.core;
  const uint64_t initial[][2] = {
      {kSensorWidth, static_cast<uint64_t>(sensor_.width)},
      {kSensorHeight, static_cast<uint64_t>(sensor_.height)},
      {kWidthMax, static_cast<uint64_t>(sensor_.width)},
      {kHeightMax, static_cast<uint64_t>(sensor_.height)},
      {kWidth, static_cast<uint64_t>(sensor_.width)},
      {kHeight, static_cast<uint64_t>(sensor_.height)},
      {kOffsetX, 0},
      {kOffsetY, 0},
      {kPixelFormat, static_cast<uint64_t>(FindFeature(table_, "PixelFormat")->entries[0].value)},
      {kAcquisitionMode, kContinuous},
      {kAcquisitionFrameCount, 1},
      {kAcquisitionFrameRate, DoubleBits(25.0)},  // Aravis's fake camera default
      {kAcquisitionFrameRateEnable, 1},
      {kExposureTime, DoubleBits(c.exposure.exposure_time_us)},  // the core checked it: [1, 1e8]
      {kExposureAuto, kAutoOff},
      {kExposureMode, kExposureTimed},
      {kTriggerSelector, 0},
      {kTriggerMode, 0},
      {kTriggerSource, kSourceSoftware},
      {kTriggerActivation, 0},
      {kTriggerDelay, DoubleBits(0.0)},
      {kGain, DoubleBits(c.sensor.gain_db)},
      {kGainRaw, GainRawOf(c.sensor.gain_db)},
      {kGainAuto, kAutoOff},
      // The Auto features' range: `camsim run`'s (core/control/auto_exposure.h).
      {kAutoExposureTimeLowerLimit, DoubleBits(AutoExposureConfig().exposure_time_min_us)},
      {kAutoExposureTimeUpperLimit, DoubleBits(AutoExposureConfig().exposure_time_max_us)},
      {kAutoGainLowerLimit, DoubleBits(AutoExposureConfig().gain_min_db)},
      {kAutoGainUpperLimit, DoubleBits(AutoExposureConfig().gain_max_db)},
      {kBlackLevel, DoubleBits(c.sensor.black_level_dn)},
      {kLineSelector, 0},
      {SelectedAddress(kLineSource, 0), kLineSourceOff},
      {SelectedAddress(kLineSource, 1), kLineSourceOff},
      {SelectedAddress(kLineInverter, 0), 0},
      {SelectedAddress(kLineInverter, 1), 0},
      {kLineDebouncerTime, DoubleBits(0.0)},
      // The fake camera's default (fits a 1500-byte MTU), or what the largest frame needs.
      {kPacketSize, std::max<uint32_t>(1400, MinPacketSize(sensor_))},
      {kPacketDelay, 0},
      {kTLParamsLocked, 0},
      {kHeartbeatTimeout, 3000},  // the fake camera's default (GigE Vision's too)
      {kSimSceneCount, static_cast<uint64_t>(sensor_.scene_count)},
      {kSimSceneFrame, 0},
      {kSimFrameIndex, 0},
      {kSimFNumber, DoubleBits(c.exposure.f_number)},
      // (Unchecked while dof.method is off: kept in the XML's range.)
      {kSimFocusDistance,
       DoubleBits(std::isfinite(c.dof.focus_distance_m)
                      ? std::clamp(c.dof.focus_distance_m, sensor_.min_focus_distance_m, kMaxFocusDistanceM)
                      : kMaxFocusDistanceM)},
      {kSimSeed, c.seed & 0x7fffffff},
      {kSimStageSelector, 0},
      {kSimAutoTarget, DoubleBits(0.4)},  // 40% of full scale: mid-grey with highlight headroom
      {kChunkModeActive, 0},
      {kChunkSelector, 0},
      {kReverseX, 0},
      {kReverseY, 0},
      {kBinningHorizontal, 1},
      {kBinningVertical, 1},
      {kBinningHorizontalMode, kBinningSum},
      {kBinningVerticalMode, kBinningSum},
      {kDecimationHorizontal, 1},
      {kDecimationVertical, 1},
      {kTestPatternGeneratorSelector, 0},
      {kTestPattern, kTestPatternOff},
      {kDeviceTemperatureSelector, 0},
      {kDeviceTemperature, DoubleBits(c.sensor.temperature_c)},  // the core checked it: [-100, 150]
      {kUserSetSelector, kUserSetDefaultSet},
      {kUserSetDefault, kUserSetDefaultSet},
  };
  std::lock_guard<std::mutex> lock(mutex_);
  for (const auto& iv : initial) SetApplied(static_cast<uint32_t>(iv[0]), iv[1]);
  for (size_t i = 0; i < configured_stages_.size(); ++i) SetApplied(SelectedAddress(kSimStageEnable, i), 1);
  // Every chunk on: ChunkModeActive alone sends them all.
  for (int i = 0; i < kChunkCount; ++i) SetApplied(SelectedAddress(kChunkEnable, static_cast<size_t>(i)), 1);
  if (sensor_.has_white_balance) {  // the configured gains (the core checked them: 0 .. 16)
    SetApplied(kBalanceRatioSelector, kBalanceRed);
    SetApplied(kBalanceWhiteAuto, kAutoOff);
    for (int i = 0; i < kBalanceCount; ++i)
      SetApplied(SelectedAddress(kBalanceRatio, static_cast<size_t>(i), 8), DoubleBits(c.white_balance.gain[i]));
  }
  if (sensor_.has_gamma) {  // off: the configured curve; Gamma from the configured power curve's gamma
    SetApplied(kGammaEnable, 0);
    const double g = c.gamma.gamma >= kMinGamma && c.gamma.gamma <= kMaxGamma ? c.gamma.gamma : GammaConfig().gamma;
    SetApplied(kGamma, DoubleBits(std::clamp(1.0 / g, kMinGamma, kMaxGamma)));
  }
  seed_register_at_start_ = applied_[kSimSeed];
  Write(SelectedAddress(kLineMode, 0), 0);  // Line0: Input (the trigger)
  Write(SelectedAddress(kLineMode, 1), 1);  // Line1: Output (the strobe)
  Write(kAcquisition, 0);
  Write(kTriggerSoftware, 0);
  WriteDerived();
  ready_ = true;  // the values in use are set: the filter may plan on them
  // User sets: Default is this start-up configuration; the file's sets and
  // UserSetDefault's set load through the filter, as a client's writes.
  user_sets_[0] = {true, UserSetNow()};
  for (int i = 1; i < kUserSetCount; ++i) user_sets_[i] = {false, user_sets_[0].values};
  user_set_file_ = o.user_set_file;
  start_user_set_ = "the Default user set (no --user-set-file)";
  if (!user_set_file_.empty()) {
    // UserSetSave writes it later: a directory it cannot write in fails now.
    const size_t slash = user_set_file_.find_last_of('/');
    const std::string dir = slash == std::string::npos ? "." : slash == 0 ? "/" : user_set_file_.substr(0, slash);
    if (access(dir.c_str(), W_OK | X_OK) != 0) {
      *error = "--user-set-file " + user_set_file_ + ": cannot write in its directory " + dir + ": " +
               std::strerror(errno);
      return false;
    }
  }
  if (!user_set_file_.empty()) {
    const ClientWritesHeld hold(fake_);
    if (!ReadUserSetFile(error)) return false;
  }
  arv_fake_camera_set_fill_pattern(fake_, &GigeDevice::FillThunk, this);
  if (!o.serve) return true;
  sync_thread_ = std::thread([this] { SyncLoop(); });
  if (trigger_) trigger_thread_ = std::thread([this] { TriggerLoop(); });
  return true;
}

GigeDevice::~GigeDevice() {
  if (fake_) SetWriteFilter(fake_, nullptr, nullptr);
  stop_ = true;
  if (sync_thread_.joinable()) sync_thread_.join();
  if (trigger_thread_.joinable()) trigger_thread_.join();
  if (probe_fd_ >= 0) close(probe_fd_);
  if (gv_) g_object_unref(gv_);  // stops the fake camera's thread
  else if (fake_) g_object_unref(fake_);
  if (own_xml_) unlink(xml_path_.c_str());
  FlushRefusalLog(true);
}

uint64_t GigeDevice::DeviceTime(std::chrono::steady_clock::time_point t) const {
  return static_cast<uint64_t>(SteadyNs(t) + clock_offset_ns_ - timestamp_origin_ns_.load());
}

// Ranges, the read-only XML and the client-write rules: fake_camera_hooks.cc.
uint64_t GigeDevice::writes_refused() const {
  const uint64_t hooks = gv_ != nullptr ? WritesRefusedAt(address_.c_str()) - hooks_refused_before_ : 0;
  return writes_refused_.load() + hooks;
}

bool GigeDevice::WriteMemory(uint32_t address, const void* data, uint32_t size) {
  std::lock_guard<std::mutex> lock(mutex_);
  return arv_fake_camera_write_memory(fake_, address, size, data);
}

bool GigeDevice::ReadMemory(uint32_t address, void* data, uint32_t size) const {
  std::lock_guard<std::mutex> lock(mutex_);
  return arv_fake_camera_read_memory(fake_, address, size, data);
}

void GigeDevice::SyncNow() {
  std::lock_guard<std::mutex> lock(mutex_);
  Sync();
}

bool GigeDevice::RenderNow(std::vector<uint8_t>* frame) {
  const size_t payload = arv_fake_camera_get_payload(fake_);
  ArvBuffer* b = arv_buffer_new(payload, nullptr);
  arv_fake_camera_fill_buffer(fake_, b, nullptr);  // calls Fill
  const bool ok = arv_buffer_get_status(b) == ARV_BUFFER_STATUS_SUCCESS;
  if (ok) {
    const uint8_t* data = static_cast<const uint8_t*>(arv_buffer_get_data(b, nullptr));
    frame->assign(data, data + payload);
  }
  g_object_unref(b);
  return ok;
}

std::string GigeDevice::CheckInvariants() const {
  std::lock_guard<std::mutex> lock(mutex_);
  for (const Feature& f : registers_) {
    if (!Checked(f)) continue;
    const uint64_t in_use = applied_.at(f.address);
    const int readout = static_cast<int>(applied_.at(reg::kReverseX) | applied_.at(reg::kReverseY) << 1);
    if (!Valid(f, in_use, readout)) return f.name + ": the value in use is invalid";
    if (ReadFeature(f) != in_use) return f.name + ": the register differs from the value in use";
  }
  using namespace reg;
  const auto applied = [this](uint32_t r) { return applied_.at(r); };
  const uint64_t max_w = static_cast<uint64_t>(ReadoutExtent(sensor_, 0, applied)),
                 max_h = static_cast<uint64_t>(ReadoutExtent(sensor_, 1, applied));
  if (applied_.at(kWidth) + applied_.at(kOffsetX) > max_w || applied_.at(kHeight) + applied_.at(kOffsetY) > max_h)
    return "the window is off the readout (WidthMax x HeightMax)";
  if (Read(kWidthMax) != max_w || Read(kHeightMax) != max_h) return "WidthMax or HeightMax is not the readout's";
  if (applied_.at(kGain) != DoubleBits(GainDbOf(applied_.at(kGainRaw))))
    return "Gain is not GainRaw's step";
  for (const AutoLimits& l : kAutoLimits)
    if (AppliedDouble(l.lower) > AppliedDouble(l.upper))
      return std::string(l.name) + "LowerLimit is above " + l.name + "UpperLimit";
  return "";
}

std::string GigeDevice::line_error() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return line_error_;
}

void GigeDevice::WriteDerived() {
  using namespace reg;
  // The fake camera's own registers follow camsim's. It stays in its
  // software-trigger mode: camsim asks it for every frame, the triggers' and
  // the free run's (PaceFreeRun), so that it never waits for a frame's slot
  // inside Fill, on the thread that also answers control packets.
  Write(kFakeFramePeriodUs, 1);
  Write(kFakeTriggerMode, 1);
  Write(kFakeTriggerSource, 1);  // the fake camera's "Software"
  Write(kFakeExposureUs, static_cast<uint32_t>(AppliedDouble(kExposureTime)));
  WriteLineStatus();
  Write(kSimSceneFrame, static_cast<uint32_t>(Applied(kSimFrameIndex) % static_cast<uint32_t>(sensor_.scene_count)));
  WriteResultingFrameRate();
}

// The free-run period: FramePeriod with AcquisitionFrameRate on (the device
// waits for it), and at least the last frame's rendering and conversion and
// its paced sending (without it, frames come as fast as that; before the
// first frame, the XML's maximum). An upper bound: the thread's other work is left out.
void GigeDevice::WriteResultingFrameRate() {
  using namespace reg;
  double period_s = last_render_s_ + last_send_s_;
  if (Applied(kAcquisitionFrameRateEnable) != 0)
    period_s = std::max(period_s, std::chrono::duration<double>(FramePeriod(AppliedDouble(kAcquisitionFrameRate),
                                                                            AppliedDouble(kExposureTime)))
                                      .count());
  WriteDouble(kAcquisitionResultingFrameRate, period_s > 1e-6 ? 1.0 / period_s : 1e6);
}

uint64_t GigeDevice::PacketDelayNs() const {
  using namespace reg;
  const uint64_t hz = uint64_t{Read(kTickFrequencyHigh)} << 32 | Read(kTickFrequencyLow);
  return hz == 0 ? 0 : static_cast<uint64_t>(static_cast<double>(Read(kPacketDelay)) * 1e9 / static_cast<double>(hz));
}

void GigeDevice::DriveStrobe(bool active) {
  std::string error;
  const bool high = active != (Applied(reg::SelectedAddress(reg::kLineInverter, 1)) != 0);
  if (strobe_->Set(high, &error)) {
    strobe_level_ = high;
    WriteLineStatus();
  } else {
    line_error_ = error;
  }
}

void GigeDevice::WriteLineStatus() {
  using namespace reg;
  Write(SelectedAddress(kLineStatus, 0), trigger_level_ ? 1 : 0);
  Write(SelectedAddress(kLineStatus, 1), strobe_level_ ? 1 : 0);
}

// PlanFor reads only these registers (PlanKey below lists them).
bool GigeDevice::PlanFor(const Registers& r, host::PlannedPipeline* planned, std::string* error) const {
  using namespace reg;
  ++pipelines_planned_;
  host::RunConfig rc = base_config_;
  rc.core.exposure.exposure_time_us = BitsDouble(r.at(kExposureTime));
  rc.core.exposure.f_number = BitsDouble(r.at(kSimFNumber));
  rc.core.dof.focus_distance_m = BitsDouble(r.at(kSimFocusDistance));
  rc.core.sensor.gain_db = BitsDouble(r.at(kGain));
  rc.core.sensor.black_level_dn = BitsDouble(r.at(kBlackLevel));
  if (r.at(kSimSeed) != seed_register_at_start_) rc.core.seed = r.at(kSimSeed);
  rc.core.order_count = 0;
  for (size_t i = 0; i < configured_stages_.size(); ++i)
    if (r.at(SelectedAddress(kSimStageEnable, i)) != 0) rc.core.order[rc.core.order_count++] = configured_stages_[i];
  if (sensor_.has_white_balance)
    for (int i = 0; i < kBalanceCount; ++i)
      rc.core.white_balance.gain[i] = BitsDouble(r.at(SelectedAddress(kBalanceRatio, static_cast<size_t>(i), 8)));
  // GammaEnable: Y^Gamma is the power curve of gamma 1 / Gamma (`camsim run --set gamma.curve="power"
  // --set gamma.gamma=` that value, to 17 digits, makes the same frames).
  if (sensor_.has_gamma && r.at(kGammaEnable) != 0) {
    rc.core.gamma.curve = GammaCurve::kPower;
    rc.core.gamma.gamma = 1.0 / BitsDouble(r.at(kGamma));
  }
  // Plan only (no tables): the running renderer stays as it is on failure,
  // and Reconfigure installs this plan.
  if (!renderer_->PlanPipeline(rc, register_origins_, scenes_[0].width, scenes_[0].height, planned, error))
    return false;
  const Plan& plan = planned->pipeline->plan();
  const LineFormat out = plan.output;
  const bool rgb = out.channels == 3 && (out.domain == Domain::kEncoded || out.domain == Domain::kLinear);
  const PlanEntry* sensor = RunningSensor(plan);
  const bool from_isp = FromIsp(r.at(kPixelFormat), sensor_.cfa);  // RGB8, or Mono8 made from it
  if (from_isp ? !rgb : sensor == nullptr) {
    *error = "the selected PixelFormat needs " + std::string(from_isp ? "the ISP" : "the sensor");
    return false;
  }
  if (sensor != nullptr && sensor->out.channels != 1) {
    *error = kSensorNeedsCfa;
    return false;
  }
  return true;
}

std::vector<uint64_t> GigeDevice::PlanKey(const Registers& r) const {
  using namespace reg;
  std::vector<uint64_t> key = {r.at(kExposureTime), r.at(kSimFNumber), r.at(kSimFocusDistance), r.at(kGain),
                               r.at(kBlackLevel),   r.at(kSimSeed),    r.at(kPixelFormat)};
  for (size_t i = 0; i < configured_stages_.size(); ++i) key.push_back(r.at(SelectedAddress(kSimStageEnable, i)));
  if (sensor_.has_white_balance)
    for (int i = 0; i < kBalanceCount; ++i) key.push_back(r.at(SelectedAddress(kBalanceRatio, static_cast<size_t>(i), 8)));
  if (sensor_.has_gamma) {
    key.push_back(r.at(kGammaEnable));
    key.push_back(r.at(kGamma));
  }
  return key;
}

bool GigeDevice::Reconfigure(const Registers& r, std::string* error) {
  host::PlannedPipeline planned;
  const bool kept = kept_plan_ != nullptr && kept_plan_->key == PlanKey(r);
  if (kept) {
    planned = std::move(kept_plan_->planned);
    kept_plan_.reset();
  }
  return (kept || PlanFor(r, &planned, error)) && Install(std::move(planned), error);
}

bool GigeDevice::Install(host::PlannedPipeline planned, std::string* error) {
  if (!renderer_->Install(std::move(planned), origins_, error)) return false;
  if (!renderer_->has_scene()) current_scene_ = -1;  // the next frame prepares its input again
  return true;
}

// A client's write, as it arrives (in the order the client's writes came).
// AcquisitionStart, AcquisitionStop and AcquisitionAbort (value 1) set or
// clear the fake camera's acquisition register and are not stored, so each
// reads back 0. A value a feature never takes (out of its range, not one of
// its entries at that selection, e.g. a source for the input Line0), a
// window that would leave the sensor or an Auto lower limit above its upper
// limit is set back to the value in memory: invalid parameter; so is
// half of a Float: bad alignment, and a read-only feature's register:
// write protect. A change of a feature (or to an entry) that the table's
// availability and lock formulas refuse, on the registers as the block
// leaves them, is set back: access denied. A change of the pipeline's
// registers that the pipeline cannot run (a raw format without the sensor,
// RGB8 without the ISP, ...) is set back: invalid parameter (the block's
// pipeline registers together).
// Control privilege 0 (the client lets go, or libaravis ends it at a
// heartbeat timeout, maybe inside the packet that hands control to the next
// client) clears TLParamsLocked. A change of the payload's registers while
// acquiring or while TLParamsLocked is 1 (a block that also clears the
// acquisition register is a stop, and taken) is set back to the value in
// use: access denied. A window written before AcquisitionStart (even in the
// same millisecond) is taken, and a refused one never reaches the fake
// camera's stream. Writing the value in use passes. What is not set back in
// a block is stored.
WriteVerdict GigeDevice::FilterClientWrite(void* self, uint32_t address, uint32_t size, uint8_t* data) {
  auto* d = static_cast<GigeDevice*>(self);
  // Before Init has set the values in use (the GVCP thread may already
  // serve): not yet.
  if (!d->ready_) {
    ++d->writes_refused_;
    d->LogRefusal("a write at " + HexAddress(address), "the device is still starting");
    return {false, GevStatus::kAccessDenied};
  }
  // Client writes are whole registers (fake_camera_hooks.h, kMaxClientWrite).
  const auto covers = [&](uint32_t r) { return Covers(address, size, r); };
  const auto value = [&](uint32_t r) { return ValueAt(address, data, r); };
  const auto set_back = [&](uint32_t r) {  // the register's value in memory
    const uint32_t now = d->Read(r);
    for (uint32_t b = 0; b < 4; ++b) data[r - address + b] = static_cast<uint8_t>(now >> (24 - 8 * b));
  };
  // TriggerSoftware: one frame per write, taken as it arrives (a register
  // the sync polled merged writes that came within one sync period). Not
  // stored: it reads back 0. Not available (its formula, the XML's
  // pIsAvailable, on TriggerMode and TriggerSource as written so far):
  // refused, access denied. Available but while the acquisition is stopped:
  // acknowledged and dropped (counted in triggers_dropped, logged), as a
  // camera not waiting for a trigger drops it.
  if (covers(reg::kTriggerSoftware)) {
    if (size != 4 || value(reg::kTriggerSoftware) != 1) {
      ++d->writes_refused_;
      d->LogRefusal("TriggerSoftware = " + std::to_string(value(reg::kTriggerSoftware)),
                    size != 4 ? "a command is written alone" : "its CommandValue is 1");
      return {false, GevStatus::kInvalidParameter};
    }
    if (const std::string why = d->CommandRefusal(reg::kTriggerSoftware); !why.empty()) {
      ++d->writes_refused_;
      d->LogRefusal("TriggerSoftware = 1", why);
      return {false, GevStatus::kAccessDenied};
    }
    if (d->Read(reg::kAcquisition) != 0 || d->restarting_) {
      std::lock_guard<std::mutex> t(d->trigger_mutex_);
      d->TakeTrigger(kNextIndex, d->trigger_level_.load(), std::chrono::steady_clock::now());
    } else {
      ++d->triggers_dropped_;
      d->LogRefusal("TriggerSoftware", "the acquisition is stopped (no frame)", "dropped");
    }
    return {false, GevStatus::kSuccess};
  }
  // GevTimestampControl: latch (the timestamp now into GevTimestampValue),
  // then reset (the clock restarts from 0), as they arrive. Not stored.
  if (covers(reg::kTimestampControl)) {
    const uint32_t bits = value(reg::kTimestampControl);
    if (size != 4 || (bits & ~(reg::kTimestampLatch | reg::kTimestampReset)) != 0) {
      ++d->writes_refused_;
      d->LogRefusal("GevTimestampControl = " + std::to_string(bits),
                    size != 4 ? "a command is written alone" : "only its latch (2) and reset (1) bits exist");
      return {false, GevStatus::kInvalidParameter};
    }
    if (bits & reg::kTimestampLatch) {
      const uint64_t now = d->TimestampNow();
      d->Write(reg::kTimestampValue, static_cast<uint32_t>(now >> 32));
      d->Write(reg::kTimestampValue + 4, static_cast<uint32_t>(now));
    }
    if (bits & reg::kTimestampReset)
      d->timestamp_origin_ns_ = SteadyNs(std::chrono::steady_clock::now()) + d->clock_offset_ns_;
    return {false, GevStatus::kSuccess};
  }
  for (const uint32_t command : {reg::kAcquisitionStart, reg::kAcquisitionStop, reg::kAcquisitionAbort}) {
    if (!covers(command)) continue;
    if (size != 4 || value(command) != 1) {
      ++d->writes_refused_;
      d->LogRefusal(std::string(command == reg::kAcquisitionStart  ? "AcquisitionStart"
                                : command == reg::kAcquisitionStop ? "AcquisitionStop"
                                                                   : "AcquisitionAbort") +
                        " = " + std::to_string(value(command)),
                    size != 4 ? "a command is written alone" : "its CommandValue is 1");
      return {false, GevStatus::kInvalidParameter};
    }
    if (command != reg::kAcquisitionStart) d->WithdrawFreeRun(true);
    d->Write(reg::kAcquisition, command == reg::kAcquisitionStart);
    return {false, GevStatus::kSuccess};
  }
  // UserSetLoad and UserSetSave (value 1, alone): carried out as they
  // arrive, not stored (read back 0). A load changes the payload's
  // registers, so it is locked as they are; a save is refused where its
  // formula says it is not available (Default: read-only).
  if (covers(reg::kUserSetLoad) || covers(reg::kUserSetSave)) {
    const bool load = covers(reg::kUserSetLoad);
    const uint32_t command = load ? reg::kUserSetLoad : reg::kUserSetSave;
    const int64_t set = d->Read(reg::kUserSetSelector);
    const std::string what = std::string(load ? "UserSetLoad" : "UserSetSave") + "[" + UserSetName(set) + "]";
    if (size != 4 || value(command) != 1) {
      ++d->writes_refused_;
      d->LogRefusal(what + " = " + std::to_string(value(command)),
                    size != 4 ? "a command is written alone" : "its CommandValue is 1");
      return {false, GevStatus::kInvalidParameter};
    }
    GevStatus status = GevStatus::kSuccess;
    std::string why;
    if (load && (d->Read(reg::kAcquisition) != 0 || d->restarting_)) {
      status = GevStatus::kAccessDenied;
      why = "acquisition running (a user set changes the payload's registers, which are locked)";
    } else if (load && d->Read(reg::kTLParamsLocked) == 1) {
      status = GevStatus::kAccessDenied;
      why = "TLParamsLocked is 1 (a user set changes the payload's registers, which are locked)";
    } else if (load) {
      status = d->LoadUserSet(set, &why);
    } else if (why = d->CommandRefusal(reg::kUserSetSave); !why.empty()) {
      status = GevStatus::kAccessDenied;
    } else {
      const UserSet before = d->user_sets_[set];
      d->user_sets_[set] = {true, d->UserSetNow()};
      if (!d->user_set_file_.empty() && !d->WriteUserSetFile(d->Read(reg::kUserSetDefault), &why)) {
        d->user_sets_[set] = before;
        status = GevStatus::kError;
      }
    }
    if (status != GevStatus::kSuccess) {
      ++d->writes_refused_;
      d->LogRefusal(what, why);
    }
    return {false, status};
  }
  const auto set_back_feature = [&](const Feature& f) {  // the registers of `f` the write covers
    for (uint32_t r = f.address; r < f.address + f.length; r += 4)
      if (covers(r)) set_back(r);
  };
  WriteVerdict verdict;  // its status: the first refusal's, in the order of the checks below
  // Each refusal: its status and a line on stderr (what was written, why).
  const auto refuse = [&verdict, d](GevStatus s, const std::string& what, const std::string& why) {
    if (verdict.status == GevStatus::kSuccess) verdict.status = s;
    if (!what.empty()) d->LogRefusal(what, why);
  };
  // A write to a register only the device writes, or to an address of
  // camsim's range the XML does not describe, is refused whole, not stored
  // (it used to stop a free run through the fake camera's trigger mode).
  for (uint32_t r = address; r < address + size; r += 4) {
    if (r == reg::kDeviceMode || r == reg::kGvcpCapability) {
      ++d->writes_refused_;
      d->LogRefusal("register " + HexAddress(r), "a read-only bootstrap register");
      return {false, GevStatus::kWriteProtect};
    }
    // (The fake camera's own write that acknowledges a trigger is not a
    // client's: fake_camera_hooks.cc. A client's 0 there would withdraw a
    // frame the device asked for, and each queued trigger would answer one late.)
    if (!IsDeviceRange(r)) continue;
    bool described = false;
    for (const Feature& f : d->registers_) described = described || (r >= f.address && r < f.address + f.length);
    if (!described) {
      ++d->writes_refused_;
      d->LogRefusal("register " + HexAddress(r), "no feature there (or one only the device writes)");
      return {false, GevStatus::kInvalidAddress};
    }
  }
  // The payload's registers are locked while acquiring or while
  // TLParamsLocked is 1: checked before their values, so a locked write
  // says access denied whatever its value (OffsetX = 2 with the window at
  // full width was invalid parameter: the window check came first).
  if (covers(reg::kAcquisition) && value(reg::kAcquisition) == 0) d->WithdrawFreeRun(true);  // the fake camera's own register
  if (covers(reg::kControlChannelPrivilege) && value(reg::kControlChannelPrivilege) == 0)
    d->Write(reg::kTLParamsLocked, 0);
  if (covers(reg::kStreamPort) || covers(reg::kStreamDestAddress)) ++d->stream_opens_;  // block IDs start again
  bool geometry = false;
  for (uint32_t g : kGeometryRegisters) geometry = geometry || covers(g);
  // (TLParamsLocked, at 0x80a0, is never in one block with the window.)
  const bool acquiring = (d->Read(reg::kAcquisition) != 0 || d->restarting_) &&
                         (!covers(reg::kAcquisition) || value(reg::kAcquisition) != 0);
  const char* lock_reason = acquiring ? "acquisition running (the payload's registers are locked)"
                                      : "TLParamsLocked is 1 (the payload's registers are locked)";
  const auto register_name = [d](uint32_t r) {
    for (const Feature& f : d->registers_)
      if (f.address == r) return d->RegisterName(f);
    return std::string("?");
  };
  if (geometry && (acquiring || d->Read(reg::kTLParamsLocked) == 1)) {
    for (uint32_t g : kGeometryRegisters) {
      if (!covers(g) || value(g) == d->Read(g)) continue;
      const Feature* f = nullptr;
      for (const Feature& x : d->registers_)
        if (x.address == g && x.length == 4) f = &x;
      const std::string what = register_name(g) + " = " + (f ? d->ValueText(*f, value(g)) : std::to_string(value(g)));
      set_back(g);
      refuse(GevStatus::kAccessDenied, what, lock_reason);
    }
  }
  // The packet size (SCPS0's low 16 bits; the flag bits stay free) likewise:
  // a receiver places each packet by the size its stream started with.
  if (covers(reg::kPacketSize) && (acquiring || d->Read(reg::kTLParamsLocked) == 1) &&
      (value(reg::kPacketSize) & 0xffff) != (d->Read(reg::kPacketSize) & 0xffff)) {
    const std::string what = "GevSCPSPacketSize = " + std::to_string(value(reg::kPacketSize) & 0xffff);
    set_back(reg::kPacketSize);
    refuse(GevStatus::kAccessDenied, what, lock_reason);
  }
  // The table's availability and lock formulas (rules_: ExposureTime and
  // Gain while their Auto is not Off, the trigger while ExposureMode is
  // TriggerWidth, LineDebouncerTime at Line0, Gamma with GammaEnable on,
  // ...) on the registers as the block leaves them: a change of a feature
  // locked or not available there, or to an entry not available there, is
  // set back (access denied). A refusal changes the state the others are
  // judged on, so the rules run again until none refuses. Before the
  // values (a locked write is access denied whatever its value, as the
  // payload's lock) and again after them (a value set back may change a
  // formula's variable).
  const auto enforce_rules = [&] {
    const auto after = [&](uint32_t r) { return covers(r) ? value(r) : d->Read(r); };
    for (bool again = true; again;) {
      again = false;
      for (const RegisterRule& rule : d->rules_) {
        const Feature& f = *rule.feature;
        bool touched = false;
        uint64_t v = 0;  // the value as the block leaves it
        for (uint32_t r = f.address; r < f.address + f.length; r += 4) {
          touched = touched || covers(r);
          v = v << 32 | after(r);
        }
        if (!touched || v == d->ReadFeature(f)) continue;
        if (rule.entry != nullptr && v != static_cast<uint64_t>(rule.entry->value)) continue;
        const std::vector<int64_t> values = RuleValues(rule, after);
        if (!RuleRefuses(rule, values)) continue;
        set_back_feature(f);
        refuse(GevStatus::kAccessDenied, d->RegisterName(f) + " = " + d->ValueText(f, v), RuleWhy(rule, values));
        again = true;
      }
    }
  };
  enforce_rules();
  for (const Feature& f : d->registers_) {
    if (f.address >= uint64_t{address} + size || f.address + f.length <= address) continue;
    if (!f.writable && f.kind != Kind::kSwissKnife) {  // a read-only feature's register
      set_back_feature(f);
      refuse(GevStatus::kWriteProtect, d->RegisterName(f), "read-only");
      continue;
    }
    if (!Checked(f)) continue;
    bool whole = true;
    for (uint32_t r = f.address; r < f.address + f.length; r += 4) whole = whole && covers(r);
    uint64_t v = 0;  // the value written (a Float: its 8 bytes)
    for (uint32_t r = f.address; whole && r < f.address + f.length; r += 4) v = v << 32 | value(r);
    // A Bayer PixelFormat names the phase of the readout as the block leaves
    // it (ReverseX and ReverseY come first in registers_: set back already if refused).
    const auto bit = [&](uint32_t r) { return (covers(r) ? value(r) : d->Read(r)) & 1; };
    const int readout = static_cast<int>(bit(reg::kReverseX) | bit(reg::kReverseY) << 1);
    if (whole && d->Valid(f, v, readout)) continue;
    set_back_feature(f);
    // Half of a Float's register would make a value of two writes.
    if (whole) refuse(GevStatus::kInvalidParameter, d->RegisterName(f) + " = " + d->ValueText(f, v), d->WhyInvalid(f, v));
    else refuse(GevStatus::kBadAlignment, d->RegisterName(f), "half of its 8-byte register (write both halves in one block)");
  }
  // UserSetDefault is kept in the user set file as it is written (a camera's flash).
  if (covers(reg::kUserSetDefault) && value(reg::kUserSetDefault) != d->Read(reg::kUserSetDefault) &&
      !d->user_set_file_.empty()) {
    std::string why;
    if (!d->WriteUserSetFile(value(reg::kUserSetDefault), &why)) {
      const std::string what = "UserSetDefault = " + std::string(UserSetName(value(reg::kUserSetDefault)));
      set_back(reg::kUserSetDefault);
      refuse(GevStatus::kError, what, why);
    }
  }
  enforce_rules();
  // Binning x decimation must leave at least one pixel (Bayer: one 2x2
  // cell) on the axis: a write that would not is set back.
  const auto after_write = [&](uint32_t r) { return uint64_t{covers(r) ? value(r) : d->Read(r)}; };
  const uint32_t axis_factors[2][2] = {{reg::kBinningHorizontal, reg::kDecimationHorizontal},
                                       {reg::kBinningVertical, reg::kDecimationVertical}};
  for (int a = 0; a < 2; ++a) {
    const int step = d->sensor_.cfa == Cfa::kMono ? 1 : 2;
    if ((!covers(axis_factors[a][0]) && !covers(axis_factors[a][1])) ||
        ReadoutExtent(d->sensor_, a, after_write) >= step)
      continue;
    std::string what;
    for (const uint32_t r : axis_factors[a])
      if (covers(r)) what += (what.empty() ? "" : ", ") + register_name(r) + " = " + std::to_string(value(r));
    for (const uint32_t r : axis_factors[a])
      if (covers(r)) set_back(r);
    refuse(GevStatus::kInvalidParameter, what,
           "binning x decimation leaves less than one " + std::string(step == 1 ? "pixel" : "2x2 cell") +
               " of the sensor's " + std::to_string(a == 0 ? d->sensor_.width : d->sensor_.height));
  }
  // The window must stay on the readout (SFNC's pMax: WidthMax - OffsetX,
  // ...; WidthMax as the block leaves binning and decimation): a write that
  // would move it off is set back, the offset first.
  const std::pair<uint32_t, uint32_t> axes[2] = {{reg::kWidth, reg::kOffsetX}, {reg::kHeight, reg::kOffsetY}};
  const int limits[2] = {ReadoutExtent(d->sensor_, 0, after_write), ReadoutExtent(d->sensor_, 1, after_write)};
  for (int a = 0; a < 2; ++a) {
    const auto [extent, offset] = axes[a];
    const auto after = [&](uint32_t r) { return uint64_t{covers(r) ? value(r) : d->Read(r)}; };
    if (!covers(extent) && !covers(offset)) continue;
    if (after(extent) + after(offset) <= static_cast<uint64_t>(limits[a])) continue;
    const char* names[2][2] = {{"Width", "OffsetX"}, {"Height", "OffsetY"}};
    const std::string why = std::string("window off the sensor: ") + names[a][0] + " " +
                            std::to_string(after(extent)) + " + " + names[a][1] + " " + std::to_string(after(offset)) +
                            " > " + (a == 0 ? "WidthMax " : "HeightMax ") + std::to_string(limits[a]);
    std::string what;
    for (int i = 1; i >= 0; --i) {
      const uint32_t r = i == 0 ? extent : offset;
      if (covers(r)) what += (what.empty() ? "" : ", ") + std::string(names[a][i]) + " = " + std::to_string(value(r));
    }
    if (covers(offset)) set_back(offset);
    if (covers(extent) && after(extent) + after(offset) > static_cast<uint64_t>(limits[a])) set_back(extent);
    refuse(GevStatus::kInvalidParameter, what, why);
  }
  // A binning or decimation write that leaves the window too large for the
  // new readout resets it on that axis to the whole readout (Width =
  // WidthMax, OffsetX = 0), as many cameras do; a window that still fits
  // stays. Should the reset window leave a packed frame's last byte
  // partial, the block's reduction and window writes are refused instead.
  bool reduction = false;
  for (const uint32_t r : kReductionRegisters) reduction = reduction || covers(r);
  if (reduction) {
    uint64_t extent[2], start[2];
    bool reset[2];
    for (int a = 0; a < 2; ++a) {
      extent[a] = after_write(axes[a].first);
      start[a] = after_write(axes[a].second);
      reset[a] = extent[a] + start[a] > static_cast<uint64_t>(limits[a]);
      if (reset[a]) extent[a] = static_cast<uint64_t>(limits[a]), start[a] = 0;
    }
    const uint32_t format = static_cast<uint32_t>(after_write(reg::kPixelFormat));
    if ((reset[0] || reset[1]) && PackingOf(format) != Packing::kNone &&
        extent[0] * extent[1] * static_cast<uint64_t>(PixelBits(format)) % 8 != 0) {
      std::string what;
      for (const uint32_t r : kReductionRegisters)
        if (covers(r)) what += (what.empty() ? "" : ", ") + register_name(r) + " = " + std::to_string(value(r));
      for (const uint32_t r : kReductionRegisters)
        if (covers(r)) set_back(r);
      for (const auto& [e, o] : axes)
        for (const uint32_t r : {e, o})
          if (covers(r)) set_back(r);
      refuse(GevStatus::kInvalidParameter, what,
             "the window reset to the new readout, " + std::to_string(extent[0]) + " x " + std::to_string(extent[1]) +
                 ", would not end a packed frame on a byte");
    } else {
      const auto put = [&](uint32_t r, uint64_t v) {  // into the block if it writes r, else the register
        if (covers(r)) {
          for (uint32_t b = 0; b < 4; ++b) data[r - address + b] = static_cast<uint8_t>(v >> (24 - 8 * b));
        } else {
          d->Write(r, static_cast<uint32_t>(v));
        }
      };
      for (int a = 0; a < 2; ++a) {
        if (!reset[a]) continue;
        // Said once per reset axis; not during a user set load, whose own
        // window is written after its binning and decimation.
        if (d->refusal_capture_ == nullptr) {
          const char* names[2][3] = {{"Width", "OffsetX", "WidthMax"}, {"Height", "OffsetY", "HeightMax"}};
          std::string cause;
          for (const uint32_t r : axis_factors[a])
            if (covers(r)) cause += (cause.empty() ? "" : ", ") + register_name(r) + " = " + std::to_string(value(r));
          if (cause.empty()) cause = "the binning and decimation";
          d->LogRefusal(std::string(names[a][0]) + " = " + std::to_string(extent[a]) + ", " + names[a][1] + " = 0",
                        cause + " leaves " + names[a][2] + " " + std::to_string(limits[a]) + ", too small for the window (" +
                            names[a][0] + " " + std::to_string(after_write(axes[a].first)) + " + " + names[a][1] +
                            " " + std::to_string(after_write(axes[a].second)) + "): it is now the whole readout",
                        "reset");
        }
        put(axes[a].second, 0);
        put(axes[a].first, extent[a]);
      }
    }
    d->Write(reg::kWidthMax, static_cast<uint32_t>(ReadoutExtent(d->sensor_, 0, after_write)));
    d->Write(reg::kHeightMax, static_cast<uint32_t>(ReadoutExtent(d->sensor_, 1, after_write)));
  }
  // A packed format's frame is one bit stream that must end on a byte: the
  // fake camera sends Width x Height x bits / 8 whole bytes (12-bit packing:
  // an even pixel count; 10p: a multiple of 4). A write that would leave a
  // partial byte is set back.
  if (covers(reg::kWidth) || covers(reg::kHeight) || covers(reg::kPixelFormat)) {
    const auto after = [&](uint32_t r) { return uint64_t{covers(r) ? value(r) : d->Read(r)}; };
    const uint32_t format = static_cast<uint32_t>(after(reg::kPixelFormat));
    const uint64_t pixel_bits = after(reg::kWidth) * after(reg::kHeight) * static_cast<uint64_t>(PixelBits(format));
    if (PackingOf(format) != Packing::kNone && pixel_bits % 8 != 0) {
      const std::string why = "a packed frame of " + std::to_string(after(reg::kWidth)) + " x " +
                              std::to_string(after(reg::kHeight)) + " pixels of " + std::to_string(PixelBits(format)) +
                              " bits does not end on a byte (12-bit packing needs an even pixel count, 10p a "
                              "multiple of 4)";
      std::string what;
      for (const auto& [r, name] : {std::pair{reg::kWidth, "Width"}, {reg::kHeight, "Height"}}) {
        if (!covers(r)) continue;
        what += (what.empty() ? "" : ", ") + std::string(name) + " = " + std::to_string(value(r));
        set_back(r);
      }
      if (covers(reg::kPixelFormat)) {
        what += (what.empty() ? "" : ", ") + std::string("PixelFormat = ") +
                d->ValueText(*FindFeature(d->registers_, "PixelFormat"), format);
        set_back(reg::kPixelFormat);
      }
      refuse(GevStatus::kInvalidParameter, what, why);
    }
  }
  // An Auto lower limit stays at or below its upper limit (each one's pMax
  // or pMin): a write that would cross them is set back, the lower first.
  for (const AutoLimits& l : kAutoLimits) {
    const auto touched = [&](uint32_t r) { return covers(r) || covers(r + 4); };
    const auto after = [&](uint32_t r) {  // the Float as the write leaves it
      const auto word = [&](uint32_t w) { return uint64_t{covers(w) ? value(w) : d->Read(w)}; };
      return BitsDouble(word(r) << 32 | word(r + 4));
    };
    const auto set_back_float = [&](uint32_t r) {
      for (const uint32_t w : {r, r + 4})
        if (covers(w)) set_back(w);
    };
    if (!touched(l.lower) && !touched(l.upper)) continue;
    if (after(l.lower) <= after(l.upper)) continue;
    const std::string why = std::string(l.name) + "LowerLimit " + Fmt(after(l.lower)) + " above " + l.name +
                            "UpperLimit " + Fmt(after(l.upper));
    const std::string what = std::string(l.name) + (touched(l.lower) ? "LowerLimit" : "UpperLimit") + " = " +
                             Fmt(after(touched(l.lower) ? l.lower : l.upper));
    set_back_float(l.lower);
    if (after(l.lower) > after(l.upper)) set_back_float(l.upper);
    refuse(GevStatus::kInvalidParameter, what, why);
  }
  // Gain is applied in GainRaw's steps: a valid Gain written is stored (and
  // planned) as its nearest step, so it reads back as the gain in use.
  if (covers(reg::kGain) && covers(reg::kGain + 4)) {
    const uint64_t q = DoubleBits(QuantiseGain(BitsDouble(uint64_t{value(reg::kGain)} << 32 | value(reg::kGain + 4))));
    for (uint32_t b = 0; b < 8; ++b) data[reg::kGain - address + b] = static_cast<uint8_t>(q >> (56 - 8 * b));
  }
  // ReverseX and ReverseY: a Bayer PixelFormat follows the phase read out
  // (BayerRG12 -> BayerGR12 with ReverseX), unless the block writes one
  // (checked above against the new readout).
  if ((covers(reg::kReverseX) || covers(reg::kReverseY)) && !covers(reg::kPixelFormat)) {
    const auto bit = [&](uint32_t r) { return (covers(r) ? value(r) : d->Read(r)) & 1; };
    const int readout = static_cast<int>(bit(reg::kReverseX) | bit(reg::kReverseY) << 1);
    d->Write(reg::kPixelFormat, ReadoutFormat(d->Read(reg::kPixelFormat), d->sensor_.cfa, readout));
  }
  // The pipeline must run what the registers then ask for (raw formats need
  // the sensor and the cfa, RGB8 the ISP, the focus lies beyond the focal
  // length, ...): planned as the sync will plan it, without tables. The
  // pipeline registers of one block are one request.
  if (!d->PipelineTakes(address, size, data)) {
    for (const Feature& f : d->registers_)
      if (Checked(f) && d->IsPipelineRegister(f.address)) set_back_feature(f);
    refuse(GevStatus::kInvalidParameter, "", "");  // PipelineTakes logged it
  }
  // Gain and GainRaw are one setting in two units: the one written (not set
  // back) sets the other now, so the last write wins whatever the sync sees.
  const bool gain = covers(reg::kGain) && covers(reg::kGain + 4);
  const uint64_t gain_bits = gain ? (uint64_t{value(reg::kGain)} << 32 | value(reg::kGain + 4)) : 0;
  if (gain && gain_bits != DoubleBits(d->ReadDouble(reg::kGain))) {
    d->Write(reg::kGainRaw, static_cast<uint32_t>(GainRawOf(BitsDouble(gain_bits))));
  } else if (!gain && covers(reg::kGainRaw) && value(reg::kGainRaw) != d->Read(reg::kGainRaw)) {
    d->WriteDouble(reg::kGain, GainDbOf(value(reg::kGainRaw)));
  }
  // TriggerMode On during an acquisition: a free-run frame asked for and
  // not yet begun would come without a trigger.
  if (covers(reg::kTriggerMode) && value(reg::kTriggerMode) == 1 && d->Read(reg::kTriggerMode) != 1)
    d->WithdrawFreeRun(false);
  if (verdict.status != GevStatus::kSuccess) ++d->writes_refused_;
  return verdict;
}

void GigeDevice::WithdrawFreeRun(bool stop) {
  std::lock_guard<std::mutex> t(trigger_mutex_);
  if (stop) {
    ++acquisition_stops_;
    pending_triggers_.clear();  // triggers belong to the acquisition they came in
    exposure_busy_until_ = {};
    trigger_requested_ = false;
  }
  if (pending_triggers_.empty()) Write(reg::kFakeTriggerSoftware, 0);
  ++free_run_withdrawn_;
}

void GigeDevice::TakeClientStops() {
  const uint64_t stops = acquisition_stops_.load(), withdrawn = free_run_withdrawn_.load();
  if (withdrawn != withdrawn_seen_) {
    withdrawn_seen_ = withdrawn;
    free_run_requested_ = false;
  }
  if (stops != stops_seen_) {
    stops_seen_ = stops;
    was_acquiring_ = false;  // the next frame starts a new acquisition's count
  }
}

std::string GigeDevice::FrameFormat() const {
  const uint32_t code = Read(reg::kPixelFormat);
  std::string format = HexAddress(code);
  if (const Feature* f = FindFeature(table_, "PixelFormat"))
    for (const EnumEntry& e : f->entries)
      if (static_cast<uint32_t>(e.value) == code) format = e.name;
  return std::to_string(Read(reg::kWidth)) + "x" + std::to_string(Read(reg::kHeight)) + " at (" +
         std::to_string(Read(reg::kOffsetX)) + ", " + std::to_string(Read(reg::kOffsetY)) + ") in " + format;
}

std::string GigeDevice::RegisterName(const Feature& r) const {
  for (const Feature& f : table_) {
    if (f.selected_by.empty() || r.address < f.address || r.address >= f.address + f.length * f.selections) continue;
    const Feature* selector = FindFeature(table_, f.selected_by);
    const int64_t value = (r.address - f.address) / f.length;
    for (size_t e = 0; selector != nullptr && e < selector->entries.size(); ++e)
      if (selector->entries[e].value == value) return f.name + "[" + selector->entries[e].name + "]";
  }
  return r.name;
}

bool GigeDevice::IsPipelineRegister(uint32_t address) const {
  using namespace reg;
  if (address == kPixelFormat || address == kGainRaw) return true;
  for (uint32_t p : kPipelineRegisters)
    if (address == p) return true;
  if (sensor_.has_white_balance && address >= kBalanceRatio && address < SelectedAddress(kBalanceRatio, kBalanceCount, 8))
    return true;
  if (sensor_.has_gamma && (address == kGamma || address == kGammaEnable)) return true;
  return address >= kSimStageEnable && address < SelectedAddress(kSimStageEnable, configured_stages_.size());
}

// Under the camera's client-write lock: the registers (and applied_) stay as
// they are, and so does the pipeline in use that the plan borrows from.
bool GigeDevice::PipelineTakes(uint32_t address, uint32_t size, const uint8_t* data) const {
  using namespace reg;
  const auto covers = [&](uint32_t r) { return Covers(address, size, r); };
  const auto value = [&](uint32_t r) { return ValueAt(address, data, r); };
  bool pipeline = false;
  for (const Feature& f : registers_) pipeline = pipeline || (IsPipelineRegister(f.address) && covers(f.address));
  if (!pipeline) return true;
  Registers after;    // every checked register once the write is stored
  std::string names;  // the pipeline settings it changes
  for (const Feature& f : registers_) {
    if (!Checked(f)) continue;
    uint64_t v = 0;
    bool written = false;
    for (uint32_t r = f.address; r < f.address + f.length; r += 4) {
      written = written || covers(r);
      v = v << 32 | (covers(r) ? value(r) : Read(r));
    }
    after[f.address] = v;
    if (written && IsPipelineRegister(f.address) && v != ReadFeature(f))
      names += (names.empty() ? "" : ", ") + RegisterName(f);
  }
  if (names.empty()) return true;
  // Gain and GainRaw as FilterClientWrite joins them: the one written sets the other.
  if (!covers(kGain) && covers(kGainRaw)) after[kGain] = DoubleBits(GainDbOf(after[kGainRaw]));
  host::PlannedPipeline planned;
  std::string why;
  if (PlanFor(after, &planned, &why)) {
    kept_plan_ = std::make_unique<KeptPlan>(KeptPlan{PlanKey(after), std::move(planned)});
    return true;
  }
  LogRefusal(names, why);
  return false;
}

void GigeDevice::Sync() {
  using namespace reg;
  FlushRefusalLog(false);
  const ClientWritesHeld hold(fake_);  // one consistent state of the registers
  TakeClientStops();
  const bool acquiring = Read(kAcquisition) != 0;
  // Clients that go away. The fake camera picks its stream destination when
  // an acquisition starts and forgets it only when a control packet arrives
  // while acquisition or privilege is 0.
  const uint64_t dest = (static_cast<uint64_t>(Read(kStreamDestAddress)) << 16) | (Read(kStreamPort) & 0xffff);
  const bool controlled = Read(kControlChannelPrivilege) != 0;
  if (!controlled && (acquiring || Read(kTLParamsLocked) != 0)) {
    // The controller's heartbeat timed out (or it let go): stop, and unlock
    // the window, so the next client finds neither a stream running nor its
    // window writes refused.
    Write(kAcquisition, 0);
    Write(kTLParamsLocked, 0);
    applied_[kTLParamsLocked] = 0;
  } else if (acquiring && sync_saw_acquiring_ && dest != stream_dest_) {
    // A new client took control of a running acquisition (its predecessor was
    // killed: the heartbeat timeout and the new client's control request were
    // one packet) and set its own destination: make the fake camera re-read it
    // (SyncLoop, outside the lock: the fake camera's thread may wait for it in Fill).
    restart_stream_ = true;
  }
  stream_dest_ = dest;
  // The payload's registers during acquisition: FilterClientWrite.
  sync_saw_acquiring_ = acquiring;
  if (!acquiring) was_acquiring_ = false;
  if (!acquiring || Read(kTriggerMode) == 0) {
    // Triggers belong to an acquisition in trigger mode: none left for the
    // next. (The register as written: FilterClientWrite takes a trigger
    // that follows a TriggerMode write before this sync applies it.) In
    // free run the fake camera's flag is PaceFreeRun's request.
    std::lock_guard<std::mutex> t(trigger_mutex_);
    pending_triggers_.clear();
    exposure_busy_until_ = {};
    trigger_requested_ = false;
    if (!acquiring) free_run_requested_ = false;
    if (!free_run_requested_) Write(kFakeTriggerSoftware, 0);
  }

  Registers next = applied_;
  std::vector<const Feature*> changed;
  for (const Feature& f : registers_) {
    if (!Checked(f)) continue;
    const uint64_t v = ReadFeature(f);
    if (v == applied_.at(f.address)) continue;
    // (FilterClientWrite refuses invalid values as they arrive; this keeps
    // the applied state valid whatever wrote the memory.)
    if (Valid(f, v)) {
      next[f.address] = v;
      changed.push_back(&f);
    } else {
      LogRefusal(RegisterName(f) + " = " + ValueText(f, v), WhyInvalid(f, v) + " (found by the register sync)");
      WriteFeature(f, applied_.at(f.address));
      ++writes_refused_;
    }
  }
  if (changed.empty()) {
    // Nothing new; only commands.
  } else {
    auto was_changed = [&](uint32_t a) {
      for (const Feature* f : changed)
        if (f->address == a) return true;
      return false;
    };
    auto refuse = [&](uint32_t a) {
      next[a] = applied_.at(a);
      for (const Feature& f : registers_)
        if (f.address == a && f.alias_of.empty()) WriteFeature(f, applied_.at(a));
      ++writes_refused_;
    };
    // The window must stay on the sensor: refuse the offset, then the size
    // (FilterClientWrite does this as writes arrive; here whatever wrote the
    // registers).
    const std::pair<uint32_t, uint32_t> axes[2] = {{kWidth, kOffsetX}, {kHeight, kOffsetY}};
    // Binning and decimation that leave no pixel go back; the window is on
    // the readout they leave (a device write past the filter that makes it
    // too large resets it, as the filter does).
    const uint32_t axis_factors[2][2] = {{kBinningHorizontal, kDecimationHorizontal},
                                         {kBinningVertical, kDecimationVertical}};
    const auto at_next = [&](uint32_t r) { return next.at(r); };
    for (int a = 0; a < 2; ++a)
      if (ReadoutExtent(sensor_, a, at_next) < (sensor_.cfa == Cfa::kMono ? 1 : 2))
        for (const uint32_t r : axis_factors[a])
          if (was_changed(r)) refuse(r);
    const int limits[2] = {ReadoutExtent(sensor_, 0, at_next), ReadoutExtent(sensor_, 1, at_next)};
    for (int a = 0; a < 2; ++a) {
      if (next[axes[a].first] + next[axes[a].second] <= static_cast<uint64_t>(limits[a])) continue;
      if (was_changed(axis_factors[a][0]) || was_changed(axis_factors[a][1])) {
        next[axes[a].first] = static_cast<uint64_t>(limits[a]);
        next[axes[a].second] = 0;
        Write(axes[a].first, static_cast<uint32_t>(limits[a]));
        Write(axes[a].second, 0);
        continue;
      }
      if (was_changed(axes[a].second)) refuse(axes[a].second);
      if (next[axes[a].first] + next[axes[a].second] > static_cast<uint64_t>(limits[a])) refuse(axes[a].first);
    }
    Write(kWidthMax, static_cast<uint32_t>(limits[0]));
    Write(kHeightMax, static_cast<uint32_t>(limits[1]));
    // A packed frame ends on a byte: otherwise the format and size go back
    // to the applied ones (which do).
    if (PackingOf(static_cast<uint32_t>(next[kPixelFormat])) != Packing::kNone &&
        next[kWidth] * next[kHeight] * PixelBits(static_cast<uint32_t>(next[kPixelFormat])) % 8 != 0) {
      LogRefusal("PixelFormat, Width, Height",
                 "a packed frame that does not end on a byte (found by the register sync)");
      for (uint32_t a : {kPixelFormat, kWidth, kHeight})
        if (was_changed(a)) refuse(a);
    }
    // An Auto lower limit stays at or below its upper limit: refuse the lower, then the upper.
    for (const AutoLimits& l : kAutoLimits) {
      if (BitsDouble(next[l.lower]) <= BitsDouble(next[l.upper])) continue;
      if (was_changed(l.lower)) refuse(l.lower);
      if (BitsDouble(next[l.lower]) > BitsDouble(next[l.upper])) refuse(l.upper);
    }
    // Gain and GainRaw are one setting in two units.
    if (was_changed(kGain)) {  // (a device write past the filter may be off the steps)
      next[kGainRaw] = GainRawOf(BitsDouble(next[kGain]));
      next[kGain] = DoubleBits(GainDbOf(next[kGainRaw]));
      Write(kGainRaw, static_cast<uint32_t>(next[kGainRaw]));
      WriteDouble(kGain, BitsDouble(next[kGain]));
    } else if (was_changed(kGainRaw)) {
      next[kGain] = DoubleBits(GainDbOf(next[kGainRaw]));
      WriteDouble(kGain, BitsDouble(next[kGain]));
    }
    bool pipeline = false;
    for (const Feature* f : changed) pipeline = pipeline || IsPipelineRegister(f->address);
    std::string error;
    const auto t_rc = std::chrono::steady_clock::now();
    if (pipeline && !Reconfigure(next, &error)) {
      // FilterClientWrite planned every client write as it arrived, so only
      // a failure to build the tables, or a write past the filter, ends up
      // here: the pipeline's settings go back, every other write stays.
      std::fprintf(stderr, "camsim-gige: refused: %s\n", error.c_str());
      for (const Feature* f : changed)
        if (IsPipelineRegister(f->address)) refuse(f->address);
      next[kGain] = applied_.at(kGain);  // both units, one of them set above from the other
      next[kGainRaw] = applied_.at(kGainRaw);
      WriteDouble(kGain, AppliedDouble(kGain));
      Write(kGainRaw, Applied(kGainRaw));
    }
    if (std::getenv("CAMSIM_GIGE_DEBUG"))
      std::fprintf(stderr, "camsim-gige: reconfigured in %.1f ms\n",
                   std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t_rc).count());
    applied_ = next;
    WriteDerived();
  }
  // A strobe whose falling edge failed is lowered as soon as it can be (the
  // strobe is active only inside a frame's rendering, which holds mutex_ as
  // every Sync does): not left active until the next frame, if one comes.
  // A LineInverter[Line1] change moves the idle level likewise.
  const bool strobe_idle = Applied(SelectedAddress(kLineInverter, 1)) != 0;
  if (strobe_ && strobe_level_ != strobe_idle) DriveStrobe(false);
  if (!strobe_) strobe_level_ = strobe_idle;  // no line: LineStatus says what it would be
  Write(kSimSyncCount, Read(kSimSyncCount) + 1);
  {
    std::lock_guard<std::mutex> t(trigger_mutex_);
    line0_armed_ = Applied(kTriggerMode) == 1 && Applied(kTriggerSource) == kSourceLine0;
    line0_rising_ = Applied(kTriggerActivation) == 0;
    line0_width_ = line0_armed_ && Applied(kExposureMode) == kExposureTriggerWidth;
    if (!line0_width_) EndTriggerWidth(std::chrono::steady_clock::now());  // out of TriggerWidth: none stays open
    line0_inverted_ = Applied(SelectedAddress(kLineInverter, 0)) != 0;
    trigger_level_ = line0_electrical_ != line0_inverted_;
    line0_debounce_ = std::chrono::duration_cast<std::chrono::steady_clock::duration>(
        std::chrono::duration<double, std::micro>(AppliedDouble(kLineDebouncerTime)));
  }
  WriteLineStatus();  // the trigger thread changes the input's level without mutex_
  {
    std::lock_guard<std::mutex> t(trigger_mutex_);
    trigger_exposure_ = std::chrono::duration_cast<std::chrono::steady_clock::duration>(
        std::chrono::duration<double, std::micro>(AppliedDouble(kExposureTime)));
    trigger_delay_ = std::chrono::duration_cast<std::chrono::steady_clock::duration>(
        std::chrono::duration<double, std::micro>(AppliedDouble(kTriggerDelay)));
  }
}

void GigeDevice::TakeTrigger(int64_t index, bool line0_high, std::chrono::steady_clock::time_point at, bool width) {
  if (pending_triggers_.size() >= kMaxPendingTriggers) {
    ++triggers_dropped_;
    if (!overrun_logged_.exchange(true))
      std::fprintf(stderr, "camsim-gige: triggers come faster than frames are made; %zu wait, later ones are dropped\n",
                   kMaxPendingTriggers);
    return;
  }
  if (width) EndTriggerWidth(at);  // an activation edge ends any pulse still open (one at a time)
  const auto start = std::max(at + trigger_delay_, exposure_busy_until_);
  exposure_busy_until_ = width ? start : start + trigger_exposure_;
  const auto end = width ? std::chrono::steady_clock::time_point::max() : exposure_busy_until_;
  pending_triggers_.push_back({index, line0_high, start, end, width, width});
  FireDueTrigger(std::chrono::steady_clock::now());
}

void GigeDevice::EndTriggerWidth(std::chrono::steady_clock::time_point at) {
  // At most one is open, the newest of its kind; later Timed triggers may
  // queue behind it (a mode change), so it is found wherever it is.
  const auto open = std::find_if(pending_triggers_.begin(), pending_triggers_.end(),
                                 [](const PendingTrigger& q) { return q.width_open; });
  if (open == pending_triggers_.end()) return;
  PendingTrigger& p = *open;
  p.exposure_end = std::max(at + trigger_delay_, p.exposure_start + std::chrono::microseconds(1));
  p.width_open = false;
  exposure_busy_until_ = p.exposure_end;
  FireDueTrigger(std::chrono::steady_clock::now());
}

std::chrono::steady_clock::time_point GigeDevice::FireDueTrigger(std::chrono::steady_clock::time_point now) {
  if (pending_triggers_.empty() || trigger_requested_) return std::chrono::steady_clock::time_point::max();
  if (pending_triggers_.front().exposure_end > now) return pending_triggers_.front().exposure_end;
  // Once: the fake camera clears its flag as it takes the request, and a
  // second 1 before the frame begins (FillLocked) would ask for another frame.
  Write(reg::kFakeTriggerSoftware, 1);
  trigger_requested_ = true;
  return std::chrono::steady_clock::time_point::max();
}

void GigeDevice::RestartStream() {
  using namespace reg;
  // The fake camera forgets its stream destination only when it handles a
  // control packet while Acquisition is 0 (arvgvfakecamera.c, _thread). Its
  // thread takes one packet per loop and checks Acquisition right after it,
  // so once a second read is answered, the check after the first has run;
  // if Acquisition still reads 0, it ran with 0 and the stream is dropped.
  // A client that wrote AcquisitionStart meanwhile (it reads 1) costs a
  // round. The thread can be busy rendering: each answer may take a while.
  // A client's stop meanwhile (acquisition_stops_) ends it: the acquisition
  // is not set again over the stop.
  restarting_ = true;  // the window stays locked (FilterClientWrite)
  const uint64_t stops = acquisition_stops_;
  bool dropped = false;
  for (int round = 0; round < kRestartRounds && !dropped && acquisition_stops_ == stops; ++round) {
    Write(kAcquisition, 0);
    dropped = GvcpRoundTrip(address_, kRestartAnswerMs) && GvcpRoundTrip(address_, kRestartAnswerMs) &&
              Read(kAcquisition) == 0;
  }
  bool stopped = false;
  {
    // Under the lock a client's write is decided under: a stop cannot come
    // between the check and the write.
    const ClientWritesHeld hold(fake_);
    stopped = acquisition_stops_ != stops;
    if (!stopped && Read(kAcquisition) == 0) Write(kAcquisition, 1);
  }
  restarting_ = false;
  if (dropped || stopped) return;
  std::lock_guard<std::mutex> lock(mutex_);
  LogOnce("restart-stream", "camsim-gige: could not make the fake camera drop a killed client's stream");
}

void GigeDevice::ProbeHeartbeat(bool acquiring) {
  const auto now = std::chrono::steady_clock::now();
  if (now - last_probe_ < std::chrono::milliseconds(kHeartbeatProbeMs)) return;
  last_probe_ = now;
  const uint64_t packets = ControllerPackets(address_.c_str());
  const bool renew = packets != controller_packets_;  // the controller sent a command since the last probe
  controller_packets_ = packets;
  if (!renew && !acquiring) return;
  if (probe_fd_ < 0) probe_fd_ = socket(AF_INET, SOCK_DGRAM | SOCK_CLOEXEC | SOCK_NONBLOCK, 0);
  if (probe_fd_ < 0) return;
  uint8_t answer[64];
  while (recv(probe_fd_, answer, sizeof answer, 0) > 0) continue;  // the earlier probes' answers
  sockaddr_in to{};
  to.sin_family = AF_INET;
  to.sin_port = htons(kGvcpPort);
  inet_pton(AF_INET, address_.c_str(), &to.sin_addr);
  // READREG_CMD of the privilege register, whose read renews the
  // controller's heartbeat (whoever sends it), or else of the version register.
  const uint32_t read = renew ? kControlChannelPrivilege : reg::kVersion;
  const uint8_t cmd[12] = {0x42, 0x01, 0x00, 0x80, 0x00, 0x04, 0xbe, 0xa7, static_cast<uint8_t>(read >> 24),
                           static_cast<uint8_t>(read >> 16), static_cast<uint8_t>(read >> 8), static_cast<uint8_t>(read)};
  sendto(probe_fd_, cmd, sizeof cmd, 0, reinterpret_cast<sockaddr*>(&to), sizeof to);
}

void GigeDevice::SyncLoop() {
  while (!stop_) {
    bool restart = false, probe = false, acquiring = false;
    auto wake = std::chrono::steady_clock::now() + std::chrono::milliseconds(kSyncPeriodMs);
    {
      std::lock_guard<std::mutex> lock(mutex_);
      Sync();
      wake = std::min(wake, PaceFreeRun());  // a free-run slot before the next sync: wake for it
      {
        std::lock_guard<std::mutex> t(trigger_mutex_);
        wake = std::min(wake, FireDueTrigger(std::chrono::steady_clock::now()));  // a trigger's exposure ending
      }
      restart = restart_stream_;
      restart_stream_ = false;
      probe = gv_ != nullptr && probe_heartbeat_ && Read(kControlChannelPrivilege) != 0;
      acquiring = Read(reg::kAcquisition) != 0;
    }
    if (restart) RestartStream();
    if (probe) ProbeHeartbeat(acquiring);
    std::this_thread::sleep_until(wake);
  }
}

// LineDebouncerTime: a level is taken once it has held the debounce time,
// judged by the edges' own timestamps (hal::InputLine::LastEdgeTime: a GPIO
// line's kernel stamp, a trigger bus sender's; the time an edge was read
// where a line has none). An edge that comes within
// the debounce time of the last one cancels it; one that comes later
// confirms the level before it, at its start plus the debounce time,
// however late the edges are read. With no edge queued, a level is taken
// when the thread wakes at its deadline (the wait's 1 ms steps). A debounce
// time of 0 takes each edge as it is read.
void GigeDevice::TriggerLoop() {
  using Clock = std::chrono::steady_clock;
  // Line0 on the wire as the last edge left it, since when, and the frame index that edge carried.
  bool wire = false;
  Clock::time_point wire_since{};
  int64_t wire_index = kNextIndex;
  while (!stop_) {
    int timeout_ms = 50;
    {
      std::lock_guard<std::mutex> lock(trigger_mutex_);
      if (wire != line0_electrical_) {  // a level waiting to be taken: wake at its deadline
        const auto left = wire_since + line0_debounce_ - Clock::now();
        const auto ms = std::chrono::ceil<std::chrono::milliseconds>(left).count();
        timeout_ms = static_cast<int>(std::clamp<int64_t>(ms, 0, 50));
      }
    }
    hal::Edge edge;
    std::string error;
    const int r = trigger_->WaitEdge(timeout_ms, &edge, &error);
    if (const std::string notice = trigger_->TakeNotice(); !notice.empty())
      std::fprintf(stderr, "camsim-gige: %s\n", notice.c_str());
    if (r < 0) {
      std::lock_guard<std::mutex> lock(mutex_);
      line_error_ = error;
      std::fprintf(stderr, "camsim-gige: trigger line stopped: %s\n", error.c_str());
      return;
    }
    const Clock::time_point now = Clock::now();
    std::lock_guard<std::mutex> lock(trigger_mutex_);
    if (r == 1) {
      Clock::time_point at = now;
      if (!trigger_->LastEdgeTime(&at) || at > now) at = now;
      // Edges are in order: one whose stamp fell back to its read time (the
      // reader stalled past kMaxEdgeAgeS) must not come before the next.
      at = std::max(at, wire_since);
      // The level before this edge held from wire_since to `at`.
      if (wire != line0_electrical_ && at - wire_since >= line0_debounce_)
        TakeLine0Level(wire, wire_since + line0_debounce_, wire_index);
      wire = edge == hal::Edge::kRising;
      wire_since = at;
      // A trigger bus pulse names the frame to take: every camera of the rig
      // renders the same frame index, also after a missed pulse.
      uint32_t index = 0;
      wire_index = trigger_->LastEdgeIndex(&index) ? static_cast<int64_t>(index & 0x7fffffff) : kNextIndex;
    }
    if (wire != line0_electrical_ &&
        (line0_debounce_ == Clock::duration::zero() || (r == 0 && now - wire_since >= line0_debounce_)))
      TakeLine0Level(wire, wire_since + line0_debounce_, wire_index);
    if (r == 1) ++trigger_edges_;
  }
}

void GigeDevice::TakeLine0Level(bool electrical, std::chrono::steady_clock::time_point at, int64_t index) {
  line0_electrical_ = electrical;
  // The trigger logic and LineStatus see the level after LineInverter.
  const bool high = electrical != line0_inverted_;
  trigger_level_ = high;  // LineStatus: written by the next sync
  if (high == line0_rising_ && line0_armed_ && Read(reg::kAcquisition) != 0) TakeTrigger(index, high, at, line0_width_);
  if (high != line0_rising_) EndTriggerWidth(at);  // (also after the mode changed: none stays open)
}

void GigeDevice::FillThunk(ArvBuffer* buffer, void* self, uint32_t, uint32_t, uint32_t pixel_format) {
  static_cast<GigeDevice*>(self)->Fill(buffer, pixel_format);
}

void GigeDevice::AutoAdjust(double frac) {
  using namespace reg;
  const uint32_t ea = Applied(kExposureAuto), ga = Applied(kGainAuto);
  if (ea == kAutoOff && ga == kAutoOff) {
    auto_state_valid_ = false;
    return;
  }
  // A client's write waits: its filter plans on the pipeline in use and the
  // applied values, which this may replace. (A served camera fills frames on
  // its GVCP thread, which also runs the filter; RenderNow may not.)
  const ClientWritesHeld hold(fake_);
  // A client changed a mode since the sync (ExposureAuto Off, then maybe
  // ExposureTime): the sync takes it; no step over those writes.
  if (Read(kExposureAuto) != ea || Read(kGainAuto) != ga) return;
  // The core's controller (core/control/auto_exposure.h) with the features
  // that are Off held at their current value, and those that are on in
  // their Auto limits (which register_table.cc keeps inside the features'
  // own ranges). It keeps its state from frame to frame; a change of mode,
  // target, a limit or SimFNumber, or a host write of ExposureTime or Gain,
  // starts it afresh from the applied values.
  if (!auto_state_valid_ || AutoKey() != auto_key_) {
    const double t0 = AppliedDouble(kExposureTime), g0 = AppliedDouble(kGain);
    AutoExposureConfig& c = auto_config_;
    c = AutoExposureConfig();
    c.mode = (ea == kAutoContinuous || ga == kAutoContinuous) ? AutoExposureMode::kContinuous : AutoExposureMode::kOnce;
    c.target = AppliedDouble(kSimAutoTarget);  // the register's range is inside the controller's
    c.exposure_time_min_us = ea != kAutoOff ? AppliedDouble(kAutoExposureTimeLowerLimit) : t0;
    c.exposure_time_max_us = ea != kAutoOff ? AppliedDouble(kAutoExposureTimeUpperLimit) : t0;
    c.gain_min_db = ga != kAutoOff ? AppliedDouble(kAutoGainLowerLimit) : g0;
    c.gain_max_db = ga != kAutoOff ? AppliedDouble(kAutoGainUpperLimit) : g0;
    // The aperture stays where SimFNumber puts it (no f-number range given).
    if (!RestartAuto()) return;
  }
  ExposureSettings s = auto_exposure_.Update(frac);
  Registers next = AutoRegisters(s);
  std::string error;
  if (next != applied_ && !Reconfigure(next, &error)) {
    // The pipeline refuses the request (CCD smear and motion blur need a
    // minimum exposure, for example): the controller's range ends where the
    // pipeline's does, and it starts afresh from the applied settings.
    const double t1 = s.exposure_time_us, g1 = std::round(s.gain_db * 10) / 10;
    const AutoExposureConfig limits = auto_config_;
    LimitAutoRange(s);
    const AutoExposureConfig& c = auto_config_;
    // The applied settings may lie outside the Auto limits (written before
    // the Auto feature went on): then the pipeline may take nothing inside.
    if (c.exposure_time_min_us > c.exposure_time_max_us || c.gain_min_db > c.gain_max_db)
      return StopAuto("the pipeline refuses every setting within the Auto limits, ExposureTime " +
                      Fmt(limits.exposure_time_min_us) + ".." + Fmt(limits.exposure_time_max_us) + " us and Gain " +
                      Fmt(limits.gain_min_db) + ".." + Fmt(limits.gain_max_db) + " dB (" + error + ")");
    LogOnce(error, "camsim-gige: auto exposure: the pipeline refuses ExposureTime " + Fmt(t1) + " us, Gain " +
                       Fmt(g1) + " dB (" + error + "); its range is now ExposureTime " + Fmt(c.exposure_time_min_us) +
                       ".." + Fmt(c.exposure_time_max_us) + " us, Gain " + Fmt(c.gain_min_db) + ".." +
                       Fmt(c.gain_max_db) + " dB");
    if (!RestartAuto()) return;
    s = auto_exposure_.Update(frac);
    next = AutoRegisters(s);
    if (next != applied_ && !Reconfigure(next, &error)) return StopAuto(error);
  }
  // Once ends when the controller settles, or when a frame taken at the end
  // of its range still asks to go further (pinned: the target is out of
  // reach). The controller runs Continuous when the other feature is.
  const bool once_done = auto_exposure_.done() || !auto_exposure_.active() || auto_exposure_.pinned();
  if (ea == kAutoOnce && once_done) next[kExposureAuto] = kAutoOff;
  if (ga == kAutoOnce && once_done) next[kGainAuto] = kAutoOff;
  for (const auto& kv : next)
    if (kv.second != applied_[kv.first]) SetApplied(kv.first, kv.second);
  auto_key_ = AutoKey();
}

void GigeDevice::BalanceWhite(int x, int y, int w, int h) {
  using namespace reg;
  // Gray world: each CFA colour's mean raw level above black in the window
  // (what the white balance stage multiplies, up to a common scale).
  double sum[3] = {};
  uint64_t count[3] = {};
  const double black = AppliedDouble(kBlackLevel);
  for (int r = y; r < y + h; ++r)
    for (int i = x; i < x + w; ++i) {
      const Colour colour = CfaColour(sensor_.cfa, i, r);
      sum[colour] += raw_[static_cast<size_t>(r) * sensor_.width + i] - black;
      ++count[colour];
    }
  const ClientWritesHeld hold(fake_);  // the filter plans on applied_ and the pipeline in use
  Registers next = applied_;
  const auto ratio = [](int colour) { return SelectedAddress(kBalanceRatio, static_cast<size_t>(colour), 8); };
  double mean[3];
  for (int c = 0; c < 3; ++c) mean[c] = count[c] > 0 ? sum[c] / static_cast<double>(count[c]) : 0.0;
  // Green keeps its ratio; Red and Blue bring their means to Green's. A
  // colour without signal (a black frame) keeps its ratio.
  const double green = AppliedDouble(ratio(kGreen)) * mean[kGreen];
  for (const int c : {kRed, kBlue})
    if (mean[c] > 0.0 && green > 0.0) next[ratio(c)] = DoubleBits(std::clamp(green / mean[c], 0.0, kMaxBalanceRatio));
  if (Applied(kBalanceWhiteAuto) == kAutoOnce) next[kBalanceWhiteAuto] = kAutoOff;  // SFNC: Once returns to Off
  std::string error;
  if (next[ratio(kRed)] != applied_.at(ratio(kRed)) || next[ratio(kBlue)] != applied_.at(ratio(kBlue))) {
    if (!Reconfigure(next, &error)) {  // not expected: the stage takes every gain in range
      LogOnce("balance: " + error, "camsim-gige: BalanceWhiteAuto: the pipeline refuses the gains (" + error + ")");
      next[ratio(kRed)] = applied_.at(ratio(kRed));
      next[ratio(kBlue)] = applied_.at(ratio(kBlue));
      next[kBalanceWhiteAuto] = kAutoOff;
    }
  }
  for (const auto& kv : next)
    if (kv.second != applied_[kv.first]) SetApplied(kv.first, kv.second);
}

GigeDevice::Registers GigeDevice::AutoRegisters(const ExposureSettings& s) const {
  using namespace reg;
  Registers next = applied_;
  // A feature that is Off keeps its register (the controller holds it at the
  // applied value, which need not be on GainRaw's 0.1 dB steps).
  if (Applied(kExposureAuto) != kAutoOff) next[kExposureTime] = DoubleBits(s.exposure_time_us);
  if (Applied(kGainAuto) != kAutoOff) {
    // GainRaw's 0.1 dB steps, the nearest inside the AutoGain limits (which
    // need not lie on a step; with no step between them, the lower's nearest).
    const double lower = AppliedDouble(kAutoGainLowerLimit), upper = AppliedDouble(kAutoGainUpperLimit);
    const int64_t lo = static_cast<int64_t>(std::ceil(lower * 10 - 1e-9)),
                  hi = static_cast<int64_t>(std::floor(upper * 10 + 1e-9));
    int64_t raw = std::lround(s.gain_db * 10);
    raw = lo > hi ? std::lround(lower * 10) : std::clamp(raw, lo, hi);
    next[kGainRaw] = static_cast<uint64_t>(raw);
    next[kGain] = DoubleBits(GainDbOf(next[kGainRaw]));
  }
  return next;
}

bool GigeDevice::RestartAuto() {
  using namespace reg;
  const Status st = auto_exposure_.Configure(
      auto_config_, {AppliedDouble(kExposureTime), AppliedDouble(kGain), AppliedDouble(kSimFNumber)});
  if (!st.ok()) {
    StopAuto(host::DescribeStatus(st, origins_));
    return false;
  }
  auto_state_valid_ = true;
  return true;
}

void GigeDevice::StopAuto(const std::string& error) {
  using namespace reg;
  LogOnce("off: " + error, "camsim-gige: ExposureAuto and GainAuto turned Off: " + error);
  SetApplied(kExposureAuto, kAutoOff);
  SetApplied(kGainAuto, kAutoOff);
  auto_state_valid_ = false;
}

void GigeDevice::LimitAutoRange(const ExposureSettings& want) {
  using namespace reg;
  const double t0 = AppliedDouble(kExposureTime), g0 = AppliedDouble(kGain);
  auto accepted = [&](double t, double g) {  // the registers a request would set, planned only
    host::PlannedPipeline unused;
    std::string error;
    return PlanFor(AutoRegisters({t, g, AppliedDouble(kSimFNumber)}), &unused, &error);
  };
  // Exposure first, at the applied gain: bisection on log2(t) between the
  // applied value (accepted) and the request (refused).
  double t = want.exposure_time_us;
  if (t != t0 && !accepted(t, g0)) {
    const double log_ratio = std::log2(t / t0);
    double ok = 0, bad = 1;
    for (int i = 0; i < 20; ++i) {
      const double mid = (ok + bad) / 2;
      (accepted(t0 * std::exp2(mid * log_ratio), g0) ? ok : bad) = mid;
    }
    t = t0 * std::exp2(ok * log_ratio);
    (log_ratio < 0 ? auto_config_.exposure_time_min_us : auto_config_.exposure_time_max_us) = t;
  }
  // Then gain, at that exposure, in GainRaw's 0.1 dB steps.
  const long raw0 = std::lround(g0 * 10), raw1 = std::lround(want.gain_db * 10);
  if (raw1 != raw0 && !accepted(t, raw1 / 10.0)) {
    long ok = raw0, bad = raw1;
    while (ok - bad > 1 || bad - ok > 1) {
      const long mid = ok + (bad - ok) / 2;
      (accepted(t, mid / 10.0) ? ok : bad) = mid;
    }
    (raw1 < raw0 ? auto_config_.gain_min_db : auto_config_.gain_max_db) = ok / 10.0;
  }
}

void GigeDevice::LogRefusal(const std::string& what, const std::string& why, const char* verb) const {
  if (refusal_capture_ != nullptr && refusal_capture_->empty()) *refusal_capture_ = what + ": " + why;
  const auto now = std::chrono::steady_clock::now();
  std::lock_guard<std::mutex> lock(refusal_log_mutex_);
  if (now - refusal_window_ >= std::chrono::seconds(1)) {
    refusal_window_ = now;
    refusal_lines_ = 0;
  }
  if (refusal_lines_ >= kRefusalLinesPerSecond) {
    ++refusals_unlogged_;
    return;
  }
  ++refusal_lines_;
  std::string more;
  if (refusals_unlogged_ > 0)
    more = " (" + std::to_string(refusals_unlogged_) + " earlier lines not logged: over " +
           std::to_string(kRefusalLinesPerSecond) + " a second)";
  refusals_unlogged_ = 0;
  std::fprintf(stderr, "camsim-gige: %s %s: %s%s\n", verb, what.c_str(), why.c_str(), more.c_str());
}

void GigeDevice::FlushRefusalLog(bool at_end) const {
  std::lock_guard<std::mutex> lock(refusal_log_mutex_);
  if (refusals_unlogged_ == 0) return;
  if (!at_end && std::chrono::steady_clock::now() - refusal_window_ < std::chrono::seconds(1)) return;
  std::fprintf(stderr, "camsim-gige: %llu more lines not logged: over %d a second\n",
               static_cast<unsigned long long>(refusals_unlogged_), kRefusalLinesPerSecond);
  refusals_unlogged_ = 0;
}

std::string GigeDevice::CommandRefusal(uint32_t address) const {
  const auto read = [this](uint32_t r) { return Read(r); };
  for (const RegisterRule& rule : rules_) {
    if (rule.feature->address != address || rule.entry != nullptr) continue;
    const std::vector<int64_t> values = RuleValues(rule, read);
    if (RuleRefuses(rule, values)) return RuleWhy(rule, values);
  }
  return "";
}

std::string GigeDevice::ValueText(const Feature& f, uint64_t v) const {
  switch (f.kind) {
    case Kind::kFloat: return Fmt(BitsDouble(v));
    case Kind::kEnum:
      for (const EnumEntry& e : TableFeature(table_, f).entries)
        if (static_cast<uint64_t>(e.value) == v) return e.name + " (" + std::to_string(v) + ")";
      return std::to_string(v);
    default: return std::to_string(MaskedValue(f, v));
  }
}

std::string GigeDevice::WhyInvalid(const Feature& f, uint64_t v) const {
  if (Valid(f, v)) return "";
  switch (f.kind) {
    case Kind::kInteger: {
      const double x = static_cast<double>(MaskedValue(f, v));
      if (x < f.min || x > f.max) return "out of range " + Fmt(f.min) + ".." + Fmt(f.max);
      return "off its increment " + Fmt(f.inc) + " (from " + Fmt(f.min) + ")";
    }
    case Kind::kFloat:
      if (!std::isfinite(BitsDouble(v))) return "not a finite number";
      return "out of range " + Fmt(f.min) + ".." + Fmt(f.max);
    case Kind::kEnum:
      for (const EnumEntry& e : TableFeature(table_, f).entries)
        if (static_cast<uint64_t>(e.value) == v && e.readout >= 0)
          return "entry " + e.name + " is not the phase this readout gives (ReverseX " + std::to_string(Readout() & 1) +
                 ", ReverseY " + std::to_string(Readout() >> 1) + ")";
        else if (static_cast<uint64_t>(e.value) == v && f.address == reg::kTriggerSource && v == kSourceLine0 &&
                 !sensor_.has_trigger_line)
          return "entry Line0 is not available: this camera has no trigger line (start it with --trigger-line)";
        else if (static_cast<uint64_t>(e.value) == v)
          return "entry " + e.name + " is not available (at this selector value, or on this device)";
      return "no such entry";
    case Kind::kBoolean: return "a Boolean is 0 or 1";
    default: return "not writable";
  }
}

void GigeDevice::LogOnce(const std::string& key, const std::string& message) {
  if (logged_.insert(key).second) std::fprintf(stderr, "%s\n", message.c_str());
}

std::array<uint64_t, 10> GigeDevice::AutoKey() const {
  using namespace reg;
  return {applied_.at(kExposureAuto),
          applied_.at(kGainAuto),
          applied_.at(kSimAutoTarget),
          applied_.at(kExposureTime),
          applied_.at(kGain),
          applied_.at(kSimFNumber),
          applied_.at(kAutoExposureTimeLowerLimit),
          applied_.at(kAutoExposureTimeUpperLimit),
          applied_.at(kAutoGainLowerLimit),
          applied_.at(kAutoGainUpperLimit)};
}

std::chrono::steady_clock::duration GigeDevice::FreeRunPeriod() const {
  using namespace reg;
  // The first frame of an acquisition goes at once (FillLocked sets was_acquiring_).
  if (!was_acquiring_ || Applied(kTriggerMode) != 0 || Applied(kAcquisitionFrameRateEnable) == 0) return {};
  return FramePeriod(AppliedDouble(kAcquisitionFrameRate), AppliedDouble(kExposureTime));
}

std::chrono::steady_clock::time_point GigeDevice::PaceFreeRun() {
  using namespace reg;
  using Clock = std::chrono::steady_clock;
  const Clock::time_point now = Clock::now();
  TakeClientStops();
  if (free_run_requested_ || Read(kAcquisition) == 0 || Applied(kTriggerMode) != 0) return Clock::time_point::max();
  const Clock::duration period = FreeRunPeriod();
  if (period > Clock::duration::zero()) {
    const FrameSlot next = NextFrameSlot(frame_slot_, now, period);
    if (next.start > now) return next.start;
  }
  free_run_requested_ = true;
  Write(kFakeTriggerSoftware, 1);
  return Clock::time_point::max();
}

void GigeDevice::TakeFrameSlot() {
  const std::chrono::steady_clock::time_point now = std::chrono::steady_clock::now();
  const std::chrono::steady_clock::duration period = FreeRunPeriod();
  frame_slot_ = period > period.zero() ? NextFrameSlot(frame_slot_, now, period).slot : now;
  free_run_requested_ = false;
}

void GigeDevice::Fill(ArvBuffer* buffer, uint32_t pixel_format) {
  uint64_t dest = 0;
  bool chunks = false;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    TakeClientStops();  // a stop and a start inside one sync period: this is a new acquisition's first frame
    TakeFrameSlot();
    // The frame's time is its slot on the fake camera's clock (it stamps the
    // buffer itself before this callback): free-run frames keep their cadence,
    // as a camera's sensor timing does, however late this thread runs.
    // A triggered frame's time is its exposure's start (TakeTrigger).
    auto start = frame_slot_;
    if (Applied(reg::kTriggerMode) == 1) {
      std::lock_guard<std::mutex> t(trigger_mutex_);
      if (!pending_triggers_.empty()) start = pending_triggers_.front().exposure_start;
    }
    const auto now = std::chrono::steady_clock::now();
    start = std::min(start, now);
    // The device's clock, as GevTimestampControlLatch reads it; the host's
    // real time for the system timestamp.
    arv_buffer_set_timestamp(buffer, DeviceTime(start));
    const auto late_ns = static_cast<guint64>(std::chrono::duration_cast<std::chrono::nanoseconds>(now - start).count());
    arv_buffer_set_system_timestamp(buffer, static_cast<guint64>(RealTimeNs()) - late_ns);
    // The GVSP block ID (and ChunkFrameID): a stream opened since the last
    // frame starts at 1, as a camera's does; the fake camera sends the
    // buffer's ID, which it set from its own never-reset counter.
    if (stream_opens_.load() != stream_opens_seen_) {
      stream_opens_seen_ = stream_opens_.load();
      block_id_ = 0;
    }
    block_id_ = block_id_ % 0xffff + 1;
    arv_buffer_set_frame_id(buffer, block_id_);
    const bool first = !was_acquiring_;
    FillLocked(buffer, pixel_format);
    chunks = Applied(reg::kChunkModeActive) != 0;
    if (chunks) QueueChunks(buffer, pixel_format);
    PaceFreeRun();  // the next frame at once when its slot has passed, or frames come as fast as they are made
    // The link and GevSCPD pace the packets this thread sends next (fake_camera_hooks.h).
    PaceNextFrame(static_cast<uint16_t>(arv_buffer_get_frame_id(buffer)), link_bits_per_s_, PacketDelayNs());
    dest = (static_cast<uint64_t>(Read(kStreamDestAddress)) << 16) | (Read(kStreamPort) & 0xffff);
    if (!gv_ || !prime_first_frame_ || dest == 0 || (!first && dest == primed_dest_)) return;
    primed_dest_ = dest;
  }
  PrimeReceiver(buffer, dest, chunks);
}

void GigeDevice::QueueChunks(ArvBuffer* buffer, uint32_t pixel_format) {
  using namespace reg;
  const size_t image =
      FrameBytes(pixel_format, arv_buffer_get_image_width(buffer), arv_buffer_get_image_height(buffer));
  const size_t padded = (image + 3) / 4 * 4;  // chunk lengths are whole 4-byte words
  uint8_t tail[kMaxChunkTail] = {};
  size_t n = padded - image;  // the padding's zeros
  const auto put32 = [&](uint32_t v) {
    for (int b = 3; b >= 0; --b) tail[n++] = static_cast<uint8_t>(v >> (8 * b));
  };
  const auto put64 = [&](uint64_t v) {
    put32(static_cast<uint32_t>(v >> 32));
    put32(static_cast<uint32_t>(v));
  };
  put32(kChunkIdImage);
  put32(static_cast<uint32_t>(padded));
  for (int i = 0; i < kChunkCount; ++i) {
    if (Applied(SelectedAddress(kChunkEnable, static_cast<size_t>(i))) == 0) continue;
    switch (i) {
      case kChunkTimestamp: put64(arv_buffer_get_timestamp(buffer)); break;
      case kChunkFrameID: put64(arv_buffer_get_frame_id(buffer)); break;
      case kChunkExposureTime: put64(DoubleBits(frame_exposure_us_)); break;
      case kChunkGain: put64(DoubleBits(frame_gain_db_)); break;
      case kChunkSimFrameIndex: put64(frame_index_); break;
      case kChunkOffsetX: put64(static_cast<uint64_t>(arv_buffer_get_image_x(buffer))); break;
      case kChunkOffsetY: put64(static_cast<uint64_t>(arv_buffer_get_image_y(buffer))); break;
      case kChunkWidth: put64(static_cast<uint64_t>(arv_buffer_get_image_width(buffer))); break;
      case kChunkHeight: put64(static_cast<uint64_t>(arv_buffer_get_image_height(buffer))); break;
      case kChunkPixelFormat: put64(pixel_format); break;
      case kChunkBlackLevel: put64(DoubleBits(frame_black_level_dn_)); break;
      case kChunkLineStatusAll: put64(frame_line_status_); break;
    }
    put32(kChunkIdBase + static_cast<uint32_t>(i));
    put32(kChunkDataBytes);
  }
  // The fake camera sends packets of GevSCPSPacketSize (read after this, on this thread).
  const size_t packet_data = (Read(kPacketSize) & 0xffff) - kGvspOverheadBytes;
  SendChunksWithNextFrame(static_cast<uint16_t>(arv_buffer_get_frame_id(buffer)), image, packet_data, tail, n);
}

void GigeDevice::PrimeReceiver(ArvBuffer* buffer, uint64_t dest, bool chunks) {
  // Aravis's receiver (arvgvstream.c, 0.8.26) sets its socket buffer size
  // (the stream's socket-buffer-size) only when the first packet of a frame
  // arrives. The fake camera sends a frame as one burst right after this
  // callback, so the first frame of a stream would meet the default
  // net.core.rmem_default buffer (212992 B: about 16 packets of 9000 B) and
  // lose the rest. Sending that frame's leader now, and waiting, lets the
  // receiver grow its buffer first; the fake camera's own leader then arrives
  // as a duplicate, which receivers ignore.
  const int fd = socket(AF_INET, SOCK_DGRAM | SOCK_CLOEXEC, 0);
  if (fd < 0) return;
  sockaddr_in from{}, to{};
  from.sin_family = to.sin_family = AF_INET;
  inet_pton(AF_INET, address_.c_str(), &from.sin_addr);  // from the camera's address
  to.sin_addr.s_addr = htonl(static_cast<uint32_t>(dest >> 16));
  to.sin_port = htons(static_cast<uint16_t>(dest & 0xffff));
  uint8_t p[kGvspLeaderBytes] = {};
  auto put16 = [&](int at, uint32_t v) {
    p[at] = static_cast<uint8_t>(v >> 8);
    p[at + 1] = static_cast<uint8_t>(v);
  };
  auto put32 = [&](int at, uint32_t v) {
    put16(at, v >> 16);
    put16(at + 2, v & 0xffff);
  };
  // GVSP header (GigE Vision 1.x, standard ids): status 0, block id, then
  // packet format 1 (data leader) in the top byte of a word whose low 24 bits
  // are the packet id 0.
  put16(2, static_cast<uint32_t>(arv_buffer_get_frame_id(buffer) & 0xffff));
  p[4] = 0x01;
  // Image data leader: flags 0, payload type 1 (image; 0x4001 with chunks), 64-bit timestamp,
  // pixel format, size x/y, offset x/y, padding x/y 0 -- the values the fake
  // camera puts in its own leader.
  put16(10, chunks ? kGvspPayloadImageWithChunks : 0x0001);
  const uint64_t ts = arv_buffer_get_timestamp(buffer);
  put32(12, static_cast<uint32_t>(ts >> 32));
  put32(16, static_cast<uint32_t>(ts & 0xffffffff));
  put32(20, arv_buffer_get_image_pixel_format(buffer));
  put32(24, static_cast<uint32_t>(arv_buffer_get_image_width(buffer)));
  put32(28, static_cast<uint32_t>(arv_buffer_get_image_height(buffer)));
  put32(32, static_cast<uint32_t>(arv_buffer_get_image_x(buffer)));
  put32(36, static_cast<uint32_t>(arv_buffer_get_image_y(buffer)));
  if (bind(fd, reinterpret_cast<sockaddr*>(&from), sizeof from) == 0)
    sendto(fd, p, sizeof p, 0, reinterpret_cast<sockaddr*>(&to), sizeof to);
  close(fd);
  std::this_thread::sleep_for(std::chrono::milliseconds(kPrimeDelayMs));
}

void GigeDevice::KeepPatternCodes(int64_t pattern, bool with_rgb) {
  PatternCodes& p = pattern_codes_;
  if (p.pattern == pattern && p.width == sensor_.width && p.height == sensor_.height &&
      p.bits == sensor_.adc_bits && (p.has_rgb || !with_rgb))
    return;
  p.pattern = pattern;
  p.width = sensor_.width;
  p.height = sensor_.height;
  p.bits = sensor_.adc_bits;
  p.has_rgb = with_rgb;
  const size_t pixels = static_cast<size_t>(p.width) * p.height;
  const size_t again = pattern == kTestPatternGreyHorizontalRampMoving ? p.width - 1 : 0;
  p.raw.resize(pixels + again);
  p.rgb.resize(with_rgb ? (pixels + again) * 3 : 0);
  for (int j = 0; j < p.height; ++j)
    for (int i = 0; i < p.width; ++i) {
      const size_t at = static_cast<size_t>(j) * p.width + i;
      const uint32_t code = TestPatternCode(pattern, i, j, p.width, p.height, p.bits, 0);  // (moving: frame 0's)
      p.raw[at] = static_cast<uint16_t>(code);
      if (with_rgb) std::fill_n(&p.rgb[at * 3], 3, static_cast<uint8_t>(code >> (p.bits - 8)));  // 8..16 bits
    }
  std::copy_n(p.raw.begin(), again, p.raw.begin() + pixels);
  if (with_rgb) std::copy_n(p.rgb.begin(), again * 3, p.rgb.begin() + pixels * 3);
}

void GigeDevice::FillLocked(ArvBuffer* buffer, uint32_t pixel_format) {
  using namespace reg;
  Sync();
  if (!was_acquiring_) {
    was_acquiring_ = true;
    frames_in_acquisition_ = 0;
  }
  int64_t pulse_index = kNextIndex;
  // Line0's level as this frame's exposure starts: a triggered frame's is
  // the level its trigger left (a short pulse may have ended before the
  // rendering starts), a free-run frame's the level now.
  bool line0_high = trigger_level_.load();
  double width_us = 0;  // a TriggerWidth exposure's length
  if (Applied(kTriggerMode) == 1) {
    // This frame answers the oldest trigger; the fake camera is asked for the next one.
    std::lock_guard<std::mutex> t(trigger_mutex_);
    if (!pending_triggers_.empty()) {
      pulse_index = pending_triggers_.front().index;
      line0_high = pending_triggers_.front().line0_high;
      if (pending_triggers_.front().width)
        width_us = std::chrono::duration<double, std::micro>(pending_triggers_.front().exposure_end -
                                                             pending_triggers_.front().exposure_start)
                       .count();
      pending_triggers_.pop_front();
      trigger_requested_ = false;
      FireDueTrigger(std::chrono::steady_clock::now());  // the next, if its exposure has ended
    }
  }
  if (pulse_index != kNextIndex) {
    SetApplied(kSimFrameIndex, static_cast<uint64_t>(pulse_index));
    WriteDerived();
  }
  // The settings this frame is made with (its chunks). A TriggerWidth
  // exposure (in the core's range) is rendered by a pipeline planned for it;
  // the next frame of another exposure plans again.
  double exposure_us = width_us > 0 ? std::clamp(width_us, 1.0, 1e8) : AppliedDouble(kExposureTime);
  if (renderer_->pipeline().config().exposure.exposure_time_us != exposure_us) {
    Registers r = applied_;
    r[kExposureTime] = DoubleBits(exposure_us);
    std::string error;
    const ClientWritesHeld hold(fake_);  // Reconfigure's lock, as AutoAdjust takes it
    if (!Reconfigure(r, &error)) {  // not expected: the core takes the whole range
      LogOnce("exposure-" + error, "camsim-gige: cannot render an exposure of " + Fmt(exposure_us) + " us: " + error);
      exposure_us = renderer_->pipeline().config().exposure.exposure_time_us;
    }
  }
  frame_exposure_us_ = exposure_us;
  frame_gain_db_ = AppliedDouble(kGain);
  frame_black_level_dn_ = AppliedDouble(kBlackLevel);
  frame_index_ = Applied(kSimFrameIndex);
  frame_line_status_ = (line0_high ? 1u : 0u) | (strobe_level_ ? 2u : 0u);
  size_t size = 0;
  uint8_t* data = static_cast<uint8_t*>(const_cast<void*>(arv_buffer_get_data(buffer, &size)));
  const int w = arv_buffer_get_image_width(buffer), h = arv_buffer_get_image_height(buffer);
  const int x = arv_buffer_get_image_x(buffer), y = arv_buffer_get_image_y(buffer);
  if (static_cast<uint32_t>(w) != Applied(kWidth) || static_cast<uint32_t>(h) != Applied(kHeight) ||
      static_cast<uint32_t>(x) != Applied(kOffsetX) || static_cast<uint32_t>(y) != Applied(kOffsetY) ||
      pixel_format != Applied(kPixelFormat) || static_cast<uint64_t>(w) * h * PixelBits(pixel_format) % 8 != 0) {
    // A refused write was in the registers when the fake camera read them (or
    // a packed frame would end in half a byte): send black (the fake camera's
    // payload: its bytes rounded down).
    std::memset(data, 0, static_cast<size_t>(w) * h * PixelBits(pixel_format) / 8);
    return;
  }
  const uint32_t index = Applied(kSimFrameIndex);
  const int scene = static_cast<int>(index % scenes_.size());
  if (scene != current_scene_) {
    std::string error;
    if (!renderer_->SetScene(scenes_[static_cast<size_t>(scene)], &error))
      std::fprintf(stderr, "camsim-gige: %s\n", error.c_str());  // sizes were checked at start: not expected
    current_scene_ = scene;
  }
  const Plan& plan = renderer_->pipeline().plan();
  Tap taps[2];
  int n = 0;
  taps[n].stage = renderer_->SensorIndex();
  taps[n].format = TapFormat::kU16;
  taps[n].data = raw_.data();
  taps[n].stride = sensor_.width;
  ++n;
  if (FromIsp(pixel_format, sensor_.cfa)) {
    taps[n].stage = plan.running - 1;
    taps[n].format = TapFormat::kU8;
    taps[n].data = rgb_.data();
    taps[n].stride = static_cast<ptrdiff_t>(sensor_.width) * 3;
    ++n;
  }
  const bool strobe = strobe_ && Applied(SelectedAddress(kLineSource, 1)) == kLineSourceExposureActive;
  // (A falling edge that failed was sent again by the Sync above.)
  if (strobe) strobe_->SetEdgeIndex(index);  // a trigger bus driven by this strobe names the frame
  if (strobe) DriveStrobe(true);
  frame_line_status_ = (line0_high ? 1u : 0u) | (strobe_level_ ? 2u : 0u);  // as the frame starts
  const auto render_start = std::chrono::steady_clock::now();
  renderer_->Render(index, taps, n, nullptr);
  if (strobe) DriveStrobe(false);
  // (The applied window and format fill whole bytes: FilterClientWrite and Sync refuse others.)
  const bool reverse_x = Applied(kReverseX) != 0, reverse_y = Applied(kReverseY) != 0;
  // RGB8, BGR8, and Mono8 on a colour sensor, come from the ISP's frame; the rest from the raw codes.
  const bool from_rgb = FromIsp(pixel_format, sensor_.cfa);
  // Binning and decimation: the window is cut from the reduced readout (a copy).
  Reduction reduction;
  reduction.bin_x = static_cast<int>(Applied(kBinningHorizontal));
  reduction.bin_y = static_cast<int>(Applied(kBinningVertical));
  reduction.dec_x = static_cast<int>(Applied(kDecimationHorizontal));
  reduction.dec_y = static_cast<int>(Applied(kDecimationVertical));
  reduction.average_x = Applied(kBinningHorizontalMode) == kBinningAverage;
  reduction.average_y = Applied(kBinningVerticalMode) == kBinningAverage;
  const int factor_x = reduction.bin_x * reduction.dec_x, factor_y = reduction.bin_y * reduction.dec_y;
  uint16_t* raw = raw_.data();
  uint8_t* rgb = rgb_.data();
  // TestPattern: its codes replace the ADC's (and the ISP's RGB: R = G = B =
  // the code's top 8 bits, as the raw 8-bit formats carry it); the rendered
  // frame stays in raw_ for the Auto features.
  const int64_t pattern = Applied(kTestPattern);
  if (pattern != kTestPatternOff) {
    KeepPatternCodes(pattern, from_rgb);
    const size_t shift = pattern == kTestPatternGreyHorizontalRampMoving ? index % sensor_.width : 0;
    raw = pattern_codes_.raw.data() + shift;
    if (from_rgb) rgb = pattern_codes_.rgb.data() + shift * 3;
  }
  int stride = sensor_.width;
  if (factor_x * factor_y != 1) {
    const auto applied = [this](uint32_t r) { return applied_.at(r); };
    const int rw = ReadoutExtent(sensor_, 0, applied), rh = ReadoutExtent(sensor_, 1, applied);
    if (from_rgb) {  // per pixel and channel of the ISP's frame
      reduced_rgb_.resize(static_cast<size_t>(rw) * rh * 3);
      ReduceReadout(rgb, sensor_.width, 3, 1, reduction, 255, rw, rh, reduced_rgb_.data());
      rgb = reduced_rgb_.data();
    } else {  // per CFA cell of the raw codes (mono: per pixel), clamped at the ADC's full scale
      reduced_raw_.resize(static_cast<size_t>(rw) * rh);
      ReduceReadout(raw, sensor_.width, 1, sensor_.cfa == Cfa::kMono ? 1 : 2, reduction,
                    (1 << sensor_.adc_bits) - 1, rw, rh, reduced_raw_.data());
      raw = reduced_raw_.data();
    }
    stride = rw;
  }
  const auto mirror = [&] {
    if (from_rgb)
      MirrorWindow(rgb, static_cast<size_t>(stride), 3, x, y, w, h, reverse_x, reverse_y);
    else
      MirrorWindow(reinterpret_cast<uint8_t*>(raw), static_cast<size_t>(stride), sizeof raw[0], x, y, w, h, reverse_x,
                   reverse_y);
  };
  mirror();
  ConvertWindow(pixel_format, sensor_.cfa, sensor_.adc_bits, raw, rgb, stride, x, y, w, h, data);
  mirror();  // back: the Auto features and the kept pattern codes read as made
  last_render_s_ = std::chrono::duration<double>(std::chrono::steady_clock::now() - render_start).count();
  // (The chunks, at most kMaxChunkTail bytes, are left out.)
  last_send_s_ = FrameSendSeconds(FrameBytes(pixel_format, w, h),
                                  Read(kPacketSize) & 0xffff, link_bits_per_s_, PacketDelayNs());

  // Mean raw level in the window, for the Auto features.
  // (With binning or decimation: the sensor's pixels the window covers.)
  const int sx = x * factor_x, sy = y * factor_y, sw = w * factor_x, sh = h * factor_y;
  if (Applied(kExposureAuto) != kAutoOff || Applied(kGainAuto) != kAutoOff) {
    uint64_t sum = 0;
    for (int r = 0; r < sh; ++r)
      for (int i = 0; i < sw; ++i) sum += raw_[static_cast<size_t>(sy + r) * sensor_.width + sx + i];
    const double black = AppliedDouble(kBlackLevel), full = (1 << sensor_.adc_bits) - 1;
    AutoAdjust((static_cast<double>(sum) / (static_cast<double>(sw) * sh) - black) / (full - black));
  }
  if (sensor_.has_white_balance && Applied(kBalanceWhiteAuto) != kAutoOff) BalanceWhite(sx, sy, sw, sh);
  SetApplied(kSimFrameIndex, (index + 1) & 0x7fffffff);
  WriteDerived();
  ++frames_in_acquisition_;
  const uint32_t mode = Applied(kAcquisitionMode);
  if ((mode == kSingleFrame && frames_in_acquisition_ >= 1) ||
      (mode == kMultiFrame && frames_in_acquisition_ >= Applied(kAcquisitionFrameCount)))
    Write(kAcquisition, 0);
  ++frames_sent_;
}

std::vector<const Feature*> GigeDevice::UserSetRegisters() const {
  std::vector<const Feature*> out;
  for (const Feature& f : registers_) {
    if (!Checked(f)) continue;
    const std::string base = f.name.substr(0, f.name.find('['));
    for (const char* name : kUserSetFeatures)
      if (base == name) out.push_back(&f);
  }
  return out;
}

GigeDevice::Registers GigeDevice::UserSetNow() const {
  Registers r;
  for (const Feature* f : UserSetRegisters()) r[f->address] = ReadFeature(*f);
  return r;
}

void GigeDevice::RestoreRegisters(const Registers& r) {
  for (const auto& [address, v] : r)
    for (const Feature& f : registers_)
      if (f.address == address && f.alias_of.empty() && Checked(f)) WriteFeature(f, v);
  WriteReadoutMax();
}

GevStatus GigeDevice::LoadUserSet(int64_t set, std::string* why) {
  using namespace reg;
  if (set < 0 || set >= kUserSetCount) {
    *why = "no such user set";
    return GevStatus::kInvalidParameter;
  }
  const Registers& v = user_sets_[set].values;
  // The writes, in order: (address, value) of one feature, or of the two
  // halves of an Auto limit pair (lower, upper: one 16-byte block, so the
  // pair never crosses on the way).
  struct Step {
    uint32_t address;
    std::vector<std::pair<const Feature*, uint64_t>> values;
  };
  std::vector<Step> steps;
  const auto feature = [this](uint32_t address) -> const Feature* {
    for (const Feature& f : registers_)
      if (f.address == address && f.alias_of.empty() && Checked(f)) return &f;
    return nullptr;
  };
  const auto add = [&](uint32_t address, uint64_t value) {
    if (const Feature* f = feature(address)) steps.push_back({address, {{f, value}}});
  };
  const auto has = [&](uint32_t address) { return v.count(address) != 0; };
  // ExposureMode Timed and the Auto features Off (TriggerWidth locks the
  // trigger and ExposureAuto; the loop would own what the set writes).
  if (has(kExposureMode)) add(kExposureMode, kExposureTimed);
  // LineDebouncerTime is written at LineSelector Line0 (where it is
  // available); the client's selector is put back last.
  const uint64_t line_selector = Read(kLineSelector);
  if (has(kLineDebouncerTime)) add(kLineSelector, 0);
  for (const uint32_t a : {kExposureAuto, kGainAuto, kBalanceWhiteAuto})
    if (has(a)) add(a, kAutoOff);
  // Gamma is available with GammaEnable on: on while the set's Gamma is
  // written, then the set's GammaEnable.
  if (has(kGamma)) add(kGammaEnable, 1);
  // The sensor's own readout and raw format: valid in any window with any stages.
  add(kReverseX, 0);
  add(kReverseY, 0);
  for (const uint32_t a : kReductionRegisters)  // factors 1 (Sum for the modes)
    add(a, a == kBinningHorizontalMode || a == kBinningVerticalMode ? uint64_t{kBinningSum} : uint64_t{1});
  add(kPixelFormat, static_cast<uint64_t>(FindFeature(table_, "PixelFormat")->entries[0].value));
  for (const auto& [a, x] : v)
    if (a >= kSimStageEnable && a < SelectedAddress(kSimStageEnable, kStageCount)) add(a, x);
  // The window: offsets 0, then the size, then the offsets (as arv_camera_set_region).
  add(kOffsetX, 0);
  add(kOffsetY, 0);
  // (Binning and decimation before the window: they set WidthMax and HeightMax.)
  for (const uint32_t a : kReductionRegisters)
    if (has(a)) add(a, v.at(a));
  for (const uint32_t a : {kWidth, kHeight, kOffsetX, kOffsetY, kReverseX, kReverseY, kPixelFormat})
    if (has(a)) add(a, v.at(a));
  std::set<uint32_t> done = {kWidth, kHeight, kOffsetX, kOffsetY, kReverseX, kReverseY, kPixelFormat,
                             kExposureAuto, kGainAuto, kBalanceWhiteAuto, kExposureMode, kGammaEnable};
  done.insert(std::begin(kReductionRegisters), std::end(kReductionRegisters));
  for (const auto& [a, x] : v) {
    if (done.count(a) || (a >= kSimStageEnable && a < SelectedAddress(kSimStageEnable, kStageCount))) continue;
    bool limit = false;
    for (const AutoLimits& l : kAutoLimits) {
      limit = limit || a == l.lower || a == l.upper;
      if (a == l.lower && has(l.upper))
        steps.push_back({l.lower, {{feature(l.lower), x}, {feature(l.upper), v.at(l.upper)}}});
    }
    if (!limit) add(a, x);
  }
  for (const uint32_t a : {kExposureAuto, kGainAuto, kBalanceWhiteAuto, kExposureMode, kGammaEnable})
    if (has(a)) add(a, v.at(a));
  if (has(kLineDebouncerTime)) add(kLineSelector, line_selector);

  Registers before = UserSetNow();
  before[kGainRaw] = Read(kGainRaw);
  const uint64_t refused_before = writes_refused_.load();
  refusal_capture_ = why;
  why->clear();
  GevStatus status = GevStatus::kSuccess;
  for (const Step& step : steps) {
    std::vector<uint8_t> bytes;
    for (const auto& [f, x] : step.values)
      for (uint32_t b = 0; b < f->length; ++b) bytes.push_back(static_cast<uint8_t>(x >> (8 * (f->length - 1 - b))));
    const WriteVerdict verdict = FilterClientWrite(this, step.address, static_cast<uint32_t>(bytes.size()), bytes.data());
    if (verdict.store) {
      DeviceWrites own;
      arv_fake_camera_write_memory(fake_, step.address, static_cast<guint32>(bytes.size()), bytes.data());
    }
    if (verdict.status != GevStatus::kSuccess) {
      status = verdict.status;
      break;
    }
  }
  refusal_capture_ = nullptr;
  writes_refused_ = refused_before;  // the load is one write (its caller counts it)
  if (status != GevStatus::kSuccess) {
    RestoreRegisters(before);
    Write(kLineSelector, static_cast<uint32_t>(line_selector));
    *why += " (nothing of the set is loaded)";
  }
  return status;
}

std::string GigeDevice::UserSetValueText(const Feature& f, uint64_t v) const {
  switch (f.kind) {
    case Kind::kFloat: {
      char buf[40];
      std::snprintf(buf, sizeof buf, "%.17g", BitsDouble(v));
      return buf;
    }
    case Kind::kEnum:
      for (const EnumEntry& e : TableFeature(table_, f).entries)
        if (static_cast<uint64_t>(e.value) == v) return e.name;
      return std::to_string(v);
    default: return std::to_string(v);
  }
}

bool GigeDevice::WriteUserSetFile(uint64_t default_set, std::string* error) const {
  std::string text = "# camsim-gige user sets (UserSetSave); UserSetDefault is loaded at start\n";
  text += "UserSetDefault = " + std::string(UserSetName(static_cast<int64_t>(default_set))) + "\n";
  for (int64_t i = 1; i < kUserSetCount; ++i) {
    if (!user_sets_[i].saved) continue;
    text += std::string("\n[") + UserSetName(i) + "]\n";
    for (const Feature* f : UserSetRegisters())
      text += RegisterName(*f) + " = " + UserSetValueText(*f, user_sets_[i].values.at(f->address)) + "\n";
  }
  // WriteTextFile writes a temporary file beside it and renames it over it:
  // a reader sees the old file or the new.
  std::string why;
  if (!io::WriteTextFile(user_set_file_, text, &why)) {
    *error = "the user set file: " + why;
    return false;
  }
  return true;
}

bool GigeDevice::ReadUserSetFile(std::string* error) {
  const std::string& path = user_set_file_;
  std::ifstream in(path);
  if (!in) {
    if (errno == ENOENT) {  // none yet: the first UserSetSave writes it
      start_user_set_ = "the Default user set (no " + path + " yet)";
      return true;
    }
    *error = "--user-set-file " + path + ": cannot read it: " + std::strerror(errno);
    return false;
  }
  std::map<std::string, const Feature*> by_name;
  for (const Feature* f : UserSetRegisters()) by_name[RegisterName(*f)] = f;
  const auto trim = [](std::string t) {
    const size_t a = t.find_first_not_of(" \t\r"), b = t.find_last_not_of(" \t\r");
    return a == std::string::npos ? std::string() : t.substr(a, b - a + 1);
  };
  const auto fail = [&](int line, const std::string& why) {
    *error = "--user-set-file " + path + ":" + std::to_string(line) + ": " + why;
    return false;
  };
  int64_t set = -1, default_set = kUserSetDefaultSet;
  bool default_named = false;  // a UserSetDefault line was read
  std::map<uint32_t, int> lines[kUserSetCount];  // each set's registers given, and their lines
  std::string text;
  for (int n = 1; std::getline(in, text); ++n) {
    const std::string t = trim(text);
    if (t.empty() || t[0] == '#') continue;
    if (t.front() == '[') {
      const std::string name = t.back() == ']' ? t.substr(1, t.size() - 2) : "";
      set = -1;
      for (int64_t i = 1; i < kUserSetCount; ++i)
        if (name == UserSetName(i)) set = i;
      if (name == UserSetName(kUserSetDefaultSet))
        return fail(n, "[Default] is the start-up configuration, not a user set (UserSet1, UserSet2, UserSet3)");
      if (set < 0) return fail(n, "unknown section '" + t + "' (UserSet1, UserSet2, UserSet3)");
      if (user_sets_[set].saved) return fail(n, "[" + name + "] given twice");
      user_sets_[set].saved = true;
      continue;
    }
    const size_t eq = t.find('=');
    if (eq == std::string::npos) return fail(n, "expected 'Feature = value', not '" + t + "'");
    const std::string name = trim(t.substr(0, eq)), value = trim(t.substr(eq + 1));
    if (set < 0) {
      if (name != "UserSetDefault") return fail(n, "'" + name + "' before a [UserSetN] section (only UserSetDefault goes there)");
      default_set = -1;
      default_named = true;
      for (int64_t i = 0; i < kUserSetCount; ++i)
        if (value == UserSetName(i)) default_set = i;
      if (default_set < 0) return fail(n, "UserSetDefault = " + value + ": no such set (Default, UserSet1, UserSet2, UserSet3)");
      continue;
    }
    const auto it = by_name.find(name);
    if (it == by_name.end()) return fail(n, "unknown feature '" + name + "' (not one a user set of this device holds)");
    const Feature& f = *it->second;
    if (lines[set].count(f.address)) return fail(n, name + " given twice");
    uint64_t v = 0;
    bool parsed = false;
    char* end = nullptr;
    errno = 0;
    if (f.kind == Kind::kFloat) {
      const double x = std::strtod(value.c_str(), &end);
      parsed = !value.empty() && *end == '\0' && errno == 0;
      v = DoubleBits(x);
    } else if (f.kind == Kind::kEnum) {
      for (const EnumEntry& e : TableFeature(table_, f).entries)
        if (e.name == value) {
          v = static_cast<uint64_t>(e.value);
          parsed = true;
        }
      if (!parsed) return fail(n, name + " = " + value + ": no such entry");
    } else if (f.kind == Kind::kBoolean && (value == "true" || value == "false")) {
      v = value == "true";
      parsed = true;
    } else {
      const long long x = std::strtoll(value.c_str(), &end, 10);
      parsed = !value.empty() && *end == '\0' && errno == 0 && x >= 0;
      v = static_cast<uint64_t>(x);
    }
    if (!parsed) return fail(n, name + " = " + value + ": not a number");
    user_sets_[set].values[f.address] = v;
    lines[set][f.address] = n;
  }
  if (in.bad()) return fail(0, std::string("cannot read it: ") + std::strerror(errno));
  // Each value in its feature's range (PixelFormat: in the set's readout),
  // then the whole set through the client's checks by a trial load.
  for (int64_t i = 1; i < kUserSetCount; ++i) {
    if (!user_sets_[i].saved) continue;
    Registers& values = user_sets_[i].values;
    const int readout = static_cast<int>((values.at(reg::kReverseX) & 1) | (values.at(reg::kReverseY) & 1) << 1);
    for (const auto& [address, line] : lines[i]) {
      const Feature* f = nullptr;
      for (const auto& kv : by_name)
        if (kv.second->address == address) f = kv.second;
      if (!Valid(*f, values.at(address), readout)) {
        std::string why = WhyInvalid(*f, values.at(address));
        if (why.empty()) why = "not the phase of the set's readout (ReverseX, ReverseY)";
        return fail(line, RegisterName(*f) + " = " + UserSetValueText(*f, values.at(address)) + ": " + why);
      }
    }
    const Registers before = UserSetNow();
    const uint64_t gain_raw = Read(reg::kGainRaw);
    std::string why;
    const bool loaded = LoadUserSet(i, &why) == GevStatus::kSuccess;
    RestoreRegisters(before);
    Write(reg::kGainRaw, static_cast<uint32_t>(gain_raw));
    if (!loaded) {
      *error = "--user-set-file " + path + ": [" + UserSetName(i) + "]: " + why;
      return false;
    }
  }
  SetApplied(reg::kUserSetDefault, static_cast<uint64_t>(default_set));
  SetApplied(reg::kUserSetSelector, static_cast<uint64_t>(default_set));
  if (default_set != kUserSetDefaultSet) {
    std::string why;
    if (LoadUserSet(default_set, &why) != GevStatus::kSuccess) {
      *error = "--user-set-file " + path + ": UserSetDefault " + UserSetName(default_set) + ": " + why;
      return false;
    }
  }
  start_user_set_ = default_set != kUserSetDefaultSet
                        ? "user set " + std::string(UserSetName(default_set)) + " from " + path + " (its UserSetDefault)"
                    : default_named ? "the Default user set (UserSetDefault is Default in " + path + ")"
                                    : "the Default user set (" + path + " names no UserSetDefault)";
  return true;
}

}  // namespace camsim::genicam
