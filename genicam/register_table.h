// The register map of the emulated GigE Vision camera: one table from which
// the GenICam XML is generated (GenerateXml) and which the device uses to
// read, check and refuse register writes (genicam/device.cc).
//
// Addresses: the GigE Vision bootstrap registers (strings at 0x48..0xf7,
// packet size at 0xd04), the registers Aravis's fake camera itself acts on
// (0x100..0x138: geometry, pixel format, acquisition, GainRaw; 0x300..0x30c:
// its trigger), and camsim's own registers from 0x8000 (inside the fake
// camera's 64 KiB register memory). Registers are big-endian; Float features
// are 8-byte IEEE doubles.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "core/pipeline/stage.h"

namespace camsim::genicam {

// kSwissKnife: a read-only integer the client computes from other registers (no address).
enum class Kind : uint8_t { kInteger, kFloat, kEnum, kBoolean, kCommand, kString, kSwissKnife };

struct EnumEntry {
  std::string name;
  int64_t value;
  // >= 0: the entry is available only while the feature's selector has this
  // value (GenICam pIsAvailable; the device refuses it otherwise).
  int64_t only_at_selection = -1;
  // false: never available on this device (GenICam pIsAvailable 0; the
  // device refuses it), e.g. Line0 as TriggerSource without a trigger line.
  bool available = true;
  // >= 0: available only while ReverseX + 2 * ReverseY equals it: a Bayer
  // format of the CFA phase that readout gives (GenICam pIsAvailable).
  int readout = -1;
  // Nonempty: available only while this formula over `variables` (variable,
  // feature) is nonzero (GenICam pIsAvailable, an IntSwissKnife); the device
  // checks it itself (e.g. ExposureMode TriggerWidth).
  std::string available_formula{};
  std::vector<std::pair<std::string, std::string>> variables{};
};

struct Feature {
  std::string name;
  std::string category;
  std::string description;
  Kind kind = Kind::kInteger;
  uint32_t address = 0;
  uint32_t length = 4;
  bool writable = false;
  double min = 0, max = 0, inc = 1;  // Integer and Float ranges (inclusive); increment (a Float's: 0 none)
  std::string unit;
  std::vector<EnumEntry> entries;    // Enumeration entries
  int64_t command_value = 1;         // Command
  std::string alias_of;              // another feature sharing this register (same checks)
  std::string formula;               // kSwissKnife: formula over the variables
  std::vector<std::pair<std::string, std::string>> variables;  // (variable, feature) of the formulas
  // kInteger: a maximum that follows other registers (GenICam pMax, an
  // IntSwissKnife over `variables`); `max` stays the largest it can be.
  std::string max_formula;
  // kFloat: a minimum or maximum that is another Float feature's value
  // (GenICam pMin / pMax, naming its register); `min` / `max` stay the widest
  // it can be.
  std::string min_feature, max_feature;
  // A selected feature has one register per value of its selector, at
  // address + length * value (GenICam pIndex): a write never depends on the
  // selector the device last saw, so Selector-then-value writes cannot race.
  std::string selected_by;
  int selections = 1;
  // FeatureRegisters' register of one selection: the selector's value it is
  // at (selected_by stays the selector's name); -1 otherwise.
  int selection = -1;
  // kInteger, kBoolean: the value is `low_bits` bits of the register from
  // bit `shift` up (a GenICam MaskedIntReg; writes keep the other bits); 0:
  // the whole register.
  int low_bits = 0;
  int shift = 0;
  // Nonzero: the value is not in device memory but in the chunk of this ID
  // in each frame (GenICam Port with ChunkID), at `address` in it; read-only.
  uint32_t chunk_id = 0;
  // kEnum, a selector: the features it selects (GenICam pSelected).
  std::vector<std::string> selects;
  // Nonempty: the feature is available only while this formula over
  // `variables` is nonzero (GenICam pIsAvailable, an IntSwissKnife); the
  // device refuses it otherwise (e.g. TriggerSoftware outside trigger mode).
  std::string available_formula;
  // Locked (GenICam pIsLocked: not writable) during an acquisition or while
  // TLParamsLocked is 1, as the device then refuses writes (the payload).
  bool locked_while_acquiring = false;
  // (A feature has at most one of available_formula, locked_formula and
  // locked_while_acquiring: the two formulas share `variables`.)
  // Nonempty (and not locked_while_acquiring): locked while this formula
  // over `variables` is nonzero (pIsLocked, an IntSwissKnife); the device
  // refuses a change then, e.g. ExposureTime while ExposureAuto is not Off
  // or ExposureMode is TriggerWidth.
  std::string locked_formula;
};

// Register addresses (named once, used by the table, the device and the tests).
namespace reg {
inline constexpr uint32_t kVendorName = 0x48, kModelName = 0x68, kDeviceVersion = 0x88, kManufacturerInfo = 0xa8,
                          kSerialNumber = 0xd8, kUserId = 0xe8;  // GigE Vision bootstrap strings
inline constexpr uint32_t kPacketSize = 0xd04;                    // bootstrap SCPS0
// Bootstrap SCPD0: the delay after each stream packet (GevSCPD), in ticks
// of the timestamp clock, whose frequency (Hz) is the 64-bit value at
// 0x093c (high word) and 0x0940 (low word): 1e9 in Aravis's fake camera, so
// one tick is 1 ns.
inline constexpr uint32_t kPacketDelay = 0xd08, kTickFrequencyHigh = 0x093c, kTickFrequencyLow = 0x0940;
// GigE Vision bootstrap, read-only to clients: device mode (bit 31:
// big-endian registers; low 16 bits: the strings' character set) and the
// GVCP capabilities the device has.
inline constexpr uint32_t kDeviceMode = 0x0004, kGvcpCapability = 0x0934;
inline constexpr uint32_t kDeviceModeBigEndianUtf8 = 0x80000001u;
inline constexpr uint32_t kCapabilityUserName = 1u << 31, kCapabilitySerialNumber = 1u << 30,
                          kCapabilityWriteMem = 1u << 1, kCapabilityPacketResend = 1u << 2;
// GigE Vision bootstrap: heartbeat timeout (ms), control channel privilege
// (0 = no controlling client), stream channel 0 port (low 16 bits) and destination address.
inline constexpr uint32_t kHeartbeatTimeout = 0x0938, kControlChannelPrivilege = 0x0a00, kStreamPort = 0x0d00,
                          kStreamDestAddress = 0x0d18;
// GigE Vision bootstrap, the transport layer's identity and clock: version
// (major in the high 16 bits, minor in the low), MAC address (high register:
// its first 2 bytes in the low 16 bits; low register: the other 4), the IPv4
// address, stream channels, timestamp tick frequency (Hz, 64 bits: high
// then low register), timestamp control (write-only bits: latch, reset)
// and the latched timestamp (64 bits).
inline constexpr uint32_t kVersion = 0x0000, kMacHigh = 0x0008, kMacLow = 0x000c, kCurrentIp = 0x0024,
                          kStreamChannelCount = 0x0904, kTimestampTickFrequency = 0x093c,
                          kTimestampControl = 0x0944, kTimestampValue = 0x0948;
inline constexpr uint32_t kGigeVisionVersion = 0x00020000u;  // 2.0
inline constexpr uint32_t kTimestampReset = 1u << 0, kTimestampLatch = 1u << 1;
inline constexpr uint64_t kTimestampTicksPerSecond = 1000000000u;  // ns
// Registers Aravis's fake camera reads (arvfakecamera.h).
inline constexpr uint32_t kWidth = 0x100, kHeight = 0x104, kGainRaw = 0x110, kGainAuto = 0x114,
                          kSensorHeight = 0x118, kSensorWidth = 0x11c, kFakeExposureUs = 0x120,
                          kAcquisition = 0x124, kPixelFormat = 0x128, kAcquisitionMode = 0x12c, kOffsetX = 0x130,
                          kOffsetY = 0x134, kFakeFramePeriodUs = 0x138, kFakeTriggerMode = 0x300,
                          kFakeTriggerSource = 0x304, kFakeTriggerActivation = 0x308, kFakeTriggerSoftware = 0x30c;
// camsim's own registers (kWidthMax is the first).
inline constexpr uint32_t kWidthMax = 0x8000, kHeightMax = 0x8004, kAcquisitionFrameCount = 0x8008,
                          kAcquisitionFrameRate = 0x8010, kAcquisitionFrameRateEnable = 0x8018,
                          kExposureTime = 0x8020, kExposureAuto = 0x8028, kTriggerSelector = 0x8030,
                          kTriggerMode = 0x8034, kTriggerSource = 0x8038, kTriggerActivation = 0x803c,
                          kTriggerSoftware = 0x8040, kGain = 0x8048, kBlackLevel = 0x8050, kLineSelector = 0x8060,
                          kSimSceneFrame = 0x8080,
                          kSimFrameIndex = 0x8084, kSimFNumber = 0x8088, kSimSeed = 0x8090,
                          kSimStageSelector = 0x8094, kTLParamsLocked = 0x80a0, kSimSceneCount = 0x80a4,
                          kSimAutoTarget = 0x80a8, kSimSyncCount = 0x80b0, kSimFocusDistance = 0x80c0,
                          kAcquisitionResultingFrameRate = 0x80c8, kAutoExposureTimeLowerLimit = 0x80d0,
                          kAutoExposureTimeUpperLimit = 0x80d8, kAutoGainLowerLimit = 0x80e0,
                          kAutoGainUpperLimit = 0x80e8, kChunkModeActive = 0x80f0, kChunkSelector = 0x80f4;
// SimFocusDistance's range (metres): the core takes up to 1e6 m, and more
// than the focal length (checked when the pipeline is planned).
inline constexpr double kMinFocusDistanceM = 0.001, kMaxFocusDistanceM = 1e6;
// AcquisitionStart, AcquisitionStop and AcquisitionAbort: command registers
// in front of the fake camera's acquisition register that read back 0
// (GigeDevice::FilterClientWrite).
inline constexpr uint32_t kAcquisitionStart = 0x80b4, kAcquisitionStop = 0x80b8, kAcquisitionAbort = 0x80bc;
// Selected features (Feature::selected_by): the register of selector value
// v is at SelectedAddress(base, v). LineMode, LineSource and LineStatus: one
// per line (LineSelector: 2); SimStageEnable: one per configured stage
// (SimStageSelector: kStageCount at most).
inline constexpr uint32_t kLineMode = 0x8064, kLineSource = 0x806c, kLineStatus = 0x8074, kSimStageEnable = 0x8100;
// ChunkEnable: one per chunk (ChunkSelector: kChunkCount), after SimStageEnable's kStageCount.
inline constexpr uint32_t kChunkEnable = 0x8180;
// White balance (SFNC AnalogControl). BalanceRatio: one 8-byte Float per
// BalanceRatioSelector value (Red, Green, Blue), at kBalanceRatio + 8 * value.
inline constexpr uint32_t kBalanceRatioSelector = 0x8400, kBalanceWhiteAuto = 0x8404, kBalanceRatio = 0x8410;
// ReverseX, ReverseY (SFNC ImageFormatControl): the sensor's readout mirrored.
inline constexpr uint32_t kReverseX = 0x8408, kReverseY = 0x840c;
// TriggerDelay (SFNC AcquisitionControl, under TriggerSelector FrameStart): an 8-byte Float, us.
inline constexpr uint32_t kTriggerDelay = 0x8430;
// TriggerDelay's maximum (us): 10 s.
inline constexpr double kMaxTriggerDelayUs = 1e7;
// DeviceTemperatureSelector (one entry, Sensor) and DeviceTemperature (SFNC
// DeviceControl): the sensor's configured temperature (sensor.temperature_c),
// an 8-byte Float, read-only; its range is the core's (core/sensor/emva.cc).
inline constexpr uint32_t kDeviceTemperatureSelector = 0x8438, kDeviceTemperature = 0x8440;
inline constexpr double kMinSensorTemperatureC = -100.0, kMaxSensorTemperatureC = 150.0;
// Gamma (SFNC AnalogControl: Y' = Y^Gamma, an 8-byte Float) and GammaEnable
// (on: the ISP's gamma stage encodes Y^Gamma, its power curve of gamma 1 /
// Gamma; off: the configured [gamma] curve). Gamma's range is the core's
// gamma range (core/isp/gamma.h), which 1 / x maps onto itself.
inline constexpr uint32_t kGamma = 0x8448, kGammaEnable = 0x8450;
inline constexpr double kMinGamma = 0.1, kMaxGamma = 10.0;
// UserSetControl (SFNC): UserSetSelector, the UserSetLoad and UserSetSave
// command registers (read back 0), and UserSetDefault (the set loaded at start).
inline constexpr uint32_t kUserSetSelector = 0x8460, kUserSetLoad = 0x8464, kUserSetSave = 0x8468,
                          kUserSetDefault = 0x846c;
// ExposureMode (SFNC AcquisitionControl): ExposureModeValue.
inline constexpr uint32_t kExposureMode = 0x8620;
// LineInverter (SFNC DigitalIOControl): one per line (LineSelector), as
// LineMode. LineDebouncerTime: the input Line0's (one register, available
// at LineSelector Line0), an 8-byte Float, us, 0 .. kMaxLineDebouncerTimeUs.
inline constexpr uint32_t kLineInverter = 0x8600, kLineDebouncerTime = 0x8610;
inline constexpr double kMaxLineDebouncerTimeUs = 1e6;
// Binning and decimation (SFNC ImageFormatControl): the readout reduced
// before the window. Factors 1 .. kMaxReduction per axis; BinningHorizontalMode /
// BinningVerticalMode: Sum or Average (BinningModeValue).
inline constexpr uint32_t kBinningHorizontal = 0x8500, kBinningVertical = 0x8504, kBinningHorizontalMode = 0x8508,
                          kBinningVerticalMode = 0x850c, kDecimationHorizontal = 0x8510, kDecimationVertical = 0x8514;
inline constexpr int kMaxReduction = 4;
// TestPatternGeneratorSelector (one entry, Sensor) and TestPattern (SFNC
// ImageFormatControl): TestPatternValue.
inline constexpr uint32_t kTestPatternGeneratorSelector = 0x8520, kTestPattern = 0x8524;
// A selected feature's register of selector value `value`: one register of
// `length` bytes (4, a Float's 8) per value.
inline constexpr uint32_t SelectedAddress(uint32_t base, size_t value, uint32_t length = 4) {
  return base + length * static_cast<uint32_t>(value);
}
}  // namespace reg

// GigE Vision chunk mode (ChunkModeActive): the payload is the image padded
// to 4 bytes, its tag, then each enabled chunk: 8 bytes of big-endian data
// and its tag. A tag is the chunk's ID and data length, 4 bytes each,
// big-endian, after the data (receivers find chunks from the end).
// ChunkSelector values; each chunk's ID is kChunkIdBase + its value.
// The window, format and black level are the frame's own (SFNC's chunks of
// the same names), so a client need not read registers that may have changed.
enum ChunkSelectorValue : int64_t {
  kChunkTimestamp = 0,       // uint64: the frame's timestamp (ns; the GVSP leader's)
  kChunkFrameID = 1,         // uint64: the GVSP block ID
  kChunkExposureTime = 2,    // double: the exposure the frame was rendered with (us)
  kChunkGain = 3,            // double: its gain (dB)
  kChunkSimFrameIndex = 4,   // uint64: the frame index keying scene and noise (`camsim run --first-frame`)
  kChunkOffsetX = 5,         // uint64: the frame's window on the sensor
  kChunkOffsetY = 6,
  kChunkWidth = 7,
  kChunkHeight = 8,
  kChunkPixelFormat = 9,     // uint64: its PFNC code (an Enumeration of PixelFormat's entries)
  kChunkBlackLevel = 10,     // double: the black level it was rendered with (DN)
  kChunkLineStatusAll = 11,  // uint64: bit i = line i's level as the frame started (Line1: the strobe as driven for it)
  kChunkCount = 12
};
inline constexpr uint32_t kChunkIdImage = 0xC5A00000u, kChunkIdBase = 0xC5A00001u;
inline constexpr uint32_t kChunkDataBytes = 8, kChunkTagBytes = 8;

// UserSetSelector and UserSetDefault values: Default is the start-up
// configuration (read-only), UserSet1..3 the sets a client saves.
enum UserSetValue : int64_t { kUserSetDefaultSet = 0, kUserSetCount = 4 };
inline const char* UserSetName(int64_t set) {
  static const char* const names[kUserSetCount] = {"Default", "UserSet1", "UserSet2", "UserSet3"};
  return set >= 0 && set < kUserSetCount ? names[set] : "?";
}

// BalanceRatioSelector values: the white balance stage's gains (core/isp/white_balance.h).
enum BalanceRatioSelectorValue : int64_t { kBalanceRed = 0, kBalanceGreen = 1, kBalanceBlue = 2, kBalanceCount = 3 };
// BalanceRatio's range: the white balance stage's gains.
inline constexpr double kMaxBalanceRatio = 16.0;

// The pixels of an axis of `sensor` pixels read out with binning `bin` and
// decimation `dec`: sensor / (bin x dec), rounded down to the CFA's `step`
// (a Bayer readout keeps whole 2x2 cells). WidthMax and HeightMax.
inline int ReducedExtent(int sensor, int step, int bin, int dec) { return sensor / (bin * dec * step) * step; }
enum BinningModeValue : int64_t { kBinningSum = 0, kBinningAverage = 1 };
// TestPattern values: Off is the modelled image; the others replace the
// ADC's codes (TestPatternCode).
enum TestPatternValue : int64_t {
  kTestPatternOff = 0,
  kTestPatternBlack = 1,
  kTestPatternWhite = 2,
  kTestPatternGreyHorizontalRamp = 3,
  kTestPatternGreyVerticalRamp = 4,
  kTestPatternGreyDiagonalRamp = 5,
  kTestPatternGreyHorizontalRampMoving = 6
};
// A test pattern's code at sensor pixel (x, y) of a width x height sensor
// with a `bits`-bit ADC (full scale M = 2^bits - 1) in frame `frame_index`:
// Black 0, White M; a ramp r(t, n) = round(t x M / (n - 1)), half up (0 when
// n is 1): GreyHorizontalRamp r(x, width), GreyVerticalRamp r(y, height),
// GreyDiagonalRamp r(x + y, width + height - 1); GreyHorizontalRampMoving
// r((x + frame_index) mod width, width): the ramp moves one pixel left per frame.
uint32_t TestPatternCode(int64_t pattern, int x, int y, int width, int height, int bits, uint64_t frame_index);

// Enumeration values of camsim's own enum registers.
enum AcquisitionModeValue : int64_t { kContinuous = 0, kSingleFrame = 1, kMultiFrame = 2 };
enum AutoValue : int64_t { kAutoOff = 0, kAutoOnce = 1, kAutoContinuous = 2 };
enum TriggerSourceValue : int64_t { kSourceSoftware = 0, kSourceLine0 = 1 };
enum LineSourceValue : int64_t { kLineSourceOff = 0, kLineSourceExposureActive = 1 };
enum ExposureModeValue : int64_t { kExposureTimed = 0, kExposureTriggerWidth = 1 };

// PFNC pixel format codes (GigE Vision values).
inline constexpr uint32_t kMono8 = 0x01080001, kMono10 = 0x01100003, kMono12 = 0x01100005, kMono16 = 0x01100007,
                          kRGB8 = 0x02180014, kBGR8 = 0x02180015;  // BGR8: RGB8 with R and B swapped
// 4:2:2, 8 bits, made from RGB8 (full-range BT.601; see ConvertWindow): Y Cb Y Cr, Y U Y V, U Y V Y.
inline constexpr uint32_t kYCbCr422_8 = 0x0210003b, kYUV422_8 = 0x02100032, kYUV422_8_UYVY = 0x0210001f;
inline bool Is422(uint32_t code) { return code == kYCbCr422_8 || code == kYUV422_8 || code == kYUV422_8_UYVY; }
// Packed: PFNC Mono10p and Mono12p; GigE Vision 1.x Mono12Packed.
inline constexpr uint32_t kMono10p = 0x010a0046, kMono12p = 0x010c0047, kMono12Packed = 0x010c0006;
// Bayer<phase><bits>; bits 8, 10, 12 or 16 (10, 12 unpacked: one 16-bit word per sample).
uint32_t BayerCode(Cfa cfa, int bits);
// The CFA phase a readout gives: mirrored columns (ReverseX) swap RG and GR,
// GB and BG; mirrored rows (ReverseY) swap RG and GB, GR and BG (even widths
// and heights). Mono stays mono.
Cfa ReadoutCfa(Cfa sensor, bool reverse_x, bool reverse_y);
// The format a sensor read out as `readout` (ReverseX + 2 * ReverseY) sends
// at the depth of `code`: a Bayer code (of any phase) becomes the phase that
// readout gives; RGB8 and Mono codes stay.
uint32_t ReadoutFormat(uint32_t code, Cfa sensor, int readout);
// How a raw format packs its samples: one per byte or 16-bit word (kNone);
// PFNC "p" (the frame's samples as one LSB-first bit stream); GigE Vision's
// legacy 12Packed (two samples in 3 bytes: high 8 bits of the first, both
// low nibbles (first's in bits 0..3), high 8 bits of the second).
enum class Packing { kNone, kPfnc, kGigeLegacy };
// The packed raw format of a sensor: Mono or Bayer<phase>, bits 10 (kPfnc
// only) or 12; 0 when there is none.
uint32_t PackedCode(Cfa cfa, int bits, Packing packing);
Packing PackingOf(uint32_t code);
// Bits per pixel of a code (its bits 16..23), 0 when unknown.
inline int PixelBits(uint32_t code) { return static_cast<int>((code >> 16) & 0xff); }
// Significant bits per sample: 10 or 12 for the unpacked 10- and 12-bit formats, else PixelBits (per channel for RGB8, BGR8, 4:2:2).
int SampleBits(uint32_t code);
// Formats made from the ISP's RGB8: RGB8, BGR8, the 4:2:2 ones, and Mono8 on a colour sensor (its luma).
inline bool FromIsp(uint32_t code, Cfa cfa) {
  return code == kRGB8 || code == kBGR8 || Is422(code) || (code == kMono8 && cfa != Cfa::kMono);
}
// Bytes of a w x h frame: a packed frame is one bit stream, so its bits
// need not end on a byte (GigeDevice refuses such windows).
inline uint64_t FrameBytes(uint32_t code, int w, int h) {
  return (static_cast<uint64_t>(w) * static_cast<uint64_t>(h) * static_cast<uint64_t>(PixelBits(code)) + 7) / 8;
}

// What the table depends on: the simulated sensor.
struct SensorInfo {
  int width = 0, height = 0;
  Cfa cfa = Cfa::kBayerRG;
  int adc_bits = 12;
  double max_black_level_dn = 0;  // 2^adc_bits - 1 quarter: leaves headroom for signal
  int scene_count = 1;
  bool has_isp_rgb = false;  // the configured pipeline ends in an 8-bit RGB image
  bool has_trigger_line = true;
  // The configured pipeline has the white balance stage on a Bayer sensor
  // and ends in RGB8: BalanceRatio, BalanceRatioSelector, BalanceWhiteAuto.
  bool has_white_balance = false;  // a trigger input (--trigger-line): TriggerSource Line0 is available
  // The configured pipeline has the gamma stage and ends in RGB8: Gamma, GammaEnable.
  bool has_gamma = false;
  std::vector<std::string> stage_names;  // configured stages (SimStageSelector entries)
  // SimFocusDistance's Min: a value the device accepts (with depth of field,
  // the next whole millimetre beyond the focal length).
  double min_focus_distance_m = reg::kMinFocusDistanceM;
};

// The largest payload of the sensor's formats, chunks included (bytes), and
// the smallest GevSCPSPacketSize that sends it: Aravis's fake camera counts a
// frame's packets in 16 bits (at most 65534 data packets) and its bits in 32
// (GigeDevice::Init refuses a sensor whose frame does not fit).
uint64_t MaxPayloadBytes(const SensorInfo& sensor);
inline constexpr uint64_t kMaxFakeCameraPayloadBits = 0xFFFFFFFFu;
inline constexpr uint32_t kMaxGvspDataPackets = 65534, kMinPacketSize = 576, kMaxPacketSize = 9000;
inline constexpr uint32_t kMaxPacketDelayTicks = 100000;  // GevSCPD's maximum (100 us at 1 GHz)
uint32_t MinPacketSize(const SensorInfo& sensor);

// Pixel formats offered for a sensor, first = default (the raw format at the
// ADC depth). A Bayer sensor's come in the phase of each readout (EnumEntry::readout).
std::vector<EnumEntry> PixelFormats(const SensorInfo& sensor);

std::vector<Feature> RegisterTable(const SensorInfo& sensor);
// The table with each selected feature spread into one entry per register
// (named Feature[i], at SelectedAddress(address, i, length), selection i,
// with the entries available at selection i), and without the chunk
// features: what the device reads and checks.
std::vector<Feature> FeatureRegisters(const std::vector<Feature>& table);
const Feature* FindFeature(const std::vector<Feature>& table, const std::string& name);

struct DeviceStrings {
  std::string vendor = "camsim", model = "camsim-gige", version = "0.1.0", serial = "CS0001";
};
// The GenICam XML (GenApi schema 1.0) for the table.
std::string GenerateXml(const std::vector<Feature>& table, const DeviceStrings& strings);

}  // namespace camsim::genicam
