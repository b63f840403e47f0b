#include "genicam/register_table.h"

#include <algorithm>
#include <cstdio>
#include <set>
#include <sstream>

#include "core/pipeline/pipeline.h"
#include "genicam/fake_camera_hooks.h"

namespace camsim::genicam {

static_assert(reg::SelectedAddress(reg::kSimStageEnable, kStageCount) <= reg::kChunkEnable,
              "SimStageEnable's registers run into ChunkEnable's");

namespace {

Feature Int(const char* name, const char* cat, uint32_t addr, bool rw, double min, double max, double inc,
            const char* desc, const char* unit = "") {
  Feature f;
  f.name = name;
  f.category = cat;
  f.description = desc;
  f.kind = Kind::kInteger;
  f.address = addr;
  f.writable = rw;
  f.min = min;
  f.max = max;
  f.inc = inc;
  f.unit = unit;
  return f;
}

Feature Flt(const char* name, const char* cat, uint32_t addr, double min, double max, const char* desc,
            const char* unit) {
  Feature f = Int(name, cat, addr, true, min, max, 0, desc, unit);
  f.kind = Kind::kFloat;
  f.length = 8;
  return f;
}

Feature Enum(const char* name, const char* cat, uint32_t addr, bool rw, std::vector<EnumEntry> entries,
             const char* desc) {
  Feature f = Int(name, cat, addr, rw, 0, 0, 1, desc);
  f.kind = Kind::kEnum;
  f.entries = std::move(entries);
  return f;
}

Feature Bool(const char* name, const char* cat, uint32_t addr, bool rw, const char* desc) {
  Feature f = Int(name, cat, addr, rw, 0, 1, 1, desc);
  f.kind = Kind::kBoolean;
  return f;
}

Feature Cmd(const char* name, const char* cat, uint32_t addr, int64_t value, const char* desc) {
  Feature f = Int(name, cat, addr, true, 0, 0, 1, desc);
  f.kind = Kind::kCommand;
  f.command_value = value;
  return f;
}

Feature Str(const char* name, const char* cat, uint32_t addr, uint32_t length, bool rw, const char* desc) {
  Feature f = Int(name, cat, addr, rw, 0, 0, 1, desc);
  f.kind = Kind::kString;
  f.length = length;
  return f;
}

// A feature with one register per value of `selector` (Feature::selected_by).
Feature Selected(Feature f, const char* selector, int selections) {
  f.selected_by = selector;
  f.selections = selections;
  return f;
}

Feature Alias(const Feature& of, const char* name, const char* desc) {
  Feature f = of;
  f.name = name;
  f.description = desc;
  f.alias_of = of.name;
  return f;
}

std::string Xml(const std::string& s) {
  std::string out;
  for (char c : s) {
    if (c == '<') out += "&lt;";
    else if (c == '>') out += "&gt;";
    else if (c == '&') out += "&amp;";
    else if (c == '"') out += "&quot;";
    else out += c;
  }
  return out;
}

std::string Num(double v) {
  char buf[40];
  std::snprintf(buf, sizeof buf, "%.17g", v);
  return buf;
}

std::string Hex(uint32_t v) {
  char buf[16];
  std::snprintf(buf, sizeof buf, "0x%x", v);
  return buf;
}

bool IsStandard(const std::string& name) {
  // (GammaEnable: the vendors' name, not SFNC's.)
  return name.find("Sim") == std::string::npos && name != "ExposureTimeAbs" && name != "GainRaw" &&
         name != "GammaEnable";
}

// A chunk's value: read from the chunk `chunk` of each frame (Feature::chunk_id).
Feature ChunkValue(Feature f, int64_t chunk) {
  f.writable = false;
  f.address = 0;
  f.length = kChunkDataBytes;
  f.chunk_id = kChunkIdBase + static_cast<uint32_t>(chunk);
  return f;
}

// The register node a formula variable names: a feature's, or for
// "Feature[i]" the register of selection i of a selected feature (its own node,
// SelectionNodes).
std::string VariableNode(const std::string& feature) {
  std::string node = feature;
  const size_t open = node.find('[');
  if (open != std::string::npos) node = node.substr(0, open) + "_" + node.substr(open + 1, node.size() - open - 2);
  return node + "Reg";
}

// An Auto feature's limits (SFNC <prefix>LowerLimit and <prefix>UpperLimit),
// in the range of the feature `of` they limit. The device refuses a lower
// limit above the upper one, so each one's maximum (minimum) is the other's value.
void PushAutoLimits(std::vector<Feature>* t, const Feature& of, const std::string& prefix, const char* auto_name,
                    uint32_t lower_address, uint32_t upper_address) {
  Feature lo = Flt("", of.category.c_str(), lower_address, of.min, of.max, "", of.unit.c_str());
  Feature hi = lo;
  lo.name = prefix + "LowerLimit";
  hi.name = prefix + "UpperLimit";
  hi.address = upper_address;
  lo.max_feature = hi.name;
  hi.min_feature = lo.name;
  lo.description = "Lowest " + of.name + " " + auto_name + " sets (at most " + hi.name + ").";
  hi.description = "Highest " + of.name + " " + auto_name + " sets (at least " + lo.name + ").";
  t->push_back(lo);
  t->push_back(hi);
}

}  // namespace

uint32_t BayerCode(Cfa cfa, int bits) {
  // PFNC: 8-bit GR 0x08, RG 0x09, GB 0x0a, BG 0x0b; 10-bit 0x0c..0x0f; 12-bit 0x10..0x13; 16-bit 0x2e..0x31.
  int phase = 0;
  switch (cfa) {
    case Cfa::kBayerGR: phase = 0; break;
    case Cfa::kBayerRG: phase = 1; break;
    case Cfa::kBayerGB: phase = 2; break;
    case Cfa::kBayerBG: phase = 3; break;
    case Cfa::kMono: return 0;
  }
  if (bits == 8) return 0x01080008u + phase;
  if (bits == 10) return 0x0110000cu + phase;
  if (bits == 12) return 0x01100010u + phase;
  return 0x0110002eu + phase;
}

Cfa ReadoutCfa(Cfa sensor, bool reverse_x, bool reverse_y) {
  Cfa c = sensor;
  if (reverse_x) {
    switch (c) {
      case Cfa::kBayerRG: c = Cfa::kBayerGR; break;
      case Cfa::kBayerGR: c = Cfa::kBayerRG; break;
      case Cfa::kBayerGB: c = Cfa::kBayerBG; break;
      case Cfa::kBayerBG: c = Cfa::kBayerGB; break;
      case Cfa::kMono: break;
    }
  }
  if (reverse_y) {
    switch (c) {
      case Cfa::kBayerRG: c = Cfa::kBayerGB; break;
      case Cfa::kBayerGB: c = Cfa::kBayerRG; break;
      case Cfa::kBayerGR: c = Cfa::kBayerBG; break;
      case Cfa::kBayerBG: c = Cfa::kBayerGR; break;
      case Cfa::kMono: break;
    }
  }
  return c;
}

uint32_t ReadoutFormat(uint32_t code, Cfa sensor, int readout) {
  if (sensor == Cfa::kMono) return code;
  const Cfa to = ReadoutCfa(sensor, readout & 1, readout & 2);
  for (const Cfa phase : {Cfa::kBayerRG, Cfa::kBayerGR, Cfa::kBayerGB, Cfa::kBayerBG}) {
    for (const int bits : {8, 10, 12, 16})
      if (BayerCode(phase, bits) == code) return BayerCode(to, bits);
    for (const Packing packing : {Packing::kPfnc, Packing::kGigeLegacy})
      for (const int bits : {10, 12})
        if (PackedCode(phase, bits, packing) == code)
          return PackedCode(to, bits, packing);
  }
  return code;
}

uint32_t TestPatternCode(int64_t pattern, int x, int y, int width, int height, int bits, uint64_t frame_index) {
  const uint64_t full = (uint64_t{1} << bits) - 1;
  // round(t x M / (n - 1)), half up.
  const auto ramp = [full](uint64_t t, uint64_t n) {
    return n <= 1 ? 0 : static_cast<uint32_t>((2 * t * full + (n - 1)) / (2 * (n - 1)));
  };
  const uint64_t ux = static_cast<uint64_t>(x), uy = static_cast<uint64_t>(y);
  const uint64_t w = static_cast<uint64_t>(width), h = static_cast<uint64_t>(height);
  switch (pattern) {
    case kTestPatternWhite: return static_cast<uint32_t>(full);
    case kTestPatternGreyHorizontalRamp: return ramp(ux, w);
    case kTestPatternGreyVerticalRamp: return ramp(uy, h);
    case kTestPatternGreyDiagonalRamp: return ramp(ux + uy, w + h - 1);
    case kTestPatternGreyHorizontalRampMoving: return ramp((ux + frame_index % w) % w, w);
    default: return 0;  // Black (Off has no pattern)
  }
}

uint32_t PackedCode(Cfa cfa, int bits, Packing packing) {
  // PFNC: BayerXX10p BG 0x52, GB 0x54, GR 0x56, RG 0x58 (12p one more);
  // GigE Vision BayerXX12Packed GR 0x2a, RG 0x2b, GB 0x2c, BG 0x2d.
  int p10 = 0, legacy = 0;
  switch (cfa) {
    case Cfa::kBayerGR: p10 = 0x56; legacy = 0x2a; break;
    case Cfa::kBayerRG: p10 = 0x58; legacy = 0x2b; break;
    case Cfa::kBayerGB: p10 = 0x54; legacy = 0x2c; break;
    case Cfa::kBayerBG: p10 = 0x52; legacy = 0x2d; break;
    case Cfa::kMono: break;
  }
  const bool mono = cfa == Cfa::kMono;
  if (packing == Packing::kPfnc && bits == 10) return mono ? kMono10p : 0x010a0000u + p10;
  if (packing == Packing::kPfnc && bits == 12) return mono ? kMono12p : 0x010c0000u + p10 + 1;
  if (packing == Packing::kGigeLegacy && bits == 12) return mono ? kMono12Packed : 0x010c0000u + legacy;
  return 0;
}

Packing PackingOf(uint32_t code) {
  if (code == kMono10p || code == kMono12p || (code >= 0x010a0052u && code <= 0x010a0058u && code % 2 == 0) ||
      (code >= 0x010c0053u && code <= 0x010c0059u && code % 2 == 1))
    return Packing::kPfnc;
  if (code == kMono12Packed || (code >= 0x010c002au && code <= 0x010c002du)) return Packing::kGigeLegacy;
  return Packing::kNone;
}

int SampleBits(uint32_t code) {
  if (code == kMono10 || (code >= 0x0110000cu && code <= 0x0110000fu)) return 10;
  if (code == kMono12 || (code >= 0x01100010u && code <= 0x01100013u)) return 12;
  return code == kRGB8 || code == kBGR8 || Is422(code) ? 8 : PixelBits(code);
}

std::vector<EnumEntry> PixelFormats(const SensorInfo& s) {
  std::vector<EnumEntry> out;
  const bool mono = s.cfa == Cfa::kMono;
  // The raw format at the ADC's depth first (the default), then the others;
  // a Bayer sensor's in the phase of each readout (the sensor's own first).
  const int native = s.adc_bits <= 8 ? 8 : (s.adc_bits == 12 ? 12 : 16);
  for (int readout = 0; readout < (mono ? 1 : 4); ++readout) {
    const Cfa phase = ReadoutCfa(s.cfa, readout & 1, readout & 2);
    const std::string base = mono ? "Mono" : CfaName(phase);
    auto code = [&](int bits) -> int64_t {
      if (!mono) return BayerCode(phase, bits);
      return bits == 8 ? kMono8 : bits == 10 ? kMono10 : bits == 12 ? kMono12 : kMono16;
    };
    const int only_at_readout = mono ? -1 : readout;
    out.push_back({base + std::to_string(native), code(native), -1, true, only_at_readout});
    for (int bits : {8, 10, 12, 16}) {
      if (bits == native) continue;
      if (bits == 10 && s.adc_bits > 10) continue;  // would drop ADC bits
      if (bits == 12 && s.adc_bits > 12) continue;
      out.push_back({base + std::to_string(bits), code(bits), -1, true, only_at_readout});
    }
    // Packed: like the unpacked format of their depth, so only for an ADC of at most that depth.
    if (s.adc_bits <= 12) {
      out.push_back({base + "12p", PackedCode(phase, 12, Packing::kPfnc), -1, true, only_at_readout});
      out.push_back({base + "12Packed", PackedCode(phase, 12, Packing::kGigeLegacy), -1, true, only_at_readout});
    }
    if (s.adc_bits <= 10)
      out.push_back({base + "10p", PackedCode(phase, 10, Packing::kPfnc), -1, true, only_at_readout});
  }
  if (s.has_isp_rgb) {
    if (!mono) out.push_back({"Mono8", kMono8});  // the luma of RGB8
    out.push_back({"RGB8", kRGB8});
    out.push_back({"BGR8", kBGR8});
    // 4:2:2: a Cb and Cr per pixel pair. Only on a Bayer sensor (the only one
    // with an ISP RGB image), whose Width, OffsetX and WidthMax are even.
    if (!mono) {
      out.push_back({"YCbCr422_8", kYCbCr422_8});
      out.push_back({"YUV422_8", kYUV422_8});
      out.push_back({"YUV422_8_UYVY", kYUV422_8_UYVY});
    }
  }
  return out;
}

uint64_t MaxPayloadBytes(const SensorInfo& s) {
  int bits = 0;
  for (const EnumEntry& e : PixelFormats(s)) bits = std::max(bits, PixelBits(static_cast<uint32_t>(e.value)));
  const uint64_t image = static_cast<uint64_t>(s.width) * static_cast<uint64_t>(s.height) * bits / 8;
  return (image + 3) / 4 * 4 + kChunkTagBytes + kChunkCount * (kChunkDataBytes + kChunkTagBytes);
}

uint32_t MinPacketSize(const SensorInfo& s) {
  const uint64_t data = (MaxPayloadBytes(s) + kMaxGvspDataPackets - 1) / kMaxGvspDataPackets;
  return static_cast<uint32_t>(std::max<uint64_t>(kMinPacketSize, data + kGvspOverheadBytes));
}

std::vector<Feature> RegisterTable(const SensorInfo& s) {
  using namespace reg;
  std::vector<Feature> t;
  const char* dc = "DeviceControl";
  t.push_back(Str("DeviceVendorName", dc, kVendorName, 32, false, "Vendor of the device."));
  t.push_back(Str("DeviceModelName", dc, kModelName, 32, false, "Model of the device."));
  t.push_back(Str("DeviceVersion", dc, kDeviceVersion, 32, false, "Version of the device."));
  t.push_back(Str("DeviceManufacturerInfo", dc, kManufacturerInfo, 48, false, "Manufacturer information."));
  t.push_back(Str("DeviceSerialNumber", dc, kSerialNumber, 16, false, "Serial number of the device."));
  t.push_back(Alias(t.back(), "DeviceID", "Serial number (GigE Vision 1.x name)."));
  t.push_back(Str("DeviceUserID", dc, kUserId, 16, true, "User-programmable device identifier."));
  t.push_back(Enum("DeviceTemperatureSelector", dc, kDeviceTemperatureSelector, true, {{"Sensor", 0}},
                   "Where DeviceTemperature is measured."));
  t.back().selects = {"DeviceTemperature"};
  Feature temperature = Flt("DeviceTemperature", dc, kDeviceTemperature, kMinSensorTemperatureC,
                            kMaxSensorTemperatureC,
                            "Temperature of the selected part: the sensor's, as configured (sensor.temperature_c; "
                            "it sets the dark current).",
                            "C");
  temperature.writable = false;
  t.push_back(temperature);

  // Bayer ROIs keep the CFA phase: even offsets and sizes.
  const double step = s.cfa == Cfa::kMono ? 1 : 2;
  const char* ifc = "ImageFormatControl";
  t.push_back(Int("SensorWidth", ifc, kSensorWidth, false, s.width, s.width, 1, "Simulated sensor width.", "px"));
  t.push_back(Int("SensorHeight", ifc, kSensorHeight, false, s.height, s.height, 1, "Simulated sensor height.", "px"));
  // (Binning and decimation reduce them, down to a factor of kMaxReduction x kMaxReduction.)
  const int istep = static_cast<int>(step);
  t.push_back(Int("WidthMax", ifc, kWidthMax, false, ReducedExtent(s.width, istep, kMaxReduction, kMaxReduction),
                  s.width, 1,
                  "Largest Width: SensorWidth / (BinningHorizontal x DecimationHorizontal), rounded down to whole "
                  "CFA cells.",
                  "px"));
  t.push_back(Int("HeightMax", ifc, kHeightMax, false, ReducedExtent(s.height, istep, kMaxReduction, kMaxReduction),
                  s.height, 1, "Largest Height: SensorHeight / (BinningVertical x DecimationVertical), likewise.",
                  "px"));
  // SFNC: each window feature's maximum leaves room for the other on its
  // axis, so a client orders its writes by the limits it reads.
  const auto window = [&t](Feature f, const char* max_name, const char* other) {
    f.max_formula = "M-O";
    f.variables = {{"M", max_name}, {"O", other}};
    f.locked_while_acquiring = true;
    t.push_back(f);
  };
  window(Int("Width", ifc, kWidth, true, step, s.width, step,
             "Width of the image window (OffsetX + Width <= WidthMax).", "px"),
         "WidthMax", "OffsetX");
  window(Int("Height", ifc, kHeight, true, step, s.height, step,
             "Height of the image window (OffsetY + Height <= HeightMax).", "px"),
         "HeightMax", "OffsetY");
  window(Int("OffsetX", ifc, kOffsetX, true, 0, s.width - step, step, "Left edge of the image window.", "px"),
         "WidthMax", "Width");
  window(Int("OffsetY", ifc, kOffsetY, true, 0, s.height - step, step, "Top edge of the image window.", "px"),
         "HeightMax", "Height");
  // Binning and decimation reduce the readout before the window (Width,
  // OffsetX, ... count reduced pixels); a Bayer readout keeps its CFA.
  const auto reduction = [&t](const char* name, uint32_t address, const char* desc) {
    t.push_back(Int(name, "ImageFormatControl", address, true, 1, kMaxReduction, 1, desc));
    t.back().locked_while_acquiring = true;
  };
  reduction("BinningHorizontal", kBinningHorizontal,
            "Horizontal binning: each pixel read out combines this many same-colour pixels of a row (Bayer: of "
            "neighbouring 2x2 cells), as BinningHorizontalMode says. A window that no longer fits is reset to the "
            "whole readout on this axis.");
  reduction("BinningVertical", kBinningVertical, "Vertical binning (as BinningHorizontal, over rows).");
  const std::vector<EnumEntry> modes = {{"Sum", kBinningSum}, {"Average", kBinningAverage}};
  t.push_back(Enum("BinningHorizontalMode", ifc, kBinningHorizontalMode, true, modes,
                   "Sum (clamped at full scale) or Average (rounded half up) of the binned pixels."));
  t.back().locked_while_acquiring = true;
  t.push_back(Enum("BinningVerticalMode", ifc, kBinningVerticalMode, true, modes,
                   "Sum (clamped at full scale) or Average (rounded half up) of the binned rows."));
  t.back().locked_while_acquiring = true;
  reduction("DecimationHorizontal", kDecimationHorizontal,
            "Horizontal decimation: keeps every Nth pixel (Bayer: every Nth 2x2 cell, so the phase stays). A "
            "window that no longer fits is reset to the whole readout on this axis.");
  reduction("DecimationVertical", kDecimationVertical, "Vertical decimation (as DecimationHorizontal, over rows).");
  // Before PixelFormat: the device checks a block's readout before its format.
  t.push_back(Bool("ReverseX", ifc, kReverseX, true,
                   "Mirrors the readout horizontally (the window stays on the sensor; its content is mirrored). "
                   "A Bayer PixelFormat then names the phase read out (BayerRG -> BayerGR)."));
  t.back().locked_while_acquiring = true;
  t.push_back(Bool("ReverseY", ifc, kReverseY, true,
                   "Mirrors the readout vertically (BayerRG -> BayerGB)."));
  t.back().locked_while_acquiring = true;
  t.push_back(Enum("PixelFormat", ifc, kPixelFormat, true, PixelFormats(s),
                   "Format of the pixels sent. Raw formats carry the sensor's digital numbers (8-bit: the top 8 "
                   "ADC bits; 16-bit: shifted to the top; 10p/12p/12Packed: packed, the frame's pixel bits a "
                   "whole number of bytes); RGB8 is the ISP output, BGR8 the same with R and B swapped, Mono8 on a "
                   "colour sensor its BT.601 luma; YCbCr422_8 (Y Cb Y Cr), YUV422_8 (Y U Y V) and YUV422_8_UYVY "
                   "(U Y V Y) its full-range BT.601 YCbCr, Cb and Cr those of each pair's even pixel."));
  t.back().locked_while_acquiring = true;
  // Writable while acquiring: the payload does not change (from the next frame).
  t.push_back(Enum("TestPatternGeneratorSelector", ifc, kTestPatternGeneratorSelector, true, {{"Sensor", 0}},
                   "The test pattern generator TestPattern configures: the sensor's, after its ADC."));
  t.back().selects = {"TestPattern"};
  t.push_back(Enum("TestPattern", ifc, kTestPattern, true,
                   {{"Off", kTestPatternOff},
                    {"Black", kTestPatternBlack},
                    {"White", kTestPatternWhite},
                    {"GreyHorizontalRamp", kTestPatternGreyHorizontalRamp},
                    {"GreyVerticalRamp", kTestPatternGreyVerticalRamp},
                    {"GreyDiagonalRamp", kTestPatternGreyDiagonalRamp},
                    {"GreyHorizontalRampMoving", kTestPatternGreyHorizontalRampMoving}},
                   "Off: the modelled image. Otherwise exact codes that replace the ADC's over the whole sensor "
                   "(no optics, no noise), before binning, decimation, ReverseX/Y and the window: Black 0, White "
                   "full scale M = 2^bits - 1, a ramp round(t x M / (n - 1)) over x (Horizontal), y (Vertical) or "
                   "x + y (Diagonal) of the sensor; Moving: the horizontal ramp at (x + frame index) mod "
                   "SensorWidth. RGB8 and the formats made from it (BGR8, Mono8, 4:2:2) get R = G = B = the code's top "
                   "8 bits."));

  const char* ac = "AcquisitionControl";
  t.push_back(Enum("AcquisitionMode", ac, kAcquisitionMode, true,
                   {{"Continuous", kContinuous}, {"SingleFrame", kSingleFrame}, {"MultiFrame", kMultiFrame}},
                   "Number of frames to acquire after AcquisitionStart."));
  t.push_back(Int("AcquisitionFrameCount", ac, kAcquisitionFrameCount, true, 1, 65535, 1,
                  "Frames to acquire in MultiFrame mode."));
  // Each reads 0 once executed, so GenApi's IsDone (the value read back
  // differs from CommandValue) is true at once.
  t.push_back(Cmd("AcquisitionStart", ac, kAcquisitionStart, 1, "Starts the acquisition."));
  t.push_back(Cmd("AcquisitionStop", ac, kAcquisitionStop, 1, "Stops the acquisition."));
  t.push_back(Cmd("AcquisitionAbort", ac, kAcquisitionAbort, 1,
                  "Stops the acquisition, as AcquisitionStop does (a frame already being sent is finished)."));
  t.push_back(Flt("AcquisitionFrameRate", ac, kAcquisitionFrameRate, 0.1, 1000.0,
                  "Free-run frame rate when AcquisitionFrameRateEnable is on.", "Hz"));
  t.push_back(Bool("AcquisitionFrameRateEnable", ac, kAcquisitionFrameRateEnable, true,
                   "On: free-run at AcquisitionFrameRate; off: as fast as frames are rendered."));
  Feature resulting = Flt("AcquisitionResultingFrameRate", ac, kAcquisitionResultingFrameRate, 0.0, 1e6,
                          "Frame rate of free run now: with AcquisitionFrameRateEnable, AcquisitionFrameRate or "
                          "1 / ExposureTime, whichever is lower; and at most 1 / the last frame's rendering time "
                          "(without a frame rendered yet and without AcquisitionFrameRateEnable: the maximum).",
                          "Hz");
  resulting.writable = false;
  t.push_back(resulting);
  t.push_back(Enum("ExposureMode", ac, kExposureMode, true,
                   {{"Timed", kExposureTimed}, {"TriggerWidth", kExposureTriggerWidth}},
                   "Timed: an exposure lasts ExposureTime. TriggerWidth: as long as Line0 is active, from its "
                   "TriggerActivation edge to the opposite one (available with TriggerMode On, TriggerSource Line0 "
                   "and ExposureAuto Off, which it then locks, as it locks ExposureTime)."));
  t.back().entries[1].available_formula = "(M=1)&&(S=" + std::to_string(kSourceLine0) + ")&&(A=" +
                                          std::to_string(kAutoOff) + ")";
  t.back().entries[1].variables = {{"M", "TriggerMode"}, {"S", "TriggerSource"}, {"A", "ExposureAuto"}};
  // The core's whole range (core/aperture/exposure.cc): any configured exposure is reported as rendered.
  // Locked while ExposureAuto is not Off (the auto loop sets it; SFNC) or
  // ExposureMode is TriggerWidth (the pulse sets it): the device refuses a change.
  const auto auto_locked = [](Feature f, const char* auto_name) {
    f.locked_formula = "A<>" + std::to_string(kAutoOff);
    f.variables = {{"A", auto_name}};
    return f;
  };
  Feature exposure = auto_locked(Flt("ExposureTime", ac, kExposureTime, 1.0, 1e8,
                                     "Exposure time (read-only while ExposureAuto is Once or Continuous; not used, "
                                     "and locked, under ExposureMode TriggerWidth).",
                                     "us"),
                                 "ExposureAuto");
  exposure.locked_formula = "(" + exposure.locked_formula + ")||(E=" + std::to_string(kExposureTriggerWidth) + ")";
  exposure.variables.push_back({"E", "ExposureMode"});
  t.push_back(exposure);
  t.push_back(Alias(t.back(), "ExposureTimeAbs", "Exposure time (Aravis fake camera name)."));
  t.push_back(Enum("ExposureAuto", ac, kExposureAuto, true,
                   {{"Off", kAutoOff}, {"Once", kAutoOnce}, {"Continuous", kAutoContinuous}},
                   "Automatic exposure: scales ExposureTime so the mean raw level reaches SimAutoTarget "
                   "(locked under ExposureMode TriggerWidth)."));
  t.back().locked_formula = "E=" + std::to_string(kExposureTriggerWidth);
  t.back().variables = {{"E", "ExposureMode"}};
  PushAutoLimits(&t, *FindFeature(t, "ExposureTime"), "AutoExposureTime", "ExposureAuto", kAutoExposureTimeLowerLimit,
                 kAutoExposureTimeUpperLimit);
  t.push_back(Enum("TriggerSelector", ac, kTriggerSelector, true, {{"FrameStart", 0}},
                   "The trigger the other Trigger features configure."));
  t.back().selects = {"TriggerMode", "TriggerSource", "TriggerActivation", "TriggerDelay", "TriggerSoftware"};
  // Locked under ExposureMode TriggerWidth (with ExposureAuto and Line0's
  // LineInverter): the pulse's exposure needs them as they are.
  const auto width_locked = [](Feature f) {
    f.locked_formula = "E=" + std::to_string(kExposureTriggerWidth);
    f.variables = {{"E", "ExposureMode"}};
    return f;
  };
  t.push_back(width_locked(Enum("TriggerMode", ac, kTriggerMode, true, {{"Off", 0}, {"On", 1}},
                                "On: one frame per trigger; off: free run.")));
  t.push_back(width_locked(Enum("TriggerSource", ac, kTriggerSource, true,
                                {{"Software", kSourceSoftware}, {"Line0", kSourceLine0}},
                                "Software (TriggerSoftware) or Line0 (the GPIO line given by --trigger-line; "
                                "not available without one).")));
  t.back().entries[1].available = s.has_trigger_line;
  t.push_back(width_locked(Enum("TriggerActivation", ac, kTriggerActivation, true,
                                {{"RisingEdge", 0}, {"FallingEdge", 1}}, "Edge of Line0 that triggers.")));
  t.push_back(Flt("TriggerDelay", ac, kTriggerDelay, 0.0, kMaxTriggerDelayUs,
                  "Delay from a trigger to the start of its exposure (the frame's timestamp).", "us"));
  // Available only where it triggers (the device refuses it elsewhere).
  t.push_back(Cmd("TriggerSoftware", ac, kTriggerSoftware, 1,
                  "One frame; available only with TriggerMode On and TriggerSource Software (while the "
                  "acquisition is stopped it is dropped)."));
  t.back().available_formula = "(M=1)&&(S=" + std::to_string(kSourceSoftware) + ")";
  t.back().variables = {{"M", "TriggerMode"}, {"S", "TriggerSource"}};

  const char* an = "AnalogControl";
  t.push_back(auto_locked(Flt("Gain", an, kGain, 0.0, 48.0,
                              "Analog gain (amplifies signal and noise), in GainRaw's 0.1 dB steps: a value between "
                              "steps is applied and reads back as the nearest one. Read-only while GainAuto is "
                              "Once or Continuous.",
                              "dB"),
                          "GainAuto"));
  t.back().inc = 0.1;
  t.push_back(auto_locked(Int("GainRaw", an, kGainRaw, true, 0, 480, 1,
                              "Analog gain in 0.1 dB steps (Aravis fake camera name; read-only while GainAuto is "
                              "not Off)."),
                          "GainAuto"));
  t.push_back(Enum("GainAuto", an, kGainAuto, true, {{"Off", kAutoOff}, {"Once", kAutoOnce}, {"Continuous", kAutoContinuous}},
                   "Automatic gain, used when ExposureAuto alone cannot reach SimAutoTarget."));
  PushAutoLimits(&t, *FindFeature(t, "Gain"), "AutoGain", "GainAuto", kAutoGainLowerLimit, kAutoGainUpperLimit);
  t.push_back(Flt("BlackLevel", an, kBlackLevel, 0.0, s.max_black_level_dn, "Offset added by the sensor.", "DN"));
  if (s.has_white_balance) {
    t.push_back(Enum("BalanceRatioSelector", an, kBalanceRatioSelector, true,
                     {{"Red", kBalanceRed}, {"Green", kBalanceGreen}, {"Blue", kBalanceBlue}},
                     "Colour channel BalanceRatio acts on."));
    t.back().selects = {"BalanceRatio"};
    t.push_back(Selected(Flt("BalanceRatio", an, kBalanceRatio, 0.0, kMaxBalanceRatio,
                             "White balance gain of the selected channel (the ISP's white_balance stage: RGB8 "
                             "frames made after the write; the raw formats are the sensor's and do not change).",
                             ""),
                         "BalanceRatioSelector", kBalanceCount));
    t.push_back(Enum("BalanceWhiteAuto", an, kBalanceWhiteAuto, true,
                     {{"Off", kAutoOff}, {"Once", kAutoOnce}, {"Continuous", kAutoContinuous}},
                     "Automatic white balance (gray world on the window): sets the Red and Blue BalanceRatio "
                     "from each frame so its channel means equal Green's (Green stays); Once does it from the "
                     "next frame and returns to Off."));
  }

  if (s.has_gamma) {
    t.push_back(Flt("Gamma", an, kGamma, kMinGamma, kMaxGamma,
                    "Gamma correction Y' = Y^Gamma of the RGB8 frames (the ISP's gamma stage, a power curve of "
                    "gamma 1 / Gamma; below 1 brightens). Available while GammaEnable is on. Raw formats do not "
                    "change.",
                    ""));
    t.back().available_formula = "G=1";
    t.back().variables = {{"G", "GammaEnable"}};
    t.push_back(Bool("GammaEnable", an, kGammaEnable, true,
                     "On: the gamma stage applies Gamma; off: it applies the configured [gamma] curve."));
  }

  const char* io = "DigitalIOControl";
  t.push_back(Enum("LineSelector", io, kLineSelector, true, {{"Line0", 0}, {"Line1", 1}},
                   "Line0: trigger input; Line1: strobe output."));
  t.back().selects = {"LineMode", "LineSource", "LineStatus", "LineInverter", "LineDebouncerTime"};
  constexpr int kLines = 2;
  t.push_back(Selected(Enum("LineMode", io, kLineMode, false, {{"Input", 0}, {"Output", 1}},
                            "Direction of the selected line."),
                       "LineSelector", kLines));
  t.push_back(Selected(Enum("LineSource", io, kLineSource, true,
                            {{"Off", kLineSourceOff}, {"ExposureActive", kLineSourceExposureActive, 1}},
                            "What drives the selected line: the strobe output (Line1) only; the input (Line0) "
                            "stays Off."),
                       "LineSelector", kLines));
  t.push_back(Selected(Bool("LineStatus", io, kLineStatus, false,
                            "Level of the selected line: Line0 after its last edge (low before one), inverted "
                            "by its LineInverter; Line1 as last driven on the wire (after its LineInverter)."),
                       "LineSelector", kLines));
  t.push_back(Selected(Bool("LineInverter", io, kLineInverter, true,
                            "Inverts the selected line: Line0's electrical level before the trigger and "
                            "LineStatus (RisingEdge then fires on the electrical falling edge), Line1's "
                            "strobe output (low while active). Line0's is locked under ExposureMode "
                            "TriggerWidth."),
                       "LineSelector", kLines));
  t.back().locked_formula = "(E=" + std::to_string(kExposureTriggerWidth) + ")&&(L=0)";
  t.back().variables = {{"E", "ExposureMode"}, {"L", "LineSelector"}};
  // Line0's alone (the one input): not selected, available at Line0.
  t.push_back(Flt("LineDebouncerTime", io, kLineDebouncerTime, 0.0, kMaxLineDebouncerTimeUs,
                  "Line0 (input): a level change is taken once the level has held this long (by the line's edge "
                  "timestamps), so shorter pulses are ignored and a trigger comes this much after its edge.",
                  "us"));
  t.back().available_formula = "L=0";
  t.back().variables = {{"L", "LineSelector"}};

  const char* tl = "TransportLayerControl";
  // Computed by the client from the registers it has just written: never stale.
  Feature payload = Int("PayloadSize", tl, 0, false, 0, 0, 1,
                        "Bytes per frame: Width * Height * bits per pixel / 8; with ChunkModeActive, that padded "
                        "to 4 bytes, 8 for the image chunk's tag and 16 per enabled chunk.");
  payload.kind = Kind::kSwissKnife;
  // (kChunkDataBytes + kChunkTagBytes per chunk, kChunkTagBytes for the image's.)
  static_assert(kChunkDataBytes + kChunkTagBytes == 16 && kChunkTagBytes == 8);
  std::string enabled;  // E0+E1+...: the enabled chunks
  payload.variables = {{"W", "Width"}, {"H", "Height"}, {"PF", "PixelFormat"}, {"M", "ChunkModeActive"}};
  for (int i = 0; i < kChunkCount; ++i) {
    payload.variables.push_back({"E" + std::to_string(i), "ChunkEnable[" + std::to_string(i) + "]"});
    enabled += (i ? "+E" : "E") + std::to_string(i);
  }
  payload.formula = "(M=0)?((W*H*((PF>>16)&255))/8):(((W*H*((PF>>16)&255))/8+3)/4*4+8+16*(" + enabled + "))";
  t.push_back(payload);
  // SCPS0's low 16 bits; its high bits are flags (31: fire a test packet,
  // 30: do not fragment, 29: pixel endianness) that a size write keeps.
  // At least what sends the largest frame in the fake camera's 65534 packets;
  // fixed while acquiring (a receiver places packets by the size it started with).
  Feature packet = Int("GevSCPSPacketSize", tl, kPacketSize, true, std::min(MinPacketSize(s), kMaxPacketSize),
                       kMaxPacketSize, 1, "Stream packet size.", "B");
  packet.low_bits = 16;
  packet.locked_while_acquiring = true;
  t.push_back(packet);
  // At most 100 us a packet (a 1080p frame of 1400-byte packets: 0.15 s
  // more): the fake camera's one thread also answers control packets.
  t.push_back(Int("GevSCPD", tl, kPacketDelay, true, 0, kMaxPacketDelayTicks, 1,
                  "Delay after each stream packet, in timestamp ticks (GevTimestampTickFrequency: 1e9 Hz, so ns).",
                  "ticks"));
  t.push_back(Int("TLParamsLocked", tl, kTLParamsLocked, true, 0, 1, 1, "Set by the client during acquisition."));
  // The GigE Vision bootstrap registers a transport layer reads (SFNC's Gev* names).
  const auto masked = [](Feature f, int bits, int shift) {
    f.low_bits = bits;
    f.shift = shift;
    return f;
  };
  t.push_back(masked(Int("GevVersionMajor", tl, kVersion, false, 2, 2, 1, "GigE Vision major version."), 16, 16));
  t.push_back(masked(Int("GevVersionMinor", tl, kVersion, false, 0, 0, 1, "GigE Vision minor version."), 16, 0));
  t.push_back(masked(Bool("GevDeviceModeIsBigEndian", tl, kDeviceMode, false, "Registers are big-endian."), 1, 31));
  Feature mac = Int("GevMACAddress", tl, kMacHigh, false, 0, 281474976710655.0, 1,
                    "MAC address (48 bits): locally administered, derived from DeviceSerialNumber.");
  mac.length = 8;
  t.push_back(mac);
  t.push_back(Int("GevCurrentIPAddress", tl, kCurrentIp, false, 0, 4294967295.0, 1, "IPv4 address served on."));
  t.push_back(Int("GevStreamChannelCount", tl, kStreamChannelCount, false, 1, 1, 1, "Stream channels."));
  // At least GigE Vision's 500 ms; the fake camera's default is 3000.
  t.push_back(Int("GevHeartbeatTimeout", tl, kHeartbeatTimeout, true, 500, 3600000, 1,
                  "Control is released (and the acquisition stopped) when the controlling client has not read "
                  "the control channel privilege register for this long.",
                  "ms"));
  const double tick = static_cast<double>(kTimestampTicksPerSecond);
  Feature frequency = Int("GevTimestampTickFrequency", tl, kTimestampTickFrequency, false, tick, tick, 1,
                          "Timestamp ticks per second (1e9: timestamps are in ns).", "Hz");
  frequency.length = 8;
  t.push_back(frequency);
  t.push_back(Cmd("GevTimestampControlLatch", tl, kTimestampControl, kTimestampLatch,
                  "Copies the device's timestamp now into GevTimestampValue."));
  Feature reset = Alias(t.back(), "GevTimestampControlReset",
                        "Restarts the device's timestamp (frame timestamps and latches) from 0.");
  reset.command_value = kTimestampReset;
  t.push_back(reset);
  // The largest a double converts exactly (2^62): 146 years of ns.
  Feature value = Int("GevTimestampValue", tl, kTimestampValue, false, 0, 4611686018427387904.0, 1,
                      "The timestamp GevTimestampControlLatch copied (ticks of GevTimestampTickFrequency).");
  value.length = 8;
  t.push_back(value);

  // GigE Vision chunk mode (register_table.h, ChunkSelectorValue): per-frame
  // metadata after the image, read by clients with a chunk parser.
  const char* cd = "ChunkDataControl";
  t.push_back(Bool("ChunkModeActive", cd, kChunkModeActive, true,
                   "Sends each frame's image as a chunk followed by the enabled chunks (PayloadSize grows)."));
  t.back().locked_while_acquiring = true;
  t.push_back(Enum("ChunkSelector", cd, kChunkSelector, true,
                   {{"Timestamp", kChunkTimestamp},
                    {"FrameID", kChunkFrameID},
                    {"ExposureTime", kChunkExposureTime},
                    {"Gain", kChunkGain},
                    {"SimFrameIndex", kChunkSimFrameIndex},
                    {"OffsetX", kChunkOffsetX},
                    {"OffsetY", kChunkOffsetY},
                    {"Width", kChunkWidth},
                    {"Height", kChunkHeight},
                    {"PixelFormat", kChunkPixelFormat},
                    {"BlackLevel", kChunkBlackLevel},
                    {"LineStatusAll", kChunkLineStatusAll}},
                   "Chunk ChunkEnable acts on."));
  t.back().selects = {"ChunkEnable"};
  t.push_back(Selected(Bool("ChunkEnable", cd, kChunkEnable, true,
                            "Whether the selected chunk is sent with each frame in chunk mode."),
                       "ChunkSelector", kChunkCount));
  t.back().locked_while_acquiring = true;
  // The largest value an Integer chunk declares (2^62: a double that
  // converts exactly; a nanosecond timestamp reaches it in 146 years).
  constexpr double kChunkIntMax = 4611686018427387904.0;
  t.push_back(ChunkValue(Int("ChunkTimestamp", cd, 0, false, 0, kChunkIntMax, 1,
                             "Timestamp of the frame (its GVSP leader's).", "ns"),
                         kChunkTimestamp));
  t.push_back(ChunkValue(Int("ChunkFrameID", cd, 0, false, 0, kChunkIntMax, 1, "GVSP block ID of the frame."),
                         kChunkFrameID));
  t.push_back(ChunkValue(Flt("ChunkExposureTime", cd, 0, 1.0, 1e8, "Exposure time the frame was rendered with.", "us"),
                         kChunkExposureTime));
  t.push_back(ChunkValue(Flt("ChunkGain", cd, 0, 0.0, 48.0, "Gain the frame was rendered with.", "dB"), kChunkGain));
  t.push_back(ChunkValue(Int("ChunkSimFrameIndex", cd, 0, false, 0, 0x7fffffff, 1,
                             "Frame index the frame was rendered with (SimFrameIndex; `camsim run --first-frame`)."),
                         kChunkSimFrameIndex));
  t.push_back(ChunkValue(Int("ChunkOffsetX", cd, 0, false, 0, s.width - 1, 1, "OffsetX of the frame's window.", "px"),
                         kChunkOffsetX));
  t.push_back(ChunkValue(Int("ChunkOffsetY", cd, 0, false, 0, s.height - 1, 1, "OffsetY of the frame's window.", "px"),
                         kChunkOffsetY));
  t.push_back(ChunkValue(Int("ChunkWidth", cd, 0, false, 1, s.width, 1, "Width of the frame's window.", "px"),
                         kChunkWidth));
  t.push_back(ChunkValue(Int("ChunkHeight", cd, 0, false, 1, s.height, 1, "Height of the frame's window.", "px"),
                         kChunkHeight));
  t.push_back(ChunkValue(Enum("ChunkPixelFormat", cd, 0, false, PixelFormats(s), "Pixel format of the frame."),
                         kChunkPixelFormat));
  for (EnumEntry& e : t.back().entries) e.readout = -1;  // a frame's format, whichever readout made it
  t.push_back(ChunkValue(Flt("ChunkBlackLevel", cd, 0, 0.0, s.max_black_level_dn,
                             "Black level the frame was rendered with.", "DN"),
                         kChunkBlackLevel));
  t.push_back(ChunkValue(Int("ChunkLineStatusAll", cd, 0, false, 0, 3, 1,
                             "Levels of the lines as the frame started: bit 0 Line0 (the trigger input), bit 1 "
                             "Line1 (the strobe as on the wire: high for the frame under ExposureActive, low if inverted)."),
                         kChunkLineStatusAll));

  // SFNC UserSetControl: what a set holds is GigeDevice::UserSetRegisters (docs/gige.md, User sets).
  const char* us = "UserSetControl";
  std::vector<EnumEntry> sets;
  for (int64_t i = 0; i < kUserSetCount; ++i) sets.push_back({UserSetName(i), i});
  t.push_back(Enum("UserSetSelector", us, kUserSetSelector, true, sets,
                   "The user set UserSetLoad and UserSetSave act on (Default: the start-up configuration)."));
  t.back().selects = {"UserSetLoad", "UserSetSave"};
  t.push_back(Cmd("UserSetLoad", us, kUserSetLoad, 1,
                  "Loads the selected set's settings (through the same checks as a client's writes; not while "
                  "acquiring)."));
  t.back().locked_while_acquiring = true;
  t.push_back(Cmd("UserSetSave", us, kUserSetSave, 1,
                  "Saves the current settings as the selected set (not Default, which is read-only); kept in "
                  "the --user-set-file when the device has one, else for the process."));
  t.back().available_formula = "S<>" + std::to_string(kUserSetDefaultSet);
  t.back().variables = {{"S", "UserSetSelector"}};
  t.push_back(Enum("UserSetDefault", us, kUserSetDefault, true, sets, "The user set loaded at start."));

  const char* sim = "Simulation";
  t.push_back(Int("SimSceneCount", sim, kSimSceneCount, false, s.scene_count, s.scene_count, 1, "Scenes loaded."));
  t.push_back(Int("SimSceneFrame", sim, kSimSceneFrame, false, 0, s.scene_count - 1, 1,
                  "Scene the next frame is rendered from: SimFrameIndex modulo SimSceneCount (as `camsim run`)."));
  t.push_back(Int("SimFrameIndex", sim, kSimFrameIndex, true, 0, 0x7fffffff, 1,
                  "Frame index of the next frame (keys the noise; `camsim run --first-frame`)."));
  t.push_back(Flt("SimFNumber", sim, kSimFNumber, 0.5, 128.0, "Lens f-number.", ""));
  t.push_back(Flt("SimFocusDistance", sim, kSimFocusDistance, s.min_focus_distance_m, kMaxFocusDistanceM,
                  "Focus distance of the depth of field (the dof stage; it must exceed the focal length).", "m"));
  t.push_back(Int("SimSeed", sim, kSimSeed, true, 0, 0x7fffffff, 1, "Seed of all randomness."));
  std::vector<EnumEntry> stages;
  for (size_t i = 0; i < s.stage_names.size(); ++i)
    stages.push_back({"Stage_" + s.stage_names[i], static_cast<int64_t>(i)});
  if (stages.empty()) stages.push_back({"Stage_none", 0});
  t.push_back(Enum("SimStageSelector", sim, kSimStageSelector, true, stages, "Configured stage SimStageEnable acts on."));
  t.back().selects = {"SimStageEnable"};
  t.push_back(Selected(Bool("SimStageEnable", sim, kSimStageEnable, true, "Whether the selected stage runs."),
                       "SimStageSelector", static_cast<int>(stages.size())));
  t.push_back(Int("SimSyncCount", sim, kSimSyncCount, false, 0, 0xffffffff, 1,
                  "Register syncs completed: two more than when a write was sent means the write was checked "
                  "and applied (or refused)."));
  // At most 0.9: the core's controller needs the target below its saturated level (core/control/auto_exposure.h).
  t.push_back(Flt("SimAutoTarget", sim, kSimAutoTarget, 0.01, 0.9,
                  "Mean raw level (fraction of full scale) the Auto features aim for.", ""));
  return t;
}

std::vector<Feature> FeatureRegisters(const std::vector<Feature>& table) {
  std::vector<Feature> out;
  for (const Feature& f : table) {
    if (f.chunk_id != 0) continue;  // in each frame, not in device memory
    if (f.selected_by.empty()) {
      out.push_back(f);
      std::erase_if(out.back().entries, [](const EnumEntry& e) { return !e.available; });
      continue;
    }
    for (int i = 0; i < f.selections; ++i) {
      Feature r = f;
      r.name = f.name + "[" + std::to_string(i) + "]";
      r.address = reg::SelectedAddress(f.address, static_cast<size_t>(i), f.length);
      r.selections = 1;
      r.selection = i;
      std::erase_if(r.entries, [i](const EnumEntry& e) {
        return !e.available || (e.only_at_selection >= 0 && e.only_at_selection != i);
      });
      out.push_back(r);
    }
  }
  return out;
}

const Feature* FindFeature(const std::vector<Feature>& table, const std::string& name) {
  for (const Feature& f : table)
    if (f.name == name) return &f;
  return nullptr;
}

// The node a payload feature's pIsLocked names: 1 during an acquisition (the
// fake camera's acquisition register) or while TLParamsLocked is 1.
constexpr char kPayloadLocked[] = "PayloadLocked";
// Where the VersionGuid goes once the rest of the file is known.
constexpr char kVersionGuidMark[] = "@VERSION_GUID@";

std::string GenerateXml(const std::vector<Feature>& table, const DeviceStrings& d) {
  std::ostringstream x;
  std::ostringstream swiss_knives;  // the entries' availability nodes, after the features
  std::set<std::string> selections;  // "Feature[i]" a formula reads (VariableNode)
  x << "<?xml version=\"1.0\" encoding=\"utf-8\"?>\n"
    << "<!-- Generated by camsim-gige from genicam/register_table.cc; do not edit. -->\n"
    << "<RegisterDescription ModelName=\"" << Xml(d.model) << "\" VendorName=\"" << Xml(d.vendor)
    << "\" StandardNameSpace=\"GEV\" SchemaMajorVersion=\"1\" SchemaMinorVersion=\"0\" SchemaSubMinorVersion=\"1\""
    << " MajorVersion=\"0\" MinorVersion=\"1\" SubMinorVersion=\"0\" ToolTip=\"camsim emulated camera\""
    << " ProductGuid=\"5e1c0a52-6d1f-4c4e-9a3e-63616d73696d\" VersionGuid=\"" << kVersionGuidMark << "\""
    << " xmlns=\"http://www.genicam.org/GenApi/Version_1_0\""
    << " xmlns:xsi=\"http://www.w3.org/2001/XMLSchema-instance\""
    << " xsi:schemaLocation=\"http://www.genicam.org/GenApi/Version_1_0 GenApiSchema.xsd\">\n";
  std::vector<std::string> categories;
  for (const Feature& f : table) {
    bool seen = false;
    for (const std::string& c : categories) seen = seen || c == f.category;
    if (!seen) categories.push_back(f.category);
  }
  x << "  <Category Name=\"Root\" NameSpace=\"Standard\">\n";
  for (const std::string& c : categories)
    x << "    <pFeature>" << c << "</pFeature>\n";
  x << "  </Category>\n";
  for (const std::string& c : categories) {
    x << "  <Category Name=\"" << c << "\" NameSpace=\"" << (c == "Simulation" ? "Custom" : "Standard") << "\">\n";
    for (const Feature& f : table)
      if (f.category == c) x << "    <pFeature>" << f.name << "</pFeature>\n";
    x << "  </Category>\n";
  }
  for (const Feature& f : table) {
    const std::string ns = IsStandard(f.name) ? "Standard" : "Custom";
    const std::string regname = (f.alias_of.empty() ? f.name : f.alias_of) + "Reg";
    const std::string access = f.writable ? "RW" : "RO";
    const std::string head =
        "  <!-- " + (f.chunk_id != 0 ? "chunk " + Hex(f.chunk_id) + ", at " : std::string()) + Hex(f.address) + " -->\n";
    const std::string locked =
        f.locked_while_acquiring ? std::string("    <pIsLocked>") + kPayloadLocked + "</pIsLocked>\n"
        : f.locked_formula.empty() ? ""
                                   : "    <pIsLocked>" + f.name + "Locked</pIsLocked>\n";
    if (!f.locked_while_acquiring && !f.locked_formula.empty()) {
      swiss_knives << "  <IntSwissKnife Name=\"" << f.name << "Locked\" NameSpace=\"Custom\">\n";
      for (const auto& v : f.variables)
        swiss_knives << "    <pVariable Name=\"" << v.first << "\">" << VariableNode(v.second) << "</pVariable>\n";
      swiss_knives << "    <Formula>" << Xml(f.locked_formula) << "</Formula>\n  </IntSwissKnife>\n";
    }
    // Written after the Description, with pIsLocked (GenApi's order).
    const std::string available =
        f.available_formula.empty() ? "" : "    <pIsAvailable>" + f.name + "Available</pIsAvailable>\n";
    if (!f.available_formula.empty()) {
      swiss_knives << "  <IntSwissKnife Name=\"" << f.name << "Available\" NameSpace=\"Custom\">\n";
      for (const auto& v : f.variables)
        swiss_knives << "    <pVariable Name=\"" << v.first << "\">" << VariableNode(v.second) << "</pVariable>\n";
      swiss_knives << "    <Formula>" << Xml(f.available_formula) << "</Formula>\n  </IntSwissKnife>\n";
    }
    if (f.kind == Kind::kSwissKnife) {
      x << "  <IntSwissKnife Name=\"" << f.name << "\" NameSpace=\"" << ns << "\">\n"
        << "    <Description>" << Xml(f.description) << "</Description>\n";
      for (const auto& v : f.variables) {
        x << "    <pVariable Name=\"" << v.first << "\">" << VariableNode(v.second) << "</pVariable>\n";
        if (v.second.find('[') != std::string::npos) selections.insert(v.second);
      }
      x << "    <Formula>" << Xml(f.formula) << "</Formula>\n  </IntSwissKnife>\n";
      continue;
    }
    if (f.kind == Kind::kString) {
      x << head << "  <StringReg Name=\"" << f.name << "\" NameSpace=\"" << ns << "\">\n"
        << "    <Description>" << Xml(f.description) << "</Description>\n"
        << "    <Address>" << Hex(f.address) << "</Address>\n    <Length>" << f.length << "</Length>\n"
        << "    <AccessMode>" << access << "</AccessMode>\n    <pPort>Device</pPort>\n"
        << "  </StringReg>\n";
      continue;
    }
    x << head;
    switch (f.kind) {
      case Kind::kInteger:
        x << "  <Integer Name=\"" << f.name << "\" NameSpace=\"" << ns << "\">\n"
          << "    <Description>" << Xml(f.description) << "</Description>\n" << available << locked
          << "    <pValue>" << regname << "</pValue>\n"
          << "    <Min>" << static_cast<int64_t>(f.min) << "</Min>\n";
        if (f.max_formula.empty()) x << "    <Max>" << static_cast<int64_t>(f.max) << "</Max>\n";
        else x << "    <pMax>" << f.name << "MaxNow</pMax>\n";
        x << "    <Inc>" << static_cast<int64_t>(f.inc) << "</Inc>\n";
        if (!f.unit.empty()) x << "    <Unit>" << f.unit << "</Unit>\n";
        x << "  </Integer>\n";
        if (!f.max_formula.empty()) {
          x << "  <IntSwissKnife Name=\"" << f.name << "MaxNow\" NameSpace=\"Custom\">\n";
          for (const auto& v : f.variables)
            x << "    <pVariable Name=\"" << v.first << "\">" << v.second << "Reg</pVariable>\n";
          x << "    <Formula>" << Xml(f.max_formula) << "</Formula>\n  </IntSwissKnife>\n";
        }
        break;
      case Kind::kFloat:
        x << "  <Float Name=\"" << f.name << "\" NameSpace=\"" << ns << "\">\n"
          << "    <Description>" << Xml(f.description) << "</Description>\n" << available << locked
          << "    <pValue>" << regname << "</pValue>\n";
        if (f.min_feature.empty()) x << "    <Min>" << Num(f.min) << "</Min>\n";
        else x << "    <pMin>" << f.min_feature << "Reg</pMin>\n";
        if (f.max_feature.empty()) x << "    <Max>" << Num(f.max) << "</Max>\n";
        else x << "    <pMax>" << f.max_feature << "Reg</pMax>\n";
        if (f.inc > 0) x << "    <Inc>" << Num(f.inc) << "</Inc>\n";  // the step values are applied in
        if (!f.unit.empty()) x << "    <Unit>" << f.unit << "</Unit>\n";
        x << "  </Float>\n";
        break;
      case Kind::kEnum:
        x << "  <Enumeration Name=\"" << f.name << "\" NameSpace=\"" << ns << "\">\n"
          << "    <Description>" << Xml(f.description) << "</Description>\n" << available << locked;
        for (const EnumEntry& e : f.entries) {
          x << "    <EnumEntry Name=\"" << e.name << "\" NameSpace=\""
            << (IsStandard(f.name) && IsStandard(e.name) ? "Standard" : "Custom")
            << "\">\n";
          if (e.only_at_selection >= 0 || !e.available || e.readout >= 0 || !e.available_formula.empty())
            x << "      <pIsAvailable>" << f.name << e.name << "Available</pIsAvailable>\n";
          if (!e.available)
            swiss_knives << "  <Integer Name=\"" << f.name << e.name << "Available\" NameSpace=\"Custom\">\n"
                         << "    <Value>0</Value>\n  </Integer>\n";
          x << "      <Value>" << e.value << "</Value>\n    </EnumEntry>\n";
          if (!e.available_formula.empty()) {
            swiss_knives << "  <IntSwissKnife Name=\"" << f.name << e.name << "Available\" NameSpace=\"Custom\">\n";
            for (const auto& v : e.variables)
              swiss_knives << "    <pVariable Name=\"" << v.first << "\">" << VariableNode(v.second) << "</pVariable>\n";
            swiss_knives << "    <Formula>" << Xml(e.available_formula) << "</Formula>\n  </IntSwissKnife>\n";
          }
          if (e.only_at_selection >= 0)
            swiss_knives << "  <IntSwissKnife Name=\"" << f.name << e.name << "Available\" NameSpace=\"Custom\">\n"
                         << "    <pVariable Name=\"S\">" << f.selected_by << "Reg</pVariable>\n"
                         << "    <Formula>S=" << e.only_at_selection << "</Formula>\n  </IntSwissKnife>\n";
          if (e.readout >= 0)
            swiss_knives << "  <IntSwissKnife Name=\"" << f.name << e.name << "Available\" NameSpace=\"Custom\">\n"
                         << "    <pVariable Name=\"X\">ReverseXReg</pVariable>\n"
                         << "    <pVariable Name=\"Y\">ReverseYReg</pVariable>\n"
                         << "    <Formula>X+2*Y=" << e.readout << "</Formula>\n  </IntSwissKnife>\n";
        }
        x << "    <pValue>" << regname << "</pValue>\n";
        for (const std::string& selected : f.selects) x << "    <pSelected>" << selected << "</pSelected>\n";
        x << "  </Enumeration>\n";
        break;
      case Kind::kBoolean:
        x << "  <Boolean Name=\"" << f.name << "\" NameSpace=\"" << ns << "\">\n"
          << "    <Description>" << Xml(f.description) << "</Description>\n"
          << available << locked << "    <pValue>" << regname << "</pValue>\n    <OnValue>1</OnValue>\n    <OffValue>0</OffValue>\n"
          << "  </Boolean>\n";
        break;
      case Kind::kCommand:
        x << "  <Command Name=\"" << f.name << "\" NameSpace=\"" << ns << "\">\n"
          << "    <Description>" << Xml(f.description) << "</Description>\n" << available << locked
          << "    <pValue>" << regname << "</pValue>\n    <CommandValue>" << f.command_value << "</CommandValue>\n"
          << "  </Command>\n";
        break;
      case Kind::kString:
      case Kind::kSwissKnife: break;
    }
    if (!f.alias_of.empty()) continue;  // the register node is the original's
    const bool is_float = f.kind == Kind::kFloat, masked = f.low_bits > 0;
    const char* reg_kind = is_float ? "FloatReg" : (masked ? "MaskedIntReg" : "IntReg");
    x << "  <" << reg_kind << " Name=\"" << regname << "\" NameSpace=\"Custom\">\n"
      << "    <Address>" << Hex(f.address) << "</Address>\n";
    if (!f.selected_by.empty())
      x << "    <pIndex Offset=\"" << f.length << "\">" << f.selected_by << "Reg</pIndex>\n";
    const std::string port = f.chunk_id != 0 ? f.name + "Port" : "Device";
    x << "    <Length>" << f.length << "</Length>\n"
      << "    <AccessMode>" << access << "</AccessMode>\n    <pPort>" << port << "</pPort>\n"
      << "    <Cachable>NoCache</Cachable>\n";
    // Big-endian bit numbers count from the most significant bit (0).
    if (masked)
      x << "    <LSB>" << f.length * 8 - 1 - f.shift << "</LSB>\n    <MSB>" << f.length * 8 - f.shift - f.low_bits
        << "</MSB>\n";
    if (!is_float) x << "    <Sign>Unsigned</Sign>\n";
    x << "    <Endianess>BigEndian</Endianess>\n  </" << reg_kind << ">\n";
    if (f.chunk_id != 0) {
      char id[16];
      std::snprintf(id, sizeof id, "%08X", f.chunk_id);
      x << "  <Port Name=\"" << port << "\" NameSpace=\"Custom\">\n    <ChunkID>" << id << "</ChunkID>\n  </Port>\n";
    }
  }
  x << swiss_knives.str();
  // The registers of single selections that formulas read.
  for (const std::string& s : selections) {
    const size_t open = s.find('[');
    const Feature* f = FindFeature(table, s.substr(0, open));
    const uint32_t i = static_cast<uint32_t>(std::stoul(s.substr(open + 1)));
    x << "  <IntReg Name=\"" << VariableNode(s) << "\" NameSpace=\"Custom\">\n"
      << "    <Address>" << Hex(reg::SelectedAddress(f->address, i)) << "</Address>\n    <Length>4</Length>\n"
      << "    <AccessMode>RO</AccessMode>\n    <pPort>Device</pPort>\n    <Cachable>NoCache</Cachable>\n"
      << "    <Sign>Unsigned</Sign>\n    <Endianess>BigEndian</Endianess>\n  </IntReg>\n";
  }
  x << "  <IntSwissKnife Name=\"" << kPayloadLocked << "\" NameSpace=\"Custom\">\n"
    << "    <pVariable Name=\"T\">TLParamsLockedReg</pVariable>\n"
    << "    <pVariable Name=\"A\">AcquisitionActiveReg</pVariable>\n"
    << "    <Formula>(T&lt;&gt;0)||(A&lt;&gt;0)</Formula>\n  </IntSwissKnife>\n"
    << "  <IntReg Name=\"AcquisitionActiveReg\" NameSpace=\"Custom\">\n"
    << "    <Address>" << Hex(reg::kAcquisition) << "</Address>\n    <Length>4</Length>\n"
    << "    <AccessMode>RO</AccessMode>\n    <pPort>Device</pPort>\n    <Cachable>NoCache</Cachable>\n"
    << "    <Sign>Unsigned</Sign>\n    <Endianess>BigEndian</Endianess>\n  </IntReg>\n";
  x << "  <Port Name=\"Device\" NameSpace=\"Standard\"/>\n</RegisterDescription>\n";
  // The VersionGuid changes with the content (clients cache node maps by it):
  // its last 64 bits are an FNV-1a hash of the file with the mark in place.
  std::string xml = x.str();
  uint64_t hash = 14695981039346656037ull;
  for (const char c : xml) hash = (hash ^ static_cast<unsigned char>(c)) * 1099511628211ull;
  char guid[37];
  std::snprintf(guid, sizeof guid, "5e1c0a52-6d1f-4c4e-%04x-%012llx", static_cast<unsigned>(hash >> 48),
                static_cast<unsigned long long>(hash & 0xffffffffffffull));
  const size_t at = xml.find(kVersionGuidMark);
  xml.replace(at, sizeof kVersionGuidMark - 1, guid);
  return xml;
}

}  // namespace camsim::genicam
