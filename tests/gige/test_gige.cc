// camsim-gige: the register table and its XML, the wire format, the GPIO HAL,
// and end-to-end runs of the device on 127.0.0.1 with Aravis's client API.
#include <gtest/gtest.h>
#include <arpa/inet.h>
#include <netinet/in.h>
#include <png.h>
#include <poll.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/un.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <iterator>
#include <latch>
#include <map>
#include <mutex>
#include <set>
#include <thread>

#include "genicam/fake_camera_hooks.h"
#include "tests/gige/gige_client.h"
#include "tests/support/exr_fixture.h"

namespace camsim::gigetest {
namespace {

using genicam::DeviceOptions;
using genicam::GigeDevice;
namespace reg = genicam::reg;

void Sleep(int ms) { std::this_thread::sleep_for(std::chrono::milliseconds(ms)); }
// Settle (gige_client.h) through the fixture's client.
Client* g_client = nullptr;
void Settle() {
  if (!g_client) return Sleep(400);
  gigetest::Settle(*g_client);
}

// Waits until a feature reads `want` (the device's sync runs every 2 ms).
int64_t ReadInt(Client& c, const char* name) { return arv_camera_get_integer(c.camera(), name, nullptr); }
double ReadFloat(Client& c, const char* name) { return arv_camera_get_float(c.camera(), name, nullptr); }

// A frame's chunks through Aravis's chunk parser, and its image.
struct ChunkedFrame {
  bool ok = false;
  std::vector<uint8_t> image;      // the image chunk (padded to 4 bytes)
  bool has_chunks = false;
  uint64_t frame_id = 0, timestamp = 0, timestamp_chunk = 0;
  std::map<std::string, double> values;  // chunk features found
  std::vector<std::string> missing;      // chunk features not found
  std::string pixel_format;              // ChunkPixelFormat's entry ("" when missing)
};
ChunkedFrame GrabChunked(Client& c, ArvChunkParser* parser) {
  ChunkedFrame out;
  ArvBuffer* b = arv_stream_timeout_pop_buffer(c.stream(), 3000 * 1000);
  if (b == nullptr) return out;
  out.ok = arv_buffer_get_status(b) == ARV_BUFFER_STATUS_SUCCESS;
  out.has_chunks = out.ok && arv_buffer_has_chunks(b);
  out.frame_id = arv_buffer_get_frame_id(b);
  out.timestamp = arv_buffer_get_timestamp(b);
  if (out.has_chunks) {
    size_t size = 0;
    const auto* image = static_cast<const uint8_t*>(arv_buffer_get_chunk_data(b, genicam::kChunkIdImage, &size));
    if (image != nullptr) out.image.assign(image, image + size);
    for (const char* name : {"ChunkTimestamp", "ChunkFrameID", "ChunkSimFrameIndex", "ChunkExposureTime", "ChunkGain",
                             "ChunkOffsetX", "ChunkOffsetY", "ChunkWidth", "ChunkHeight", "ChunkBlackLevel",
                             "ChunkLineStatusAll"}) {
      GError* e = nullptr;
      const bool is_float = std::strcmp(name, "ChunkExposureTime") == 0 || std::strcmp(name, "ChunkGain") == 0 ||
                            std::strcmp(name, "ChunkBlackLevel") == 0;
      const double v = is_float ? arv_chunk_parser_get_float_value(parser, b, name, &e)
                                : static_cast<double>(arv_chunk_parser_get_integer_value(parser, b, name, &e));
      if (e == nullptr) out.values[name] = v;
      else out.missing.push_back(name);
      g_clear_error(&e);
    }
    GError* e = nullptr;
    const char* format = arv_chunk_parser_get_string_value(parser, b, "ChunkPixelFormat", &e);
    if (e == nullptr && format != nullptr) out.pixel_format = format;
    else out.missing.push_back("ChunkPixelFormat");
    g_clear_error(&e);
    // The timestamp exactly (a double holds it to ~256 ns).
    out.timestamp_chunk = static_cast<uint64_t>(arv_chunk_parser_get_integer_value(parser, b, "ChunkTimestamp", nullptr));
  } else if (out.ok) {
    size_t size = 0;
    const auto* data = static_cast<const uint8_t*>(arv_buffer_get_data(b, &size));
    out.image.assign(data, data + size);
  }
  arv_stream_push_buffer(c.stream(), b);
  return out;
}

// Mean raw level (above black, fraction of full scale) of a BayerRG12 frame.
double MeanLevel12(const std::vector<uint8_t>& f) {
  double sum = 0;
  for (size_t i = 0; i + 1 < f.size(); i += 2) sum += f[i] | (f[i + 1] << 8);
  return (sum / (f.size() / 2) - 64.0) / (4095.0 - 64.0);  // black level 64 DN (demo camera)
}

// A small device without network (DeviceOptions::serve false): the tests
// drive it with WriteMemory, SyncNow and RenderNow.
DeviceOptions OfflineDevice() {
  DeviceOptions o = SmallDevice();
  o.serve = false;
  return o;
}

// A small mono sensor (Mono formats, odd windows allowed).
DeviceOptions SmallMonoDevice() {
  DeviceOptions o = SmallDevice(32, 24);
  o.overrides.push_back("sensor.cfa=\"Mono\"");
  return o;
}

std::unique_ptr<GigeDevice> StartDevice(const DeviceOptions& o) {
  std::string error;
  auto d = GigeDevice::Start(o, &error);
  EXPECT_NE(d, nullptr) << error;
  return d;
}

// The SimStageEnable register of a configured stage (its selector entry,
// e.g. "Stage_sensor"), or 0 when the device has no such stage.
uint32_t StageEnableAddress(const GigeDevice& d, const std::string& entry) {
  const genicam::Feature* selector = genicam::FindFeature(d.table(), "SimStageSelector");
  if (selector != nullptr)
    for (const genicam::EnumEntry& e : selector->entries)
      if (e.name == entry) return genicam::reg::SelectedAddress(reg::kSimStageEnable, static_cast<size_t>(e.value));
  return 0;
}

void Set(Client& c, const char* feature, const char* value) {
  GError* e = nullptr;
  arv_camera_set_string(c.camera(), feature, value, &e);
  ASSERT_EQ(e, nullptr) << feature << "=" << value << ": " << e->message;
}
void SetInt(Client& c, const char* feature, int64_t value) {
  GError* e = nullptr;
  arv_camera_set_integer(c.camera(), feature, value, &e);
  ASSERT_EQ(e, nullptr) << feature << ": " << e->message;
}
void SetFloat(Client& c, const char* feature, double value) {
  GError* e = nullptr;
  arv_camera_set_float(c.camera(), feature, value, &e);
  ASSERT_EQ(e, nullptr) << feature << ": " << e->message;
}
void Start(Client& c) {
  GError* e = nullptr;
  arv_camera_start_acquisition(c.camera(), &e);
  ASSERT_EQ(e, nullptr) << e->message;
}

// Register bytes as a client sends them (big-endian; Float: an 8-byte double).
std::vector<uint8_t> Be32(uint32_t v) { return {uint8_t(v >> 24), uint8_t(v >> 16), uint8_t(v >> 8), uint8_t(v)}; }
std::vector<uint8_t> Be64(double x) {
  uint64_t v;
  std::memcpy(&v, &x, 8);
  std::vector<uint8_t> b(8);
  for (int i = 0; i < 8; ++i) b[i] = uint8_t(v >> (56 - 8 * i));
  return b;
}
// Register access on a device without network (DeviceOptions::serve false).
void WriteReg(GigeDevice& d, uint32_t address, const std::vector<uint8_t>& bytes) {
  ASSERT_TRUE(d.WriteMemory(address, bytes.data(), static_cast<uint32_t>(bytes.size())));
}
// A write the device refuses as it arrives (a value the feature never takes,
// the payload's registers while acquiring).
void WriteRegRefused(GigeDevice& d, uint32_t address, const std::vector<uint8_t>& bytes) {
  ASSERT_FALSE(d.WriteMemory(address, bytes.data(), static_cast<uint32_t>(bytes.size())));
}
uint32_t ReadReg32(const GigeDevice& d, uint32_t address) {
  uint8_t b[4] = {};
  EXPECT_TRUE(d.ReadMemory(address, b, 4));
  return uint32_t(b[0]) << 24 | uint32_t(b[1]) << 16 | uint32_t(b[2]) << 8 | b[3];
}
double ReadRegDouble(const GigeDevice& d, uint32_t address) {
  uint8_t b[8] = {};
  EXPECT_TRUE(d.ReadMemory(address, b, 8));
  uint64_t v = 0;
  for (int i = 0; i < 8; ++i) v = v << 8 | b[i];
  double x;
  std::memcpy(&x, &v, 8);
  return x;
}

// ---------------------------------------------------------------- XML / table

TEST(GigeRegisterTable, XmlLoadsInAravisAndMatchesTheTable) {
  genicam::SensorInfo s;
  s.width = 1920;
  s.height = 1080;
  s.cfa = Cfa::kBayerGB;
  s.adc_bits = 12;
  s.max_black_level_dn = 1023;
  s.scene_count = 3;
  s.has_isp_rgb = true;
  s.stage_names = {"exposure", "sensor", "gamma"};
  s.has_gamma = true;  // Gamma, GammaEnable
  const auto table = genicam::RegisterTable(s);
  const std::string xml = genicam::GenerateXml(table, genicam::DeviceStrings());
  ArvGc* gc = arv_gc_new(nullptr, xml.data(), xml.size());
  ASSERT_NE(gc, nullptr);
  int checked = 0;
  for (const genicam::Feature& f : table) {
    ArvGcNode* node = arv_gc_get_node(gc, f.name.c_str());
    ASSERT_NE(node, nullptr) << f.name;
    if (f.kind == genicam::Kind::kSwissKnife) continue;
    if (f.kind == genicam::Kind::kString) {
      ASSERT_TRUE(ARV_IS_GC_REGISTER(node)) << f.name;
      EXPECT_EQ(arv_gc_register_get_address(ARV_GC_REGISTER(node), nullptr), f.address) << f.name;
      ++checked;
      continue;
    }
    const std::string reg_name = (f.alias_of.empty() ? f.name : f.alias_of) + "Reg";
    ArvGcNode* r = arv_gc_get_node(gc, reg_name.c_str());
    ASSERT_NE(r, nullptr) << reg_name;
    ASSERT_TRUE(ARV_IS_GC_REGISTER(r)) << reg_name;
    // A selected feature's address reads its selector from the device:
    // GigeE2E.SelectedRegistersFollowTheSelector checks it there.
    if (f.selected_by.empty()) {
      EXPECT_EQ(arv_gc_register_get_address(ARV_GC_REGISTER(r), nullptr), f.address) << f.name;
    }
    EXPECT_EQ(ARV_IS_GC_MASKED_INT_REG_NODE(r), f.low_bits > 0) << f.name;
    if (f.kind == genicam::Kind::kInteger) {
      EXPECT_EQ(arv_gc_integer_get_min(ARV_GC_INTEGER(node), nullptr), static_cast<int64_t>(f.min)) << f.name;
      // A pMax reads the device: GigeE2E.WindowMaximaLeaveRoomForTheOtherFeature checks it there.
      if (f.max_formula.empty()) {
        EXPECT_EQ(arv_gc_integer_get_max(ARV_GC_INTEGER(node), nullptr), static_cast<int64_t>(f.max)) << f.name;
      }
      EXPECT_EQ(arv_gc_integer_get_inc(ARV_GC_INTEGER(node), nullptr), static_cast<int64_t>(f.inc)) << f.name;
    }
    if (f.kind == genicam::Kind::kFloat) {
      // A pMin or pMax reads the device: GigeE2E.AutoLimitsAreFeaturesBoundingEachOther checks it there.
      if (f.min_feature.empty()) {
        EXPECT_EQ(arv_gc_float_get_min(ARV_GC_FLOAT(node), nullptr), f.min) << f.name;
      }
      if (f.max_feature.empty()) {
        EXPECT_EQ(arv_gc_float_get_max(ARV_GC_FLOAT(node), nullptr), f.max) << f.name;
      }
      if (f.inc > 0) {  // Gain: GainRaw's step
        EXPECT_EQ(arv_gc_float_get_inc(ARV_GC_FLOAT(node), nullptr), f.inc) << f.name;
      }
    }
    if (f.kind == genicam::Kind::kEnum) {
      // Aravis keeps the entries in reverse order: compare as name -> value maps.
      std::map<std::string, int64_t> got, want;
      for (const GSList* e = arv_gc_enumeration_get_entries(ARV_GC_ENUMERATION(node)); e; e = e->next)
        got[arv_gc_feature_node_get_name(ARV_GC_FEATURE_NODE(e->data))] =
            arv_gc_enum_entry_get_value(ARV_GC_ENUM_ENTRY(e->data), nullptr);
      for (const genicam::EnumEntry& e : f.entries) want[e.name] = e.value;
      EXPECT_EQ(got, want) << f.name;
      // A selector names what it selects (GenICam pSelected): clients walk
      // it to save and restore every selected value.
      ArvGcSelector* selector = ARV_GC_SELECTOR(node);
      EXPECT_EQ(arv_gc_selector_is_selector(selector), !f.selects.empty()) << f.name;
      std::vector<std::string> selected;
      for (const GSList* e = arv_gc_selector_get_selected_features(selector); e; e = e->next)
        selected.push_back(arv_gc_feature_node_get_name(ARV_GC_FEATURE_NODE(e->data)));
      std::sort(selected.begin(), selected.end());
      std::vector<std::string> want_selected = f.selects;
      std::sort(want_selected.begin(), want_selected.end());
      EXPECT_EQ(selected, want_selected) << f.name;
    }
    ++checked;
  }
  EXPECT_GT(checked, 40);
  // Pixel formats for this sensor: the PFNC codes Aravis knows.
  const genicam::Feature* pf = genicam::FindFeature(table, "PixelFormat");
  ASSERT_NE(pf, nullptr);
  std::vector<std::string> names;
  for (const auto& e : pf->entries) names.push_back(e.name);
  // The sensor's phase first; then those ReverseX, ReverseY and both read out.
  EXPECT_EQ(names, (std::vector<std::string>{
                       "BayerGB12", "BayerGB8", "BayerGB16", "BayerGB12p", "BayerGB12Packed",  //
                       "BayerBG12", "BayerBG8", "BayerBG16", "BayerBG12p", "BayerBG12Packed",  //
                       "BayerRG12", "BayerRG8", "BayerRG16", "BayerRG12p", "BayerRG12Packed",  //
                       "BayerGR12", "BayerGR8", "BayerGR16", "BayerGR12p", "BayerGR12Packed",  //
                       "Mono8", "RGB8", "BGR8", "YCbCr422_8", "YUV422_8", "YUV422_8_UYVY"}));
  EXPECT_EQ(genicam::BayerCode(Cfa::kBayerGB, 12), static_cast<uint32_t>(ARV_PIXEL_FORMAT_BAYER_GB_12));
  EXPECT_EQ(genicam::BayerCode(Cfa::kBayerRG, 8), static_cast<uint32_t>(ARV_PIXEL_FORMAT_BAYER_RG_8));
  EXPECT_EQ(genicam::BayerCode(Cfa::kBayerBG, 16), static_cast<uint32_t>(ARV_PIXEL_FORMAT_BAYER_BG_16));
  EXPECT_EQ(genicam::kRGB8, static_cast<uint32_t>(ARV_PIXEL_FORMAT_RGB_8_PACKED));
  EXPECT_EQ(genicam::kBGR8, static_cast<uint32_t>(ARV_PIXEL_FORMAT_BGR_8_PACKED));
  EXPECT_EQ(genicam::kMono12, static_cast<uint32_t>(ARV_PIXEL_FORMAT_MONO_12));
  EXPECT_EQ(genicam::kMono10, static_cast<uint32_t>(ARV_PIXEL_FORMAT_MONO_10));
  EXPECT_EQ(genicam::BayerCode(Cfa::kBayerGR, 10), static_cast<uint32_t>(ARV_PIXEL_FORMAT_BAYER_GR_10));
  EXPECT_EQ(genicam::BayerCode(Cfa::kBayerBG, 10), static_cast<uint32_t>(ARV_PIXEL_FORMAT_BAYER_BG_10));
  // Packed (Aravis 0.8.26 names no Mono10p/Mono12p: PFNC 0x010A0046, 0x010C0047).
  using genicam::Packing;
  EXPECT_EQ(genicam::PackedCode(Cfa::kBayerGB, 12, Packing::kPfnc), ARV_PIXEL_FORMAT_BAYER_GB_12P);
  EXPECT_EQ(genicam::PackedCode(Cfa::kBayerRG, 12, Packing::kPfnc), ARV_PIXEL_FORMAT_BAYER_RG_12P);
  EXPECT_EQ(genicam::PackedCode(Cfa::kBayerGR, 10, Packing::kPfnc), ARV_PIXEL_FORMAT_BAYER_GR_10P);
  EXPECT_EQ(genicam::PackedCode(Cfa::kBayerBG, 10, Packing::kPfnc), ARV_PIXEL_FORMAT_BAYER_BG_10P);
  EXPECT_EQ(genicam::PackedCode(Cfa::kBayerRG, 12, Packing::kGigeLegacy), ARV_PIXEL_FORMAT_BAYER_RG_12_PACKED);
  EXPECT_EQ(genicam::PackedCode(Cfa::kBayerBG, 12, Packing::kGigeLegacy), ARV_PIXEL_FORMAT_BAYER_BG_12_PACKED);
  EXPECT_EQ(genicam::PackedCode(Cfa::kMono, 12, Packing::kGigeLegacy), ARV_PIXEL_FORMAT_MONO_12_PACKED);
  EXPECT_EQ(genicam::PackedCode(Cfa::kMono, 12, Packing::kPfnc), 0x010c0047u);
  EXPECT_EQ(genicam::PackedCode(Cfa::kMono, 10, Packing::kPfnc), 0x010a0046u);
  for (Cfa cfa : {Cfa::kBayerGR, Cfa::kBayerRG, Cfa::kBayerGB, Cfa::kBayerBG, Cfa::kMono}) {
    for (int bits : {10, 12})
      EXPECT_EQ(genicam::PackingOf(genicam::PackedCode(cfa, bits, Packing::kPfnc)), Packing::kPfnc);
    EXPECT_EQ(genicam::PackingOf(genicam::PackedCode(cfa, 12, Packing::kGigeLegacy)), Packing::kGigeLegacy);
    for (int bits : {8, 12, 16})
      EXPECT_EQ(genicam::PackingOf(cfa == Cfa::kMono ? (bits == 8 ? genicam::kMono8 : bits == 12 ? genicam::kMono12
                                                                                           : genicam::kMono16)
                                                     : genicam::BayerCode(cfa, bits)),
                Packing::kNone);
  }
  g_object_unref(gc);
}

// Clients cache a parsed XML by its VersionGuid: another sensor, another
// file, another guid; the same sensor, the same.
TEST(GigeRegisterTable, VersionGuidFollowsTheContent) {
  auto guid_of = [](int width, Cfa cfa) {
    genicam::SensorInfo s;
    s.width = width;
    s.height = 48;
    s.cfa = cfa;
    s.adc_bits = 12;
    s.scene_count = 1;
    const std::string xml = genicam::GenerateXml(genicam::RegisterTable(s), genicam::DeviceStrings());
    const std::string key = "VersionGuid=\"";
    const size_t at = xml.find(key);
    EXPECT_NE(at, std::string::npos);
    return at == std::string::npos ? std::string() : xml.substr(at + key.size(), 36);
  };
  const std::string a = guid_of(64, Cfa::kBayerRG);
  EXPECT_EQ(a.size(), 36u);
  EXPECT_EQ(a[8], '-');
  EXPECT_EQ(a, guid_of(64, Cfa::kBayerRG));
  EXPECT_NE(a, guid_of(96, Cfa::kBayerRG));
  EXPECT_NE(a, guid_of(64, Cfa::kBayerGR));
}

// The bootstrap says what the device is: big-endian registers, UTF-8
// strings, WRITEMEM (a Float can only be written whole), PACKETRESEND, the
// serial number and user name registers. Clients cannot change either.
TEST(GigeRegisters, BootstrapDescribesTheDeviceAndIsReadOnly) {
  auto d = StartDevice(OfflineDevice());
  ASSERT_NE(d, nullptr);
  EXPECT_EQ(ReadReg32(*d, reg::kDeviceMode), 0x80000001u);
  const uint32_t caps = ReadReg32(*d, reg::kGvcpCapability);
  EXPECT_EQ(caps, (1u << 31) | (1u << 30) | (1u << 2) | (1u << 1)) << std::hex << caps;
  WriteRegRefused(*d, reg::kDeviceMode, Be32(0));
  WriteRegRefused(*d, reg::kGvcpCapability, Be32(0xffffffff));
  EXPECT_EQ(ReadReg32(*d, reg::kDeviceMode), 0x80000001u);
  EXPECT_EQ(ReadReg32(*d, reg::kGvcpCapability), caps);
}

uint64_t ReadReg64(const GigeDevice& d, uint32_t address) {
  return uint64_t{ReadReg32(d, address)} << 32 | ReadReg32(d, address + 4);
}

// The transport layer's bootstrap: GigE Vision 2.0, a MAC address per serial
// (locally administered, stable, different for a rig's cameras), the
// heartbeat timeout's range, and a timestamp that a latch copies and a reset
// restarts (ns, the frames' clock).
TEST(GigeRegisters, TheBootstrapSaysVersionMacAndTime) {
  auto d = StartDevice(OfflineDevice());
  ASSERT_NE(d, nullptr);
  EXPECT_EQ(ReadReg32(*d, reg::kVersion), 0x00020000u);
  const uint64_t mac = ReadReg64(*d, reg::kMacHigh);
  EXPECT_EQ(mac >> 40, 0x02u) << std::hex << mac;  // locally administered, unicast, 48 bits
  DeviceOptions other = OfflineDevice();
  other.serial = "CS0002";
  auto d2 = StartDevice(other);
  ASSERT_NE(d2, nullptr);
  EXPECT_NE(ReadReg64(*d2, reg::kMacHigh), mac) << "two cameras of a rig, one MAC";
  d2.reset();
  d2 = StartDevice(OfflineDevice());
  ASSERT_NE(d2, nullptr);
  EXPECT_EQ(ReadReg64(*d2, reg::kMacHigh), mac) << "the MAC changed between two starts";
  WriteRegRefused(*d, reg::kMacLow, Be32(0));
  WriteRegRefused(*d, reg::kVersion, Be32(0));
  EXPECT_EQ(ReadReg64(*d, reg::kTimestampTickFrequency), 1000000000u);
  // The heartbeat timeout: at least GigE Vision's 500 ms.
  WriteReg(*d, reg::kHeartbeatTimeout, Be32(1000));
  WriteRegRefused(*d, reg::kHeartbeatTimeout, Be32(100));
  EXPECT_EQ(ReadReg32(*d, reg::kHeartbeatTimeout), 1000u);
  // Latch: the device's time now (ns since the epoch until a reset: the
  // host's real time at the start, to its microsecond, then the steady clock).
  const uint64_t before = static_cast<uint64_t>(g_get_real_time()) * 1000;
  WriteReg(*d, reg::kTimestampControl, Be32(reg::kTimestampLatch));
  const uint64_t latched = ReadReg64(*d, reg::kTimestampValue);
  const uint64_t after = static_cast<uint64_t>(g_get_real_time()) * 1000;
  EXPECT_GE(latched + 1000, before);  // (the host clock's microseconds)
  EXPECT_LE(latched, after + 1000);
  EXPECT_EQ(ReadReg32(*d, reg::kTimestampControl), 0u) << "a command reads back 0";
  // Reset and latch in one write: the time before the reset, then from 0.
  WriteReg(*d, reg::kTimestampControl, Be32(reg::kTimestampLatch | reg::kTimestampReset));
  EXPECT_GE(ReadReg64(*d, reg::kTimestampValue) + 1000, after);
  Sleep(20);
  WriteReg(*d, reg::kTimestampControl, Be32(reg::kTimestampLatch));
  const uint64_t since_reset = ReadReg64(*d, reg::kTimestampValue);
  EXPECT_GE(since_reset, 20000000u);
  EXPECT_LT(since_reset, 2000000000u);
  WriteRegRefused(*d, reg::kTimestampControl, Be32(4));
  WriteRegRefused(*d, reg::kTimestampValue, Be32(0));
  d->SyncNow();
  EXPECT_EQ(d->CheckInvariants(), "");
}

TEST(GigeRegisterTable, AddressesDoNotOverlap) {
  genicam::SensorInfo s;
  s.width = 64;
  s.height = 48;
  s.has_white_balance = true;  // BalanceRatio's registers too
  s.has_gamma = true;          // and Gamma's
  // As many stages as a pipeline can have: every SimStageEnable register.
  for (int i = 0; i < kStageCount; ++i) s.stage_names.push_back("stage" + std::to_string(i));
  const auto t = genicam::FeatureRegisters(genicam::RegisterTable(s));
  ASSERT_NE(genicam::FindFeature(t, "SimStageEnable[" + std::to_string(kStageCount - 1) + "]"), nullptr);
  for (size_t i = 0; i < t.size(); ++i)
    for (size_t j = i + 1; j < t.size(); ++j) {
      if (!t[i].alias_of.empty() || !t[j].alias_of.empty()) continue;
      if (t[i].kind == genicam::Kind::kSwissKnife || t[j].kind == genicam::Kind::kSwissKnife) continue;
      // Bit fields of one register (GevVersionMajor and Minor) may share it.
      const bool fields = t[i].address == t[j].address && t[i].low_bits > 0 && t[j].low_bits > 0 &&
                          (t[i].shift >= t[j].shift + t[j].low_bits || t[j].shift >= t[i].shift + t[i].low_bits);
      if (fields) continue;
      const bool apart = t[i].address + t[i].length <= t[j].address || t[j].address + t[j].length <= t[i].address;
      EXPECT_TRUE(apart) << t[i].name << " and " << t[j].name;
    }
}

// The XML generator writes a feature's pIsAvailable and pIsLocked formulas
// over the one `variables` list, and a payload lock (locked_while_acquiring)
// takes the place of a locked_formula: each feature may use one of them.
TEST(GigeRegisterTable, EachFeatureHasAtMostOneFormula) {
  genicam::SensorInfo s;
  s.width = 64;
  s.height = 48;
  s.has_white_balance = true;
  s.has_gamma = true;
  s.has_trigger_line = true;
  s.stage_names = {"exposure", "cfa", "sensor"};
  int formulas = 0;
  for (const genicam::Feature& f : genicam::RegisterTable(s)) {
    const int n = !f.available_formula.empty() + !f.locked_formula.empty() + f.locked_while_acquiring;
    EXPECT_LE(n, 1) << f.name;
    formulas += !f.available_formula.empty() + !f.locked_formula.empty();
  }
  EXPECT_GE(formulas, 8) << "TriggerSoftware, ExposureTime, Gain, the trigger features, LineInverter";
}

// ---------------------------------------------------------------- wire format

TEST(GigeWireFormat, ConvertsDnToEachFormat) {
  // A 4x2 sensor of 12-bit DN; window x=1, y=1, 2x1.
  const uint16_t raw[8] = {0, 1, 2, 3, 4, 4095, 0x800, 7};
  uint8_t out[4] = {};
  genicam::ConvertWindow(genicam::BayerCode(Cfa::kBayerRG, 8), Cfa::kBayerRG, 12, raw, nullptr, 4, 1, 1, 2, 1, out);
  EXPECT_EQ(out[0], 255);   // 4095 >> 4
  EXPECT_EQ(out[1], 0x80);  // 0x800 >> 4
  genicam::ConvertWindow(genicam::BayerCode(Cfa::kBayerRG, 12), Cfa::kBayerRG, 12, raw, nullptr, 4, 1, 1, 2, 1, out);
  EXPECT_EQ(out[0], 0xff);  // 4095 little-endian
  EXPECT_EQ(out[1], 0x0f);
  EXPECT_EQ(out[2], 0x00);
  EXPECT_EQ(out[3], 0x08);
  genicam::ConvertWindow(genicam::BayerCode(Cfa::kBayerRG, 16), Cfa::kBayerRG, 12, raw, nullptr, 4, 1, 1, 2, 1, out);
  EXPECT_EQ(out[0], 0xf0);  // 4095 << 4 = 0xfff0
  EXPECT_EQ(out[1], 0xff);
  EXPECT_EQ(out[2], 0x00);
  EXPECT_EQ(out[3], 0x80);
  const uint8_t rgb[2 * 2 * 3] = {1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12};
  uint8_t o3[3];
  genicam::ConvertWindow(genicam::kRGB8, Cfa::kBayerRG, 12, nullptr, rgb, 2, 1, 1, 1, 1, o3);
  EXPECT_EQ(o3[0], 10);
  EXPECT_EQ(o3[2], 12);
  genicam::ConvertWindow(genicam::kBGR8, Cfa::kBayerRG, 12, nullptr, rgb, 2, 1, 1, 1, 1, o3);
  EXPECT_EQ(std::vector<uint8_t>(o3, o3 + 3), (std::vector<uint8_t>{12, 11, 10}));  // B, G, R
  // 4:2:2 by hand (full-range BT.601, Cb and Cr of the even pixel): blue,
  // red; (1, 123, 0) (Y exactly 72.5: 73), white. Blue's Cb 255.5 clamps to 255.
  const uint8_t pair_rgb[4 * 3] = {0, 0, 255, 255, 0, 0, 1, 123, 0, 255, 255, 255};
  uint8_t o4[8];
  for (const uint32_t f : {genicam::kYCbCr422_8, genicam::kYUV422_8}) {
    genicam::ConvertWindow(f, Cfa::kBayerRG, 12, nullptr, pair_rgb, 4, 0, 0, 4, 1, o4);
    EXPECT_EQ(std::vector<uint8_t>(o4, o4 + 8), (std::vector<uint8_t>{29, 255, 76, 107, 73, 87, 255, 77}));  // Y Cb Y Cr
  }
  genicam::ConvertWindow(genicam::kYUV422_8_UYVY, Cfa::kBayerRG, 12, nullptr, pair_rgb, 4, 0, 0, 4, 1, o4);
  EXPECT_EQ(std::vector<uint8_t>(o4, o4 + 8), (std::vector<uint8_t>{255, 29, 107, 76, 87, 73, 77, 255}));  // U Y V Y
  // Packed, by hand from the layouts (docs/gige.md): one row of 1x4 DN.
  using genicam::Packing;
  const uint16_t dn[4] = {0x123, 0x256, 0x3ff, 0x001};
  uint8_t p[5] = {};
  genicam::ConvertWindow(genicam::PackedCode(Cfa::kBayerRG, 12, Packing::kPfnc), Cfa::kBayerRG, 12, dn, nullptr, 4, 0, 0,
                         2, 1, p);
  EXPECT_EQ(std::vector<uint8_t>(p, p + 3), (std::vector<uint8_t>{0x23, 0x61, 0x25}));  // LSB first
  genicam::ConvertWindow(genicam::kMono12Packed, Cfa::kMono, 12, dn, nullptr, 4, 0, 0, 2, 1, p);
  EXPECT_EQ(std::vector<uint8_t>(p, p + 3), (std::vector<uint8_t>{0x12, 0x63, 0x25}));  // high bits, nibbles, high
  genicam::ConvertWindow(genicam::kMono10p, Cfa::kMono, 10, dn, nullptr, 4, 0, 0, 4, 1, p);
  EXPECT_EQ(std::vector<uint8_t>(p, p + 5), (std::vector<uint8_t>{0x23, 0x59, 0xf9, 0x7f, 0x00}));
  // Mono8 on a colour sensor: BT.601 luma of RGB8.
  const uint8_t rgb2[2 * 3] = {10, 20, 30, 255, 255, 255};
  uint8_t y2[2] = {};
  genicam::ConvertWindow(genicam::kMono8, Cfa::kBayerRG, 12, nullptr, rgb2, 2, 0, 0, 2, 1, y2);
  EXPECT_EQ(y2[0], 18);  // 0.299 * 10 + 0.587 * 20 + 0.114 * 30 = 18.15
  EXPECT_EQ(y2[1], 255);
}

// ---------------------------------------------------------------- GPIO HAL

TEST(GigeGpio, LineSpecsAreChecked) {
  std::string chip, error;
  unsigned offset = 0;
  EXPECT_TRUE(hal::ParseLineSpec("gpiochip0:17", &chip, &offset, &error));
  EXPECT_EQ(chip, "gpiochip0");
  EXPECT_EQ(offset, 17u);
  EXPECT_TRUE(hal::ParseLineSpec("/dev/gpiochip2:0", &chip, &offset, &error));
  EXPECT_EQ(chip, "/dev/gpiochip2");
  for (const char* bad : {"gpiochip0", "gpiochip0:", ":3", "gpiochip0:x", "gpiochip0:-1", "gpiochip0:70000",
                          "gpiochip0: 17", "gpiochip0:+17", "gpiochip0:17 "}) {
    error.clear();
    EXPECT_FALSE(hal::ParseLineSpec(bad, &chip, &offset, &error)) << bad;
    EXPECT_NE(error.find(bad), std::string::npos) << error;
  }
}

TEST(GigeGpio, MissingChipGivesAClearError) {
  // A chip name no system has: libgpiod really tries to open it.
  std::string error;
  EXPECT_EQ(hal::OpenGpiodInput("camsim-no-such-chip:3", "test", &error), nullptr);
  EXPECT_NE(error.find("camsim-no-such-chip:3"), std::string::npos) << error;
  EXPECT_NE(error.find("cannot open chip"), std::string::npos) << error;
  error.clear();
  EXPECT_EQ(hal::OpenGpiodOutput("/dev/null:0", "test", &error), nullptr);  // not a GPIO chip
  EXPECT_NE(error.find("/dev/null"), std::string::npos) << error;
  EXPECT_NE(error.find(std::strerror(ENOTTY)), std::string::npos) << "the reason: its ioctl fails\n" << error;
  // A path outside /dev is opened as given (libgpiod's lookup would try
  // /dev/PATH and report a missing file).
  const std::string file = testing::TempDir() + "camsim_not_a_chip";
  std::ofstream(file) << "x";
  error.clear();
  EXPECT_EQ(hal::OpenGpiodInput(file + ":0", "test", &error), nullptr);
  EXPECT_NE(error.find(std::strerror(ENOTTY)), std::string::npos) << error;
  std::remove(file.c_str());
}

// Edges that arrive before the waiter wakes keep their own direction: a
// pulse (rise, fall) is one rising and one falling edge, in that order.
TEST(GigeGpio, MemoryLineReportsEachEdgeWithItsDirection) {
  hal::MemoryLine line("test");
  std::string error;
  hal::Edge edge;
  ASSERT_TRUE(line.Set(true, &error));
  ASSERT_TRUE(line.Set(false, &error));
  ASSERT_EQ(line.WaitEdge(0, &edge, &error), 1);
  EXPECT_EQ(edge, hal::Edge::kRising);
  ASSERT_EQ(line.WaitEdge(0, &edge, &error), 1);
  EXPECT_EQ(edge, hal::Edge::kFalling);
  EXPECT_EQ(line.WaitEdge(0, &edge, &error), 0);
  // Bounded: the newest kMaxPendingEdges are kept, the last one being the level's.
  const int n = 3 * static_cast<int>(hal::MemoryLine::kMaxPendingEdges) + 1;
  for (int i = 0; i < n; ++i) ASSERT_TRUE(line.Set(i % 2 == 0, &error));
  EXPECT_EQ(line.edges(), 2 + n);
  size_t pending = 0;
  hal::Edge last = hal::Edge::kFalling;
  for (; line.WaitEdge(0, &edge, &error) == 1; ++pending) {
    if (pending > 0) {
      EXPECT_NE(edge, last) << "edge " << pending;
    }
    last = edge;
  }
  EXPECT_EQ(pending, hal::MemoryLine::kMaxPendingEdges);
  EXPECT_EQ(last, hal::Edge::kRising);
  EXPECT_TRUE(line.level());
}

// Each edge keeps the time of its Set (what LineDebouncerTime judges), however late it is read.
TEST(GigeGpio, MemoryLineStampsEachEdgeWhenItWasSet) {
  hal::MemoryLine line("test");
  std::string error;
  const auto t0 = std::chrono::steady_clock::now();
  ASSERT_TRUE(line.Set(true, &error));
  const auto t1 = std::chrono::steady_clock::now();
  Sleep(20);
  ASSERT_TRUE(line.Set(false, &error));
  const auto t2 = std::chrono::steady_clock::now();
  Sleep(20);
  hal::Edge edge;
  std::chrono::steady_clock::time_point at;
  ASSERT_EQ(line.WaitEdge(0, &edge, &error), 1);
  ASSERT_TRUE(line.LastEdgeTime(&at));
  EXPECT_TRUE(at >= t0 && at <= t1);
  ASSERT_EQ(line.WaitEdge(0, &edge, &error), 1);
  ASSERT_TRUE(line.LastEdgeTime(&at));
  EXPECT_TRUE(at >= t1 + std::chrono::milliseconds(20) && at <= t2);
}

TEST(GigeGpio, DeviceRefusesToStartWithAMissingTriggerLineOnly) {
  DeviceOptions o = SmallDevice();
  o.trigger_line = "camsim-no-such-chip:1";
  std::string error;
  EXPECT_EQ(GigeDevice::Start(o, &error), nullptr);
  EXPECT_NE(error.find("camsim-no-such-chip:1"), std::string::npos) << error;
  o.trigger_line.clear();
  o.strobe_line = "camsim-no-such-chip:2";
  EXPECT_EQ(GigeDevice::Start(o, &error), nullptr);
  EXPECT_NE(error.find("camsim-no-such-chip:2"), std::string::npos) << error;
  o.strobe_line.clear();
  auto d = GigeDevice::Start(o, &error);  // no lines: starts
  EXPECT_NE(d, nullptr) << error;
}

TEST(GigeTriggerBus, BadSpecsGiveAClearErrorNamingThem) {
  std::string error;
  // Each call's own message (error cleared before it).
  const auto input = [&error](const std::string& spec) {
    error.clear();
    return hal::OpenInputLine(spec, "test", &error);
  };
  // Not a bus spec, a scheme we do not have, a directory whose parent is missing.
  EXPECT_EQ(input("unix:"), nullptr);
  EXPECT_NE(error.find("'unix:'"), std::string::npos) << error;
  EXPECT_NE(error.find("unix:DIR"), std::string::npos) << error;
  EXPECT_EQ(input("udp:127.0.0.1:5000"), nullptr);
  EXPECT_NE(error.find("udp:127.0.0.1:5000"), std::string::npos) << error;
  EXPECT_NE(error.find("unix:DIR"), std::string::npos) << error;
  EXPECT_EQ(input("unix:/camsim-no-such-dir/bus"), nullptr);
  EXPECT_NE(error.find("unix:/camsim-no-such-dir/bus"), std::string::npos) << error;
  EXPECT_NE(error.find("No such file or directory"), std::string::npos) << error;
  error.clear();
  EXPECT_EQ(hal::OpenOutputLine("unix:/camsim-no-such-dir/bus", "test", &error), nullptr);
  EXPECT_NE(error.find("unix:/camsim-no-such-dir/bus"), std::string::npos) << error;
  const std::string long_dir = testing::TempDir() + std::string(120, 'd');
  EXPECT_EQ(input("unix:" + long_dir), nullptr);
  EXPECT_NE(error.find("longer than"), std::string::npos) << error;
  EXPECT_NE(rmdir(long_dir.c_str()), 0) << "a refused bus made its directory";
  // A file where the bus directory should be.
  const std::string file = testing::TempDir() + "camsim-bus-file-" + std::to_string(getpid());
  std::fclose(std::fopen(file.c_str(), "w"));
  EXPECT_EQ(input("unix:" + file), nullptr);
  EXPECT_NE(error.find("is not a directory"), std::string::npos) << error;
  std::remove(file.c_str());
  // The device refuses to start on a bad bus and says which.
  DeviceOptions o = SmallDevice();
  o.trigger_line = "unix:/camsim-no-such-dir/bus";
  error.clear();
  EXPECT_EQ(GigeDevice::Start(o, &error), nullptr);
  EXPECT_NE(error.find("unix:/camsim-no-such-dir/bus"), std::string::npos) << error;
}

// An edge that could not be sent is not lost: the line keeps its level, so
// the same Set sends it once the bus is back.
TEST(GigeTriggerBus, AnEdgeThatFailedIsSentByTheNextSet) {
  const std::string dir = testing::TempDir() + "camsim-retry-" + std::to_string(getpid());
  std::string error;
  auto out = [&] {
    auto in = hal::OpenInputLine("unix:" + dir, "test", &error);  // creates the directory
    return hal::OpenBusOutput("unix:" + dir, &error);
  }();
  ASSERT_NE(out, nullptr) << error;
  ASSERT_EQ(rmdir(dir.c_str()), 0);
  error.clear();
  EXPECT_FALSE(out->Set(true, &error));
  EXPECT_NE(error.find(dir), std::string::npos) << error;
  auto in = hal::OpenInputLine("unix:" + dir, "test", &error);
  ASSERT_NE(in, nullptr) << error;
  ASSERT_TRUE(out->Set(true, &error)) << error;
  EXPECT_EQ(out->last_receivers(), 1);
  hal::Edge edge;
  ASSERT_EQ(in->WaitEdge(1000, &edge, &error), 1);
  EXPECT_EQ(edge, hal::Edge::kRising);
  in.reset();
  EXPECT_EQ(rmdir(dir.c_str()), 0);
}

// Cameras in different PID namespaces can share a pid, and so a socket name:
// an input never takes a live input's name, and replaces a killed one's.
TEST(GigeTriggerBus, AnInputSkipsNamesInUseAndReplacesStaleOnes) {
  const std::string dir = testing::TempDir() + "camsim-names-" + std::to_string(getpid());
  ASSERT_EQ(mkdir(dir.c_str(), 0755), 0);
  const std::string stem = dir + "/line-" + std::to_string(getpid()) + "-";
  auto bind_at = [](const std::string& path) {
    const int fd = socket(AF_UNIX, SOCK_DGRAM, 0);
    sockaddr_un a{};
    a.sun_family = AF_UNIX;
    std::snprintf(a.sun_path, sizeof a.sun_path, "%s", path.c_str());
    EXPECT_EQ(bind(fd, reinterpret_cast<sockaddr*>(&a), sizeof a), 0) << path;
    return fd;
  };
  const int other = bind_at(stem + "0.sock");  // another namespace's camera, live
  close(bind_at(stem + "1.sock"));             // a killed camera's socket file
  std::string error;
  auto in = hal::OpenInputLine("unix:" + dir, "test", &error);
  ASSERT_NE(in, nullptr) << error;
  std::vector<std::string> names;
  for (const auto& e : std::filesystem::directory_iterator(dir)) names.push_back(e.path().filename().string());
  std::sort(names.begin(), names.end());
  const std::string pid = std::to_string(getpid());
  EXPECT_EQ(names, (std::vector<std::string>{"line-" + pid + "-0.sock", "line-" + pid + "-1.sock"}));
  auto out = hal::OpenBusOutput("unix:" + dir, &error);
  ASSERT_NE(out, nullptr) << error;
  ASSERT_TRUE(out->Set(true, &error)) << error;
  EXPECT_EQ(out->last_receivers(), 2) << "both the other camera and the new input";
  hal::Edge edge;
  EXPECT_EQ(in->WaitEdge(1000, &edge, &error), 1);
  uint8_t buf[16];
  EXPECT_EQ(recv(other, buf, sizeof buf, MSG_DONTWAIT), 16) << "the other camera lost its socket";
  in.reset();
  EXPECT_TRUE(std::filesystem::exists(stem + "0.sock")) << "closing the input removed the other camera's socket";
  close(other);
  std::filesystem::remove_all(dir);
}

// The inputs of one process share their names' stem (line-<pid>-N.sock), so
// inputs opened at the same moment claim the same names, and where killed
// cameras left their socket files they judge them stale together. The bus
// directory's lock (DirectoryLock) makes each claim one step: in every round
// each name goes to exactly one input, the others take the next free names
// (no error: an input fails only when all kMaxInputNames are taken), and an
// edge reaches every input. Without the lock two inputs could both judge a
// name stale, and the second one's unlink took the first one's fresh socket
// off the bus: it then missed every edge.
TEST(GigeTriggerBus, InputsClaimingOneNameAtOnceGetOneEach) {
  const std::string dir = testing::TempDir() + "camsim-claims-" + std::to_string(getpid());
  std::filesystem::remove_all(dir);
  ASSERT_EQ(mkdir(dir.c_str(), 0755), 0);
  const std::string stem = dir + "/line-" + std::to_string(getpid()) + "-";
  const auto stale_socket_at = [](const std::string& path) {  // bound, then closed: its file stays
    const int fd = socket(AF_UNIX, SOCK_DGRAM, 0);
    sockaddr_un a{};
    a.sun_family = AF_UNIX;
    std::snprintf(a.sun_path, sizeof a.sun_path, "%s", path.c_str());
    const bool bound = bind(fd, reinterpret_cast<sockaddr*>(&a), sizeof a) == 0;
    close(fd);
    return bound;
  };
  std::string error;
  auto out = hal::OpenBusOutput("unix:" + dir, &error);
  ASSERT_NE(out, nullptr) << error;
  constexpr int kInputs = 6, kRounds = 300;
  std::vector<std::string> expected;
  for (int n = 0; n < kInputs; ++n) expected.push_back("line-" + std::to_string(getpid()) + "-" + std::to_string(n) + ".sock");
  std::sort(expected.begin(), expected.end());
  for (int round = 0; round < kRounds; ++round) {
    SCOPED_TRACE("round " + std::to_string(round));
    // Killed cameras' sockets at every name: all inputs claim the first at
    // once, the losers the next, and so on.
    for (int n = 0; n < kInputs; ++n) ASSERT_TRUE(stale_socket_at(stem + std::to_string(n) + ".sock"));
    std::vector<std::unique_ptr<hal::InputLine>> inputs(kInputs);
    std::vector<std::string> errors(kInputs);
    std::latch start(kInputs);
    std::vector<std::thread> claims;
    for (int i = 0; i < kInputs; ++i)
      claims.emplace_back([&, i] {
        start.arrive_and_wait();
        inputs[i] = hal::OpenInputLine("unix:" + dir, "test", &errors[i]);
      });
    for (std::thread& t : claims) t.join();
    for (int i = 0; i < kInputs; ++i) ASSERT_NE(inputs[i], nullptr) << errors[i];
    std::vector<std::string> names;
    for (const auto& e : std::filesystem::directory_iterator(dir)) names.push_back(e.path().filename().string());
    std::sort(names.begin(), names.end());
    EXPECT_EQ(names, expected) << "one input per name";
    out->SetEdgeIndex(static_cast<uint32_t>(round));
    ASSERT_TRUE(out->Set(round % 2 == 0, &error)) << error;  // a new level each round: an edge
    EXPECT_EQ(out->last_receivers(), kInputs) << "a name nobody holds (a stale socket left)";
    int reached = 0;
    for (const auto& in : inputs) {
      hal::Edge edge;
      reached += in->WaitEdge(200, &edge, &error) == 1;
    }
    ASSERT_EQ(reached, kInputs) << "an input lost its name to another that claimed it at the same moment";
    inputs.clear();
    ASSERT_TRUE(std::filesystem::is_empty(dir)) << "an input left its socket file";
  }
  std::filesystem::remove_all(dir);
}

// Datagrams that are not bus edges do not restart an input's timeout.
TEST(GigeTriggerBus, ForeignDatagramsDoNotHoldAWaitPastItsTimeout) {
  const std::string dir = testing::TempDir() + "camsim-junk-" + std::to_string(getpid());
  std::string error;
  auto in = hal::OpenInputLine("unix:" + dir, "test", &error);
  ASSERT_NE(in, nullptr) << error;
  std::string socket_path;
  for (const auto& e : std::filesystem::directory_iterator(dir)) socket_path = e.path().string();
  ASSERT_FALSE(socket_path.empty());
  std::atomic<bool> stop{false};
  std::thread sender([&] {  // one junk datagram every 5 ms for up to 3 s
    const int fd = socket(AF_UNIX, SOCK_DGRAM, 0);
    sockaddr_un a{};
    a.sun_family = AF_UNIX;
    std::snprintf(a.sun_path, sizeof a.sun_path, "%s", socket_path.c_str());
    for (int i = 0; i < 600 && !stop; ++i) {
      sendto(fd, "junk", 4, MSG_DONTWAIT, reinterpret_cast<sockaddr*>(&a), sizeof a);
      std::this_thread::sleep_for(std::chrono::milliseconds(5));
    }
    close(fd);
  });
  hal::Edge edge;
  const auto t0 = std::chrono::steady_clock::now();
  const int r = in->WaitEdge(100, &edge, &error);
  const double ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  stop = true;
  sender.join();
  EXPECT_EQ(r, 0) << error;
  EXPECT_LT(ms, 2000.0) << "the junk kept the wait going";
  in.reset();
  EXPECT_EQ(rmdir(dir.c_str()), 0);
}

TEST(GigeTriggerBus, EveryInputGetsEachEdgeWithItsFrameIndex) {
  const std::string dir = testing::TempDir() + "camsim-bus-" + std::to_string(getpid());
  std::string error;
  auto a = hal::OpenInputLine("unix:" + dir, "test", &error);
  ASSERT_NE(a, nullptr) << error;
  auto b = hal::OpenInputLine("unix:" + dir + "/", "test", &error);
  ASSERT_NE(b, nullptr) << error;
  auto out = hal::OpenBusOutput("unix:" + dir, &error);
  ASSERT_NE(out, nullptr) << error;
  out->SetEdgeIndex(1234);
  ASSERT_TRUE(out->Set(true, &error)) << error;
  EXPECT_EQ(out->last_receivers(), 2);
  EXPECT_TRUE(out->Set(true, &error));  // same level: no edge
  out->SetEdgeIndex(1235);
  ASSERT_TRUE(out->Set(false, &error));
  for (hal::InputLine* in : {a.get(), b.get()}) {
    hal::Edge edge;
    uint32_t index = 0;
    ASSERT_EQ(in->WaitEdge(1000, &edge, &error), 1);
    EXPECT_EQ(edge, hal::Edge::kRising);
    ASSERT_TRUE(in->LastEdgeIndex(&index));
    EXPECT_EQ(index, 1234u);
    ASSERT_EQ(in->WaitEdge(1000, &edge, &error), 1);
    EXPECT_EQ(edge, hal::Edge::kFalling);
    in->LastEdgeIndex(&index);
    EXPECT_EQ(index, 1235u);
    EXPECT_EQ(in->WaitEdge(20, &edge, &error), 0) << "one datagram per edge";
  }
  // Anything that is not a whole bus message is ignored by the inputs.
  hal::TriggerBusMessage m;
  uint8_t bytes[hal::TriggerBusMessage::kSize];
  m.frame_index = 7;
  m.Encode(bytes);
  ASSERT_TRUE(hal::TriggerBusMessage::Decode(bytes, sizeof bytes, &m));
  EXPECT_EQ(m.frame_index, 7u);
  EXPECT_FALSE(hal::TriggerBusMessage::Decode(bytes, sizeof bytes - 1, &m));
  bytes[0] ^= 1;
  EXPECT_FALSE(hal::TriggerBusMessage::Decode(bytes, sizeof bytes, &m));
  // Inputs remove their sockets: one left, then none.
  a.reset();
  out->SetEdgeIndex(9);
  ASSERT_TRUE(out->Set(true, &error));
  EXPECT_EQ(out->last_receivers(), 1);
  b.reset();
  EXPECT_EQ(rmdir(dir.c_str()), 0) << "sockets left in " << dir;
}

// The bus input's socket in DIR (the only one there), and a datagram sent to it.
std::string BusSocketIn(const std::string& dir) {
  std::string path;
  for (const auto& e : std::filesystem::directory_iterator(dir)) path = e.path().string();
  return path;
}
void SendDatagram(const std::string& socket_path, const uint8_t* data, size_t size) {
  const int fd = socket(AF_UNIX, SOCK_DGRAM, 0);
  sockaddr_un a{};
  a.sun_family = AF_UNIX;
  std::snprintf(a.sun_path, sizeof a.sun_path, "%s", socket_path.c_str());
  EXPECT_EQ(sendto(fd, data, size, 0, reinterpret_cast<sockaddr*>(&a), sizeof a), static_cast<ssize_t>(size));
  close(fd);
}
// A version 2 bus edge stamped `edge_time_ns` (CLOCK_MONOTONIC).
void SendBusEdge(const std::string& socket_path, bool rising, uint32_t index, long long edge_time_ns) {
  hal::TriggerBusMessage m;
  m.rising = rising;
  m.frame_index = index;
  m.edge_time_ns = static_cast<uint64_t>(edge_time_ns);
  uint8_t bytes[hal::TriggerBusMessage::kSize];
  m.Encode(bytes);
  SendDatagram(socket_path, bytes, sizeof bytes);
}

// Version 2 of the bus message carries the sender's edge time (CLOCK_MONOTONIC
// ns) at bytes 16..23, little-endian; an input's LastEdgeTime is that time,
// not when it read the edge, unless the stamp is in the future or more than
// kMaxEdgeAgeS old (another clock). A message of another version (version
// 1: 16 bytes, no time) is not misread: it is ignored and named once.
TEST(GigeTriggerBus, MessagesCarryTheSendersEdgeTime) {
  hal::TriggerBusMessage m;
  m.rising = false;
  m.frame_index = 0x01020304;
  m.sequence = 0x0a0b0c0d;
  m.edge_time_ns = 0x1122334455667788ULL;
  uint8_t bytes[hal::TriggerBusMessage::kSize];
  static_assert(sizeof bytes == 24);
  m.Encode(bytes);
  const uint8_t want[24] = {'C', 'S', 'T', 'B', 2, 0, 0, 0, 0x04, 0x03, 0x02, 0x01, 0x0d, 0x0c, 0x0b, 0x0a,
                            0x88, 0x77, 0x66, 0x55, 0x44, 0x33, 0x22, 0x11};
  EXPECT_EQ(std::vector<uint8_t>(bytes, bytes + 24), std::vector<uint8_t>(want, want + 24));
  hal::TriggerBusMessage d;
  ASSERT_TRUE(hal::TriggerBusMessage::Decode(bytes, sizeof bytes, &d));
  EXPECT_FALSE(d.rising);
  EXPECT_EQ(d.frame_index, m.frame_index);
  EXPECT_EQ(d.sequence, m.sequence);
  EXPECT_EQ(d.edge_time_ns, m.edge_time_ns);
  EXPECT_EQ(hal::TriggerBusMessage::VersionOf(bytes, sizeof bytes), 2);
  // Version 1 as its senders wrote it: magic, 1, level, 0, 0, index, sequence.
  const uint8_t v1[16] = {'C', 'S', 'T', 'B', 1, 1, 0, 0, 5, 0, 0, 0, 1, 0, 0, 0};
  EXPECT_FALSE(hal::TriggerBusMessage::Decode(v1, sizeof v1, &d));
  EXPECT_EQ(hal::TriggerBusMessage::VersionOf(v1, sizeof v1), 1);
  EXPECT_EQ(hal::TriggerBusMessage::VersionOf(reinterpret_cast<const uint8_t*>("junk"), 4), -1);

  const std::string dir = testing::TempDir() + "camsim-stamp-" + std::to_string(getpid());
  std::string error;
  auto in = hal::OpenInputLine("unix:" + dir, "test", &error);
  ASSERT_NE(in, nullptr) << error;
  const std::string socket_path = BusSocketIn(dir);
  hal::Edge edge;
  std::chrono::steady_clock::time_point at;
  // A version 1 edge: no edge, and one notice naming both versions; a second one: no new notice.
  SendDatagram(socket_path, v1, sizeof v1);
  EXPECT_EQ(in->WaitEdge(50, &edge, &error), 0) << "a version 1 message taken for an edge";
  EXPECT_EQ(in->TakeNotice(), "trigger bus 'unix:" + dir +
                                  "': ignored an edge in message version 1 (this camera reads version 2; give "
                                  "camsim-trigger and every camera of the rig the same build)");
  SendDatagram(socket_path, v1, sizeof v1);
  EXPECT_EQ(in->WaitEdge(50, &edge, &error), 0);
  EXPECT_EQ(in->TakeNotice(), "") << "said twice";
  // Two new versions ignored in one wait: each named once.
  for (const uint8_t version : {3, 4}) {
    uint8_t other[24] = {'C', 'S', 'T', 'B', version, 1};
    SendDatagram(socket_path, other, sizeof other);
  }
  EXPECT_EQ(in->WaitEdge(50, &edge, &error), 0);
  const std::string notice = in->TakeNotice();
  EXPECT_NE(notice.find("message version 3 ("), std::string::npos) << notice;
  EXPECT_NE(notice.find("message version 4 ("), std::string::npos) << notice;
  // A BusOutput's edge: stamped within its Set, read 30 ms later.
  auto out = hal::OpenBusOutput("unix:" + dir, &error);
  ASSERT_NE(out, nullptr) << error;
  const auto t0 = std::chrono::steady_clock::now();
  ASSERT_TRUE(out->Set(true, &error)) << error;
  const auto t1 = std::chrono::steady_clock::now();
  Sleep(30);
  ASSERT_EQ(in->WaitEdge(1000, &edge, &error), 1);
  ASSERT_TRUE(in->LastEdgeTime(&at));
  const auto ms = [](auto span) { return std::chrono::duration<double, std::milli>(span).count(); };
  EXPECT_TRUE(at >= t0 - std::chrono::milliseconds(1) && at <= t1 + std::chrono::milliseconds(1))
      << "stamped " << ms(at - t0) << " ms after the Set began (it took " << ms(t1 - t0) << " ms)";
  // A stamp 200 ms old is kept; one in the future or 11 s old is another clock's: the time it was read.
  const long long now_ns = hal::MonotonicNowNs();
  const auto now = std::chrono::steady_clock::now();
  SendBusEdge(socket_path, false, 1, now_ns - 200000000LL);
  ASSERT_EQ(in->WaitEdge(1000, &edge, &error), 1);
  ASSERT_TRUE(in->LastEdgeTime(&at));
  EXPECT_LT(std::abs(ms(at - (now - std::chrono::milliseconds(200)))), 1.0) << ms(at - now) << " ms from now";
  for (const long long stamp : {now_ns + 3600000000000LL, now_ns - 11000000000LL}) {
    SendBusEdge(socket_path, true, 2, stamp);
    const auto before = std::chrono::steady_clock::now();
    ASSERT_EQ(in->WaitEdge(1000, &edge, &error), 1);
    const auto after = std::chrono::steady_clock::now();
    ASSERT_TRUE(in->LastEdgeTime(&at));
    EXPECT_TRUE(at >= before && at <= after) << "stamp " << stamp << " taken, " << ms(at - before) << " ms";
  }
  in.reset();
  EXPECT_EQ(rmdir(dir.c_str()), 0);
}

// A burst longer than an input's socket queue (max_dgram_qlen, 10 by default)
// reaches a reader that is briefly behind whole; a reader that never reads
// costs each later edge kSendTimeoutMs and is not counted.
TEST(GigeTriggerBus, BurstsWaitForASlowReaderAndSkipAStuckOne) {
  const std::string dir = testing::TempDir() + "camsim-burst-" + std::to_string(getpid());
  std::string error;
  auto in = hal::OpenInputLine("unix:" + dir, "test", &error);
  ASSERT_NE(in, nullptr) << error;
  auto out = hal::OpenBusOutput("unix:" + dir, &error);
  ASSERT_NE(out, nullptr) << error;
  constexpr int kEdges = 40;
  std::vector<uint32_t> got;
  // The reader stays behind until the queue is full, then wakes at once (a
  // notification, not a poll: the next send waits only kSendTimeoutMs for it).
  std::mutex m;
  std::condition_variable cv;
  bool queue_full = false;
  std::thread reader([&] {
    {
      std::unique_lock<std::mutex> lock(m);
      cv.wait(lock, [&] { return queue_full; });
    }
    std::string e;
    hal::Edge edge;
    uint32_t index = 0;
    while (got.size() < kEdges && in->WaitEdge(2000, &edge, &e) == 1) {
      in->LastEdgeIndex(&index);
      got.push_back(index);
    }
  });
  int reached = 0;
  for (int k = 0; k < kEdges; ++k) {
    out->SetEdgeIndex(static_cast<uint32_t>(k));
    EXPECT_TRUE(out->Set(k % 2 == 0, &error)) << error;  // no ASSERT: the reader thread must be joined
    reached += out->last_receivers();
    if (k == 9) {  // 10 queued (max_dgram_qlen): the next send waits for the reader
      std::lock_guard<std::mutex> lock(m);
      queue_full = true;
      cv.notify_one();
    }
  }
  reader.join();
  EXPECT_EQ(reached, kEdges);
  ASSERT_EQ(got.size(), static_cast<size_t>(kEdges)) << "edges lost in the burst";
  for (int k = 0; k < kEdges; ++k) EXPECT_EQ(got[static_cast<size_t>(k)], static_cast<uint32_t>(k));
  // Nobody reads `in` now: once its queue is full, an edge waits kSendTimeoutMs and misses it.
  int missed = 0;
  const auto t0 = std::chrono::steady_clock::now();
  for (int k = 0; k < 12; ++k) {
    ASSERT_TRUE(out->Set(k % 2 == 0, &error)) << error;
    missed += out->last_receivers() == 0;
  }
  const double ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  EXPECT_GE(missed, 1) << "a stuck reader's queue never filled";
  EXPECT_GE(ms, missed * (hal::BusOutput::kSendTimeoutMs - 10)) << "a missed edge did not wait";
  in.reset();
  EXPECT_EQ(rmdir(dir.c_str()), 0);
}

// ---------------------------------------------------------------- register logic without network

// Free run at AcquisitionFrameRate: a frame ready early waits for its slot,
// one period after the last (no drift); a late one starts at once, keeping
// the cadence when less than a period late and restarting it otherwise.
TEST(GigeFramePacing, SlotsKeepTheCadenceAndNeverWaitForALaterOne) {
  using std::chrono::milliseconds;
  const std::chrono::steady_clock::time_point t0{};
  const auto period = milliseconds(40);
  // Early (a fast render): wait for previous + period.
  genicam::FrameSlot s = genicam::NextFrameSlot(t0, t0 + milliseconds(5), period);
  EXPECT_EQ(s.start, t0 + milliseconds(40));
  EXPECT_EQ(s.slot, t0 + milliseconds(40));
  // Exactly on time.
  s = genicam::NextFrameSlot(t0, t0 + milliseconds(40), period);
  EXPECT_EQ(s.start, t0 + milliseconds(40));
  // 30 ms late: at once, and the slot stays on the cadence (the next is due at 80 ms).
  s = genicam::NextFrameSlot(t0, t0 + milliseconds(70), period);
  EXPECT_EQ(s.start, t0 + milliseconds(70));
  EXPECT_EQ(s.slot, t0 + milliseconds(40));
  // A render of 80 ms against a 40 ms period: frames every 80 ms, not at the
  // next multiple of 40 ms after it (120 ms, what the fake camera's clock did).
  s = genicam::NextFrameSlot(t0, t0 + milliseconds(80), period);
  EXPECT_EQ(s.start, t0 + milliseconds(80));
  EXPECT_EQ(s.slot, t0 + milliseconds(80));
  s = genicam::NextFrameSlot(s.slot, s.slot + milliseconds(80), period);
  EXPECT_EQ(s.start, t0 + milliseconds(160));
  // The period: 1 / rate, or the exposure time when that is longer.
  EXPECT_EQ(genicam::FramePeriod(25.0, 10000.0), milliseconds(40));
  EXPECT_EQ(genicam::FramePeriod(25.0, 1e6), milliseconds(1000));
  EXPECT_EQ(genicam::FramePeriod(1000.0, 1.0), milliseconds(1));
}

TEST(GigeRegisters, InvalidWritesAreRefusedAndValidOnesApplied) {
  DeviceOptions o = OfflineDevice();
  auto d = StartDevice(o);
  ASSERT_NE(d, nullptr);
  // Each is refused as it arrives (the write returns false: a GVCP client
  // gets invalid parameter, bad alignment for the half Float) and never stored.
  const std::vector<std::pair<uint32_t, std::vector<uint8_t>>> bad = {
      {reg::kWidth, Be32(65)},        {reg::kWidth, Be32(0)},          {reg::kOffsetY, Be32(32)},  // off the sensor
      {reg::kPixelFormat, Be32(7)},   {reg::kGainRaw, Be32(481)},      {reg::kTriggerSource, Be32(5)},
      {reg::kGain, Be64(48.5)},       {reg::kExposureTime, Be64(0.5)}, {reg::kSimFNumber, Be64(-1.0)},
      {reg::kAcquisitionFrameRateEnable, Be32(2)}, {reg::kBlackLevel, Be64(1e300)}, {reg::kExposureTime, Be64(2e8)},
      {reg::kExposureTime + 4, Be32(0)}};  // half of a Float: a value of two writes
  for (const auto& [address, bytes] : bad) {
    std::vector<uint8_t> before(bytes.size()), now(bytes.size());
    ASSERT_TRUE(d->ReadMemory(address, before.data(), static_cast<uint32_t>(before.size())));
    EXPECT_FALSE(d->WriteMemory(address, bytes.data(), static_cast<uint32_t>(bytes.size()))) << std::hex << address;
    ASSERT_TRUE(d->ReadMemory(address, now.data(), static_cast<uint32_t>(now.size())));
    EXPECT_EQ(now, before) << std::hex << address;
    d->SyncNow();
    EXPECT_EQ(d->CheckInvariants(), "") << std::hex << address;
  }
  EXPECT_EQ(d->writes_refused(), bad.size());
  std::vector<uint8_t> frame;
  ASSERT_TRUE(d->RenderNow(&frame));
  EXPECT_EQ(frame, ReferenceFrame(o, 0, genicam::BayerCode(Cfa::kBayerRG, 12), 0, 0, 64, 48));
  // Valid: a 16x8 window at (2, 4) in 8-bit, and exposure 2 ms.
  for (const auto& w : std::vector<std::pair<uint32_t, std::vector<uint8_t>>>{
           {reg::kWidth, Be32(16)}, {reg::kHeight, Be32(8)}, {reg::kOffsetX, Be32(2)}, {reg::kOffsetY, Be32(4)},
           {reg::kPixelFormat, Be32(genicam::BayerCode(Cfa::kBayerRG, 8))}, {reg::kExposureTime, Be64(2000.0)}})
    ASSERT_TRUE(d->WriteMemory(w.first, w.second.data(), static_cast<uint32_t>(w.second.size())));
  d->SyncNow();
  EXPECT_EQ(d->CheckInvariants(), "");
  EXPECT_EQ(d->writes_refused(), bad.size());
  ASSERT_TRUE(d->RenderNow(&frame));
  EXPECT_EQ(frame, ReferenceFrame(o, 1, genicam::BayerCode(Cfa::kBayerRG, 8), 2, 4, 16, 8,
                                  {"exposure.exposure_time_us=2000.0"}));
}

// Writes that meet in one sync are still separate requests: a write the
// pipeline cannot run (switching off the sensor, which raw formats need) is
// refused as it arrives, planned on the writes before it, and the others
// are taken, pipeline settings or not. In one block, the pipeline's
// registers go back together and the rest is stored.
TEST(GigeRegisters, ARefusedWriteDoesNotTakeItsSyncsOtherWritesWithIt) {
  DeviceOptions o = OfflineDevice();
  auto d = StartDevice(o);
  ASSERT_NE(d, nullptr);
  const uint32_t sensor_enable = StageEnableAddress(*d, "Stage_sensor");
  ASSERT_NE(sensor_enable, 0u);
  WriteReg(*d, reg::kExposureTime, Be64(2000.0));
  WriteRegRefused(*d, sensor_enable, Be32(0));
  EXPECT_EQ(ReadReg32(*d, sensor_enable), 1u) << "refused as it arrives";
  EXPECT_EQ(d->writes_refused(), 1u);
  WriteReg(*d, reg::kGainRaw, Be32(60));
  WriteReg(*d, reg::kAcquisitionMode, Be32(genicam::kSingleFrame));
  // One block over every SimStageEnable: vignetting and sensor off is
  // refused as a whole, vignetting alone is taken.
  const size_t stages = d->sensor().stage_names.size();
  const uint32_t vignetting_enable = StageEnableAddress(*d, "Stage_vignetting");
  ASSERT_NE(vignetting_enable, 0u);
  const auto stage_block = [&](std::initializer_list<uint32_t> off) {
    std::vector<uint8_t> block;
    for (size_t i = 0; i < stages; ++i) {
      const uint32_t a = genicam::reg::SelectedAddress(reg::kSimStageEnable, i);
      for (uint8_t b : Be32(std::find(off.begin(), off.end(), a) == off.end() ? 1 : 0)) block.push_back(b);
    }
    return block;
  };
  WriteRegRefused(*d, reg::kSimStageEnable, stage_block({vignetting_enable, sensor_enable}));
  EXPECT_EQ(ReadReg32(*d, vignetting_enable), 1u) << "the block's pipeline registers go back together";
  EXPECT_EQ(d->writes_refused(), 2u);
  WriteReg(*d, reg::kSimStageEnable, stage_block({vignetting_enable}));
  EXPECT_EQ(ReadReg32(*d, vignetting_enable), 0u);
  d->SyncNow();
  EXPECT_EQ(d->CheckInvariants(), "");
  EXPECT_EQ(d->writes_refused(), 2u);
  EXPECT_EQ(ReadReg32(*d, sensor_enable), 1u);
  EXPECT_EQ(ReadRegDouble(*d, reg::kExposureTime), 2000.0);
  EXPECT_EQ(ReadReg32(*d, reg::kGainRaw), 60u);
  EXPECT_EQ(ReadRegDouble(*d, reg::kGain), 6.0);
  EXPECT_EQ(ReadReg32(*d, reg::kAcquisitionMode), static_cast<uint32_t>(genicam::kSingleFrame));
  std::string without_vignetting;  // pipeline.stages: the configured stages but the vignetting
  for (const std::string& stage : d->sensor().stage_names)
    if (stage != "vignetting") without_vignetting += (without_vignetting.empty() ? "\"" : ",\"") + stage + "\"";
  std::vector<uint8_t> frame;
  ASSERT_TRUE(d->RenderNow(&frame));
  EXPECT_EQ(frame, ReferenceFrame(o, 0, genicam::BayerCode(Cfa::kBayerRG, 12), 0, 0, 64, 48,
                                  {"exposure.exposure_time_us=2000.0", "sensor.gain_db=6.0",
                                   "pipeline.stages=[" + without_vignetting + "]"}));
}

// A pipeline write is planned on the client's earlier writes, synced or not:
// with the demosaic switched off, RGB8 (which needs the ISP) is refused, and
// the other way round. In a block, the pipeline's registers go back and the
// others (AcquisitionMode, after PixelFormat) are stored.
TEST(GigeRegisters, APipelineWriteIsPlannedOnTheWritesBeforeIt) {
  DeviceOptions o = OfflineDevice();
  for (const bool format_first : {false, true}) {
    SCOPED_TRACE(format_first ? "RGB8 first" : "demosaic off first");
    auto d = StartDevice(o);
    ASSERT_NE(d, nullptr);
    const uint32_t demosaic_enable = StageEnableAddress(*d, "Stage_demosaic");
    ASSERT_NE(demosaic_enable, 0u);
    std::vector<uint8_t> block = Be32(genicam::kRGB8);  // PixelFormat, AcquisitionMode
    for (uint8_t b : Be32(genicam::kSingleFrame)) block.push_back(b);
    testing::internal::CaptureStderr();
    if (format_first) {
      WriteReg(*d, reg::kPixelFormat, block);
      WriteRegRefused(*d, demosaic_enable, Be32(0));  // not synced yet: RGB8 is still only in memory
      EXPECT_EQ(ReadReg32(*d, demosaic_enable), 1u);
    } else {
      WriteReg(*d, demosaic_enable, Be32(0));
      WriteRegRefused(*d, reg::kPixelFormat, block);
      EXPECT_EQ(ReadReg32(*d, reg::kPixelFormat), genicam::BayerCode(Cfa::kBayerRG, 12));
    }
    // The line names the setting the write changes (a stage switch by its stage).
    EXPECT_EQ(testing::internal::GetCapturedStderr(),
              std::string("camsim-gige: refused ") +
                  (format_first ? "SimStageEnable[Stage_demosaic]" : "PixelFormat") +
                  ": the selected PixelFormat needs the ISP\n");
    EXPECT_EQ(ReadReg32(*d, reg::kAcquisitionMode), static_cast<uint32_t>(genicam::kSingleFrame));
    EXPECT_EQ(d->writes_refused(), 1u);
    d->SyncNow();
    EXPECT_EQ(d->CheckInvariants(), "");
    EXPECT_EQ(d->writes_refused(), 1u) << "the sync refuses nothing more";
    EXPECT_EQ(ReadReg32(*d, reg::kPixelFormat), format_first ? genicam::kRGB8 : genicam::BayerCode(Cfa::kBayerRG, 12));
    EXPECT_EQ(ReadReg32(*d, demosaic_enable), format_first ? 1u : 0u);
  }
}

// The write combination the register fuzzer found (its seed cfa_off_crash):
// the cfa and demosaic stages off, a smaller window, one sync. The cfa alone
// was refused (the demosaic needs a mosaic); with the demosaic off as well,
// nothing refused it, the sensor gave three samples per pixel and the raw
// tap (one sample per pixel) overflowed. Now the cfa write is refused as it
// arrives, in either order, and the others are taken.
TEST(GigeRegisters, TheCfaStageStaysOnSoTheRawFormatsKeepOneSamplePerPixel) {
  DeviceOptions o = OfflineDevice();
  auto d = StartDevice(o);
  ASSERT_NE(d, nullptr);
  const uint32_t cfa_enable = StageEnableAddress(*d, "Stage_cfa");
  const uint32_t demosaic_enable = StageEnableAddress(*d, "Stage_demosaic");
  ASSERT_NE(cfa_enable, 0u);
  ASSERT_NE(demosaic_enable, 0u);
  std::string without_demosaic;  // pipeline.stages: the configured stages but the demosaic
  for (const std::string& stage : d->sensor().stage_names)
    if (stage != "demosaic") without_demosaic += (without_demosaic.empty() ? "\"" : ",\"") + stage + "\"";
  WriteRegRefused(*d, cfa_enable, Be32(0));  // the demosaic needs a mosaic
  WriteReg(*d, demosaic_enable, Be32(0));
  WriteRegRefused(*d, cfa_enable, Be32(0));  // the raw formats need one sample per pixel
  WriteReg(*d, reg::kHeight, Be32(6));
  EXPECT_EQ(d->writes_refused(), 2u);
  d->SyncNow();
  EXPECT_EQ(d->CheckInvariants(), "");
  EXPECT_EQ(d->writes_refused(), 2u);
  EXPECT_EQ(ReadReg32(*d, cfa_enable), 1u);
  EXPECT_EQ(ReadReg32(*d, demosaic_enable), 0u);
  EXPECT_EQ(ReadReg32(*d, reg::kHeight), 6u);
  std::vector<uint8_t> frame;
  for (uint32_t index = 0; index < 2; ++index) {  // the overflow came with the frame after the switch
    ASSERT_TRUE(d->RenderNow(&frame));
    EXPECT_EQ(frame, ReferenceFrame(o, index, genicam::BayerCode(Cfa::kBayerRG, 12), 0, 0, 64, 6,
                                    {"pipeline.stages=[" + without_demosaic + "]"}));
  }
}

// The same at start-up: a configuration whose stages leave the cfa out is
// refused with a message naming it (it used to start and overflow the raw
// tap with the first frame).
TEST(GigeRegisters, ADeviceWhoseStagesLeaveTheCfaOutDoesNotStart) {
  DeviceOptions o = OfflineDevice();
  o.overrides.push_back("pipeline.stages=[\"exposure\",\"sensor\"]");
  std::string error;
  EXPECT_EQ(GigeDevice::Start(o, &error), nullptr);
  EXPECT_NE(error.find("[pipeline] stages"), std::string::npos) << error;
  EXPECT_NE(error.find("cfa stage"), std::string::npos) << error;
  o.overrides.back() = "pipeline.stages=[\"exposure\",\"cfa\",\"sensor\"]";
  EXPECT_NE(GigeDevice::Start(o, &error), nullptr) << error;
}

// The configured exposure may be longer than 1 s (the core allows 100 s): the
// register reports it, and a later write of another pipeline register keeps it.
// A client sets the window and starts at once: one sync finds both writes.
// The window came first and is taken; one written after the start is refused
// as it arrives.
TEST(GigeRegisters, AWindowWrittenJustBeforeAcquisitionStartIsTaken) {
  DeviceOptions o = OfflineDevice();
  auto d = StartDevice(o);
  ASSERT_NE(d, nullptr);
  WriteReg(*d, reg::kControlChannelPrivilege, Be32(2));  // a controlling client
  WriteReg(*d, reg::kWidth, Be32(32));
  WriteReg(*d, reg::kHeight, Be32(16));
  WriteReg(*d, reg::kAcquisition, Be32(1));
  d->SyncNow();
  EXPECT_EQ(ReadReg32(*d, reg::kWidth), 32u);
  EXPECT_EQ(ReadReg32(*d, reg::kHeight), 16u);
  EXPECT_EQ(d->writes_refused(), 0u);
  EXPECT_EQ(d->CheckInvariants(), "");
  std::vector<uint8_t> frame;
  ASSERT_TRUE(d->RenderNow(&frame));
  EXPECT_EQ(frame, ReferenceFrame(o, 0, genicam::BayerCode(Cfa::kBayerRG, 12), 0, 0, 32, 16));
  WriteRegRefused(*d, reg::kWidth, Be32(16));  // during the acquisition
  EXPECT_EQ(ReadReg32(*d, reg::kWidth), 32u);
  EXPECT_EQ(d->writes_refused(), 1u);
  WriteReg(*d, reg::kWidth, Be32(32));  // the value in use: nothing changes
  d->SyncNow();
  EXPECT_EQ(ReadReg32(*d, reg::kWidth), 32u);
  EXPECT_EQ(d->writes_refused(), 1u);
}

// An Aravis client stops, changes the window and starts again in about
// 0.2 ms, well inside one register sync: the sync sees the acquisition
// running before and after, and the window is still taken (until 2026-11-27
// it was refused as a write during acquisition).
TEST(GigeRegisters, StopWindowStartBetweenTwoSyncsTakesTheWindow) {
  DeviceOptions o = OfflineDevice();
  auto d = StartDevice(o);
  ASSERT_NE(d, nullptr);
  WriteReg(*d, reg::kControlChannelPrivilege, Be32(2));
  WriteReg(*d, reg::kAcquisition, Be32(1));
  d->SyncNow();
  std::vector<uint8_t> frame;
  ASSERT_TRUE(d->RenderNow(&frame));
  WriteReg(*d, reg::kAcquisition, Be32(0));
  WriteReg(*d, reg::kWidth, Be32(16));  // the size first: the offset's maximum is WidthMax - Width
  WriteReg(*d, reg::kOffsetX, Be32(8));
  WriteReg(*d, reg::kPixelFormat, Be32(genicam::BayerCode(Cfa::kBayerRG, 8)));
  WriteReg(*d, reg::kAcquisition, Be32(1));
  d->SyncNow();
  EXPECT_EQ(d->writes_refused(), 0u);
  EXPECT_EQ(ReadReg32(*d, reg::kWidth), 16u);
  EXPECT_EQ(d->CheckInvariants(), "");
  ASSERT_TRUE(d->RenderNow(&frame));
  EXPECT_EQ(frame, ReferenceFrame(o, 1, genicam::BayerCode(Cfa::kBayerRG, 8), 8, 0, 16, 48));
}

// AcquisitionStart and AcquisitionStop have a register each that reads 0
// once the command ran, so GenApi's IsDone (the value read back differs from
// CommandValue) is true at once; until 2026-11-27 both were the acquisition
// register with values 1 and 0, and a WaitUntilDone never returned.
TEST(GigeRegisters, AcquisitionCommandsReadBackDone) {
  DeviceOptions o = OfflineDevice();
  auto d = StartDevice(o);
  ASSERT_NE(d, nullptr);
  const genicam::Feature* start = genicam::FindFeature(d->table(), "AcquisitionStart");
  const genicam::Feature* stop = genicam::FindFeature(d->table(), "AcquisitionStop");
  const genicam::Feature* abort = genicam::FindFeature(d->table(), "AcquisitionAbort");
  ASSERT_NE(start, nullptr);
  ASSERT_NE(stop, nullptr);
  ASSERT_NE(abort, nullptr);
  EXPECT_NE(start->address, stop->address);
  EXPECT_EQ(start->command_value, 1);
  EXPECT_EQ(stop->command_value, 1);
  EXPECT_EQ(abort->command_value, 1);
  WriteReg(*d, start->address, Be32(1));
  WriteReg(*d, abort->address, Be32(1));
  EXPECT_EQ(ReadReg32(*d, reg::kAcquisition), 0u);
  EXPECT_EQ(ReadReg32(*d, abort->address), 0u);
  WriteReg(*d, start->address, Be32(1));
  EXPECT_EQ(ReadReg32(*d, reg::kAcquisition), 1u);
  EXPECT_EQ(ReadReg32(*d, start->address), 0u);
  WriteRegRefused(*d, reg::kWidth, Be32(32));  // after the start: the window is locked
  EXPECT_EQ(d->writes_refused(), 1u);
  EXPECT_EQ(ReadReg32(*d, reg::kWidth), 64u);
  WriteReg(*d, stop->address, Be32(1));
  EXPECT_EQ(ReadReg32(*d, reg::kAcquisition), 0u);
  EXPECT_EQ(ReadReg32(*d, stop->address), 0u);
  const uint64_t refused = d->writes_refused();
  WriteRegRefused(*d, start->address, Be32(2));  // another value: not the command
  WriteRegRefused(*d, start->address + 2, {0, 1});  // half a register: not a GVCP write
  EXPECT_EQ(ReadReg32(*d, reg::kAcquisition), 0u);
  EXPECT_EQ(ReadReg32(*d, start->address), 0u);
  EXPECT_EQ(d->writes_refused(), refused + 1);
}

// One write of several registers while acquiring: the window's registers go
// back to the values in use, the others are taken; with the acquisition
// register cleared in the same block (a stop), the window is taken too.
// Gain and GainRaw are one setting in two units: the last write of either
// wins, whatever a sync sees between them (a Gain write and then a GainRaw
// write within one sync period used to keep the Gain).
TEST(GigeRegisters, TheLastOfGainAndGainRawWins) {
  auto d = StartDevice(OfflineDevice());
  ASSERT_NE(d, nullptr);
  WriteReg(*d, reg::kGain, Be64(10.0));
  d->SyncNow();
  WriteReg(*d, reg::kGain, Be64(20.0));
  EXPECT_EQ(ReadReg32(*d, reg::kGainRaw), 200u) << "GainRaw follows Gain as it arrives";
  WriteReg(*d, reg::kGainRaw, Be32(123));
  EXPECT_EQ(ReadRegDouble(*d, reg::kGain), 12.3) << "Gain follows GainRaw as it arrives";
  d->SyncNow();
  EXPECT_EQ(ReadRegDouble(*d, reg::kGain), 12.3);
  EXPECT_EQ(ReadReg32(*d, reg::kGainRaw), 123u);
  WriteReg(*d, reg::kGainRaw, Be32(50));
  WriteReg(*d, reg::kGain, Be64(7.5));
  d->SyncNow();
  EXPECT_EQ(ReadRegDouble(*d, reg::kGain), 7.5);
  EXPECT_EQ(ReadReg32(*d, reg::kGainRaw), 75u);
  // A refused GainRaw moves nothing.
  WriteRegRefused(*d, reg::kGainRaw, Be32(100000));
  EXPECT_EQ(ReadRegDouble(*d, reg::kGain), 7.5);
  EXPECT_EQ(d->CheckInvariants(), "");
}

// Gain is applied in GainRaw's 0.1 dB steps, as a camera applies its raw
// gain: 12.34 reads back (and renders, and goes in ChunkGain) as 12.3, the
// GainRaw 123 it sets. The XML says so (Inc 0.1).
TEST(GigeRegisters, GainIsAppliedInGainRawsSteps) {
  DeviceOptions o = OfflineDevice();
  auto d = StartDevice(o);
  ASSERT_NE(d, nullptr);
  EXPECT_EQ(genicam::FindFeature(d->table(), "Gain")->inc, 0.1);
  WriteReg(*d, reg::kGain, Be64(12.34));
  EXPECT_EQ(ReadRegDouble(*d, reg::kGain), 12.3) << "read back as it arrives";
  EXPECT_EQ(ReadReg32(*d, reg::kGainRaw), 123u);
  d->SyncNow();
  EXPECT_EQ(ReadRegDouble(*d, reg::kGain), 12.3);
  EXPECT_EQ(d->CheckInvariants(), "");
  std::vector<uint8_t> frame;
  ASSERT_TRUE(d->RenderNow(&frame));
  EXPECT_EQ(frame, ReferenceFrame(o, 0, genicam::BayerCode(Cfa::kBayerRG, 12), 0, 0, 64, 48, {"sensor.gain_db=12.3"}));
  WriteReg(*d, reg::kGain, Be64(47.96));  // rounds to the maximum
  EXPECT_EQ(ReadRegDouble(*d, reg::kGain), 48.0);
  EXPECT_EQ(ReadReg32(*d, reg::kGainRaw), 480u);
  // A configured gain between steps starts on its nearest step.
  DeviceOptions c = OfflineDevice();
  c.overrides.push_back("sensor.gain_db=6.06");
  auto e = StartDevice(c);
  ASSERT_NE(e, nullptr);
  EXPECT_EQ(ReadRegDouble(*e, reg::kGain), 6.1);
  EXPECT_EQ(e->CheckInvariants(), "");
  ASSERT_TRUE(e->RenderNow(&frame));
  EXPECT_EQ(frame, ReferenceFrame(o, 0, genicam::BayerCode(Cfa::kBayerRG, 12), 0, 0, 64, 48, {"sensor.gain_db=6.1"}));
}

// Every refused write leaves one line on stderr: the feature, the value
// written and why. A client could flood it: at most 20 lines a second, and
// the next line logged counts the ones left out.
TEST(GigeRegisters, EachRefusedWriteIsLoggedWithItsReason) {
  auto d = StartDevice(OfflineDevice());  // 64 x 48 BayerRG12
  ASSERT_NE(d, nullptr);
  const std::vector<std::pair<std::pair<uint32_t, std::vector<uint8_t>>, std::string>> cases = {
      {{reg::kOffsetY, Be32(32)}, "refused OffsetY = 32: window off the sensor: Height 48 + OffsetY 32 > HeightMax 48"},
      {{reg::kWidth, Be32(15)}, "refused Width = 15: off its increment 2"},
      {{reg::kWidth, Be32(66)}, "refused Width = 66: out of range 2..64"},
      {{reg::kExposureTime, Be64(0.5)}, "refused ExposureTime = 0.5: out of range 1..1e+08"},
      {{reg::kTriggerSource, Be32(5)}, "refused TriggerSource = 5: no such entry"},
      {{reg::kTriggerSource, Be32(genicam::kSourceLine0)}, "refused TriggerSource = Line0 (1): entry Line0 is not available"},
      {{reg::kGain, Be64(std::nan(""))}, "refused Gain = nan: not a finite number"},
      {{reg::kAutoGainLowerLimit, Be64(30.0)}, "refused AutoGainLowerLimit = 30: AutoGainLowerLimit 30 above AutoGainUpperLimit 24"},
      {{0x8ff0, Be32(1)}, "refused register 0x8ff0: no feature there"},
  };
  for (const auto& [write, line] : cases) {
    testing::internal::CaptureStderr();
    WriteRegRefused(*d, write.first, write.second);
    const std::string err = testing::internal::GetCapturedStderr();
    EXPECT_NE(err.find("camsim-gige: " + line), std::string::npos) << err;
    EXPECT_EQ(std::count(err.begin(), err.end(), '\n'), 1) << err;
  }
  // While TLParamsLocked is 1 (or acquiring): the lock, before the value.
  WriteReg(*d, reg::kTLParamsLocked, Be32(1));
  testing::internal::CaptureStderr();
  WriteRegRefused(*d, reg::kOffsetX, Be32(64));
  std::string err = testing::internal::GetCapturedStderr();
  EXPECT_NE(err.find("refused OffsetX = 64: TLParamsLocked is 1"), std::string::npos) << err;
  EXPECT_EQ(err.find("window off the sensor"), std::string::npos) << err;
  // A flood: 20 lines in its second, then one that counts the rest.
  std::this_thread::sleep_for(std::chrono::milliseconds(1100));
  testing::internal::CaptureStderr();
  for (int i = 0; i < 500; ++i) WriteRegRefused(*d, reg::kWidth, Be32(15));
  err = testing::internal::GetCapturedStderr();
  EXPECT_EQ(std::count(err.begin(), err.end(), '\n'), 20) << err;
  std::this_thread::sleep_for(std::chrono::milliseconds(1100));
  testing::internal::CaptureStderr();
  WriteRegRefused(*d, reg::kWidth, Be32(15));
  err = testing::internal::GetCapturedStderr();
  EXPECT_NE(err.find("(480 earlier lines not logged"), std::string::npos) << err;
  // A flood with no line after it: its count comes at the first sync after
  // its second, or at the end, not never.
  std::this_thread::sleep_for(std::chrono::milliseconds(1100));
  testing::internal::CaptureStderr();
  for (int i = 0; i < 25; ++i) WriteRegRefused(*d, reg::kWidth, Be32(15));
  d->SyncNow();  // within the second: not yet
  err = testing::internal::GetCapturedStderr();
  EXPECT_EQ(std::count(err.begin(), err.end(), '\n'), 20) << err;
  std::this_thread::sleep_for(std::chrono::milliseconds(1100));
  testing::internal::CaptureStderr();
  d->SyncNow();
  d->SyncNow();
  err = testing::internal::GetCapturedStderr();
  EXPECT_EQ(err, "camsim-gige: 5 more lines not logged: over 20 a second\n");
  std::this_thread::sleep_for(std::chrono::milliseconds(1100));
  testing::internal::CaptureStderr();
  for (int i = 0; i < 23; ++i) WriteRegRefused(*d, reg::kWidth, Be32(15));
  d.reset();
  err = testing::internal::GetCapturedStderr();
  EXPECT_NE(err.find("camsim-gige: 3 more lines not logged: over 20 a second\n"), std::string::npos) << err;
}

// Without a trigger line (no --trigger-line), TriggerSource Line0 would arm
// a trigger that never comes: the XML marks the entry unavailable
// (pIsAvailable 0) and the device refuses it, as a camera without that line
// would. With a line, it is taken.
TEST(GigeRegisters, TriggerSourceLine0NeedsATriggerLine) {
  const auto available = [](const GigeDevice& d) {
    const std::string xml = genicam::GenerateXml(d.table(), genicam::DeviceStrings());
    ArvGc* gc = arv_gc_new(nullptr, xml.data(), xml.size());
    guint n = 0;
    const char** v = arv_gc_enumeration_dup_available_string_values(
        ARV_GC_ENUMERATION(arv_gc_get_node(gc, "TriggerSource")), &n, nullptr);
    std::vector<std::string> names(v, v + n);
    g_free(v);
    g_object_unref(gc);
    std::sort(names.begin(), names.end());
    return names;
  };
  auto d = StartDevice(OfflineDevice());
  ASSERT_NE(d, nullptr);
  EXPECT_EQ(available(*d), std::vector<std::string>{"Software"});
  WriteRegRefused(*d, reg::kTriggerSource, Be32(genicam::kSourceLine0));
  EXPECT_EQ(ReadReg32(*d, reg::kTriggerSource), uint32_t(genicam::kSourceSoftware));
  d->SyncNow();
  EXPECT_EQ(d->CheckInvariants(), "");
  d.reset();
  hal::MemoryLine line("trigger");
  DeviceOptions o = OfflineDevice();
  o.trigger = &line;
  auto t = StartDevice(o);
  ASSERT_NE(t, nullptr);
  EXPECT_EQ(available(*t), (std::vector<std::string>{"Line0", "Software"}));
  WriteReg(*t, reg::kTriggerSource, Be32(genicam::kSourceLine0));
  t->SyncNow();
  EXPECT_EQ(ReadReg32(*t, reg::kTriggerSource), uint32_t(genicam::kSourceLine0));
}

// Registers only the device writes (the fake camera's trigger block, its
// frame period) and addresses of camsim's range the XML does not describe
// are no client's to write: refused, not stored (a write to the fake
// camera's trigger mode used to stop a free run).
TEST(GigeRegisters, RegistersNoFeatureDescribesRefuseClientWrites) {
  auto d = StartDevice(OfflineDevice());
  ASSERT_NE(d, nullptr);
  const uint32_t mode = ReadReg32(*d, reg::kFakeTriggerMode), period = ReadReg32(*d, reg::kFakeFramePeriodUs);
  WriteRegRefused(*d, reg::kFakeTriggerMode, Be32(1 - mode));
  WriteRegRefused(*d, reg::kFakeFramePeriodUs, Be32(period + 1000));
  WriteRegRefused(*d, reg::kFakeTriggerSoftware, Be32(1));
  WriteRegRefused(*d, reg::kFakeTriggerSoftware, Be32(0));  // the fake camera's acknowledgement is not a client's
  WriteRegRefused(*d, 0x9000, Be32(1));
  // A block with one undescribed register is refused whole: BlackLevel (a
  // Float at 0x8050) and the unused word after it.
  const double black = ReadRegDouble(*d, reg::kBlackLevel);
  std::vector<uint8_t> block = Be64(black + 1.0);
  for (uint8_t b : Be32(1)) block.push_back(b);
  WriteRegRefused(*d, reg::kBlackLevel, block);
  EXPECT_EQ(ReadRegDouble(*d, reg::kBlackLevel), black);
  EXPECT_EQ(ReadReg32(*d, reg::kFakeTriggerMode), mode);
  EXPECT_EQ(ReadReg32(*d, reg::kFakeFramePeriodUs), period);
  EXPECT_EQ(ReadReg32(*d, reg::kFakeTriggerSoftware), 0u);
  EXPECT_EQ(ReadReg32(*d, 0x9000), 0u);
  EXPECT_EQ(d->writes_refused(), 6u);
  d->SyncNow();
  EXPECT_EQ(d->CheckInvariants(), "");
}

TEST(GigeRegisters, ABlockWriteKeepsWhatItMayChange) {
  static_assert(reg::kPixelFormat == reg::kAcquisition + 4 && reg::kAcquisitionMode == reg::kPixelFormat + 4);
  DeviceOptions o = OfflineDevice();
  auto d = StartDevice(o);
  ASSERT_NE(d, nullptr);
  WriteReg(*d, reg::kControlChannelPrivilege, Be32(2));
  WriteReg(*d, reg::kAcquisition, Be32(1));
  const uint32_t format12 = genicam::BayerCode(Cfa::kBayerRG, 12), format8 = genicam::BayerCode(Cfa::kBayerRG, 8);
  auto block = [](std::vector<uint32_t> words) {
    std::vector<uint8_t> b;
    for (uint32_t w : words)
      for (uint8_t x : Be32(w)) b.push_back(x);
    return b;
  };
  WriteRegRefused(*d, reg::kPixelFormat, block({format8, genicam::kSingleFrame}));  // partly
  EXPECT_EQ(ReadReg32(*d, reg::kPixelFormat), format12);
  EXPECT_EQ(ReadReg32(*d, reg::kAcquisitionMode), static_cast<uint32_t>(genicam::kSingleFrame));
  EXPECT_EQ(d->writes_refused(), 1u);
  WriteRegRefused(*d, reg::kAcquisition, block({1, format8}));  // still acquiring
  EXPECT_EQ(ReadReg32(*d, reg::kPixelFormat), format12);
  EXPECT_EQ(d->writes_refused(), 2u);
  WriteReg(*d, reg::kAcquisition, block({0, format8}));  // a stop and a format
  EXPECT_EQ(ReadReg32(*d, reg::kAcquisition), 0u);
  EXPECT_EQ(ReadReg32(*d, reg::kPixelFormat), format8);
  EXPECT_EQ(d->writes_refused(), 2u);
  // A value no feature takes (AcquisitionMode 9) goes back; the format beside it stays.
  WriteRegRefused(*d, reg::kPixelFormat, block({format12, 9}));
  EXPECT_EQ(ReadReg32(*d, reg::kPixelFormat), format12);
  EXPECT_EQ(ReadReg32(*d, reg::kAcquisitionMode), static_cast<uint32_t>(genicam::kSingleFrame));
  EXPECT_EQ(d->writes_refused(), 3u);
}

// FakeCameraHooksInForce sees libaravis's own register accesses pass
// through the hooks, and its GLib calls resolve to them (GigeDevice::Init
// refuses to start without them).
TEST(GigeRegisters, TheHooksAreInForce) {
  ArvFakeCamera* camera = arv_fake_camera_new_full("CSHOOK", nullptr);
  ASSERT_NE(camera, nullptr);
  EXPECT_TRUE(genicam::FakeCameraHooksInForce(camera));
  g_object_unref(camera);
}

// One camera's held writes (its sync rebuilding the pipeline, its filter
// planning) do not hold up another camera's: a write to B is stored while
// A's writes are held and another caller waits for them. (The waiter used
// to wait holding the lock of every camera's filter list.)
TEST(GigeRegisters, OneCamerasHeldWritesDoNotHoldUpAnothers) {
  ArvFakeCamera* a = arv_fake_camera_new_full("CSHOOKA", nullptr);
  ArvFakeCamera* b = arv_fake_camera_new_full("CSHOOKB", nullptr);
  ASSERT_NE(a, nullptr);
  ASSERT_NE(b, nullptr);
  const genicam::WriteFilter pass = [](void*, uint32_t, uint32_t, uint8_t*) { return genicam::WriteVerdict{}; };
  genicam::SetWriteFilter(a, pass, nullptr);
  genicam::SetWriteFilter(b, pass, nullptr);
  auto held = std::make_unique<genicam::ClientWritesHeld>(a);
  std::thread waiter([a] { genicam::ClientWritesHeld wait_for_a(a); });
  for (int i = 0; i < 2000 && genicam::FilterUsers(a) < 2; ++i) std::this_thread::sleep_for(std::chrono::milliseconds(1));
  EXPECT_EQ(genicam::FilterUsers(a), 2) << "the waiter does not wait for A";  // held + waiter
  std::atomic<bool> written{false};
  std::thread writer([b, &written] {
    const uint8_t v[4] = {0, 0, 0, 32};
    written = arv_fake_camera_write_memory(b, reg::kWidth, 4, v);
  });
  for (int i = 0; i < 200 && !written; ++i) std::this_thread::sleep_for(std::chrono::milliseconds(10));
  EXPECT_TRUE(written) << "B's write waited for A's";
  held.reset();
  waiter.join();
  writer.join();
  uint8_t width[4] = {};
  ASSERT_TRUE(arv_fake_camera_read_memory(b, reg::kWidth, 4, width));
  EXPECT_EQ(width[3], 32);
  genicam::SetWriteFilter(a, nullptr, nullptr);
  genicam::SetWriteFilter(b, nullptr, nullptr);
  g_object_unref(a);
  g_object_unref(b);
}

// A filter set in place of another decides the next write; removed, none does.
TEST(GigeRegisters, AReplacedFilterDecidesTheNextWrite) {
  ArvFakeCamera* camera = arv_fake_camera_new_full("CSHOOKR", nullptr);
  ASSERT_NE(camera, nullptr);
  const genicam::WriteFilter refuse = [](void*, uint32_t, uint32_t, uint8_t*) {
    return genicam::WriteVerdict{false, genicam::GevStatus::kAccessDenied};
  };
  const genicam::WriteFilter pass = [](void*, uint32_t, uint32_t, uint8_t*) { return genicam::WriteVerdict{}; };
  const uint8_t v[4] = {0, 0, 0, 48};
  genicam::SetWriteFilter(camera, refuse, nullptr);
  EXPECT_FALSE(arv_fake_camera_write_memory(camera, reg::kWidth, 4, v));
  genicam::SetWriteFilter(camera, pass, nullptr);
  EXPECT_TRUE(arv_fake_camera_write_memory(camera, reg::kWidth, 4, v));
  genicam::SetWriteFilter(camera, refuse, nullptr);
  EXPECT_FALSE(arv_fake_camera_write_memory(camera, reg::kWidth, 4, v));
  genicam::SetWriteFilter(camera, nullptr, nullptr);
  EXPECT_TRUE(arv_fake_camera_write_memory(camera, reg::kWidth, 4, v));
  g_object_unref(camera);
}

// A fake camera serves from its creation; until its device sets its filter,
// a client's write is refused, and the creating thread's writes are stored.
TEST(GigeRegisters, ClientWritesBeforeTheFilterIsSetAreRefused) {
  const uint8_t v[4] = {0, 0, 0, 48};
  const genicam::WriteFilter pass = [](void*, uint32_t, uint32_t, uint8_t*) { return genicam::WriteVerdict{}; };
  ArvFakeCamera* camera = nullptr;
  std::atomic<int> client_write{-1};  // a write from another thread (a GVCP thread's): 1 taken, 0 refused
  const auto write_from_client = [&] {
    std::thread t([&] { client_write = arv_fake_camera_write_memory(camera, reg::kWidth, 4, v) ? 1 : 0; });
    t.join();
    return client_write.load();
  };
  uint32_t width = 0;
  {
    const genicam::UnfilteredWritesRefused starting;
    camera = arv_fake_camera_new_full("CSHOOKU", nullptr);
    ASSERT_NE(camera, nullptr);
    const uint8_t own[4] = {0, 0, 0, 64};
    EXPECT_TRUE(arv_fake_camera_write_memory(camera, reg::kWidth, 4, own)) << "the device's own write";
    EXPECT_EQ(write_from_client(), 0);
    ASSERT_TRUE(arv_fake_camera_read_register(camera, reg::kWidth, &width));
    EXPECT_EQ(width, 64u) << "the refused write was stored";
    genicam::SetWriteFilter(camera, pass, nullptr);
    EXPECT_EQ(write_from_client(), 1) << "the filter decides once it is set";
    genicam::SetWriteFilter(camera, nullptr, nullptr);
    EXPECT_EQ(write_from_client(), 0) << "no filter again while the device is still starting";
  }
  EXPECT_EQ(write_from_client(), 1) << "a camera without a device takes client writes";
  ASSERT_TRUE(arv_fake_camera_read_register(camera, reg::kWidth, &width));
  EXPECT_EQ(width, 48u);
  g_object_unref(camera);
}

// SFNC's TLParamsLocked: a GenTL consumer sets it before AcquisitionStart;
// from then on the payload's features are locked until it is cleared.
TEST(GigeRegisters, TLParamsLockedLocksTheGeometry) {
  DeviceOptions o = OfflineDevice();
  auto d = StartDevice(o);
  ASSERT_NE(d, nullptr);
  WriteReg(*d, reg::kControlChannelPrivilege, Be32(2));  // a controlling client (without one the sync unlocks)
  WriteReg(*d, reg::kWidth, Be32(32));  // found together with the lock: taken
  WriteReg(*d, reg::kTLParamsLocked, Be32(1));
  d->SyncNow();
  EXPECT_EQ(ReadReg32(*d, reg::kWidth), 32u);
  WriteRegRefused(*d, reg::kWidth, Be32(16));
  WriteRegRefused(*d, reg::kPixelFormat, Be32(genicam::BayerCode(Cfa::kBayerRG, 8)));
  WriteReg(*d, reg::kExposureTime, Be64(2000.0));  // not a payload feature: taken
  d->SyncNow();
  EXPECT_EQ(ReadReg32(*d, reg::kWidth), 32u);
  EXPECT_EQ(ReadReg32(*d, reg::kPixelFormat), genicam::BayerCode(Cfa::kBayerRG, 12));
  EXPECT_EQ(ReadRegDouble(*d, reg::kExposureTime), 2000.0);
  EXPECT_EQ(d->writes_refused(), 2u);
  EXPECT_EQ(d->CheckInvariants(), "");
  WriteReg(*d, reg::kTLParamsLocked, Be32(0));
  d->SyncNow();
  WriteReg(*d, reg::kWidth, Be32(16));
  d->SyncNow();
  EXPECT_EQ(ReadReg32(*d, reg::kWidth), 16u);
  EXPECT_EQ(d->writes_refused(), 2u);
  // A client that locks and goes away: its control ends (privilege 0, here
  // followed at once by the next client's request, as when the fake camera
  // hands control over inside one packet), the lock with it, and the next
  // client's window is taken.
  WriteReg(*d, reg::kTLParamsLocked, Be32(1));
  d->SyncNow();
  WriteReg(*d, reg::kControlChannelPrivilege, Be32(0));
  WriteReg(*d, reg::kControlChannelPrivilege, Be32(2));
  d->SyncNow();
  EXPECT_EQ(ReadReg32(*d, reg::kTLParamsLocked), 0u);
  WriteReg(*d, reg::kWidth, Be32(32));
  d->SyncNow();
  EXPECT_EQ(ReadReg32(*d, reg::kWidth), 32u);
  // With no client in control, the sync unlocks too.
  WriteReg(*d, reg::kControlChannelPrivilege, Be32(0));
  d->SyncNow();
  WriteReg(*d, reg::kTLParamsLocked, Be32(1));
  d->SyncNow();
  EXPECT_EQ(ReadReg32(*d, reg::kTLParamsLocked), 0u);
  EXPECT_EQ(d->writes_refused(), 2u);
  EXPECT_EQ(d->CheckInvariants(), "");
}

TEST(GigeRegisters, ConfiguredExposureIsReportedAndKeptAsRendered) {
  DeviceOptions o = OfflineDevice();
  // f/64 keeps the 2 s exposure below saturation, so 1 s and 2 s frames differ.
  o.overrides.insert(o.overrides.end(), {"exposure.exposure_time_us=2000000", "exposure.f_number=64"});
  auto d = StartDevice(o);
  ASSERT_NE(d, nullptr);
  EXPECT_EQ(ReadRegDouble(*d, reg::kExposureTime), 2e6);
  const uint32_t code = genicam::BayerCode(Cfa::kBayerRG, 12);
  std::vector<uint8_t> frame;
  ASSERT_TRUE(d->RenderNow(&frame));
  EXPECT_TRUE(frame == ReferenceFrame(o, 0, code, 0, 0, 64, 48));
  EXPECT_FALSE(frame == ReferenceFrame(o, 0, code, 0, 0, 64, 48, {"exposure.exposure_time_us=1000000"}));
  WriteReg(*d, reg::kGain, Be64(1.0));
  d->SyncNow();
  EXPECT_EQ(d->CheckInvariants(), "");
  EXPECT_EQ(d->writes_refused(), 0u);
  EXPECT_EQ(ReadRegDouble(*d, reg::kExposureTime), 2e6);
  ASSERT_TRUE(d->RenderNow(&frame));
  EXPECT_TRUE(frame == ReferenceFrame(o, 1, code, 0, 0, 64, 48, {"sensor.gain_db=1.0"})) << "exposure changed";
}

// AcquisitionResultingFrameRate: with AcquisitionFrameRateEnable,
// AcquisitionFrameRate or 1 / ExposureTime, whichever is lower
// (FramePeriod); never faster than the last frame's rendering (a 64 x 48
// frame renders in well under a second, and in more than 1 us).
TEST(GigeRegisters, ResultingFrameRateFollowsRateExposureAndRendering) {
  auto d = StartDevice(OfflineDevice());
  ASSERT_NE(d, nullptr);
  EXPECT_EQ(ReadRegDouble(*d, reg::kAcquisitionResultingFrameRate), 25.0);  // 25 Hz, 10 ms exposure
  WriteReg(*d, reg::kAcquisitionFrameRate, Be64(5.0));
  d->SyncNow();
  EXPECT_EQ(ReadRegDouble(*d, reg::kAcquisitionResultingFrameRate), 5.0);
  WriteReg(*d, reg::kExposureTime, Be64(1e6));
  d->SyncNow();
  EXPECT_EQ(ReadRegDouble(*d, reg::kAcquisitionResultingFrameRate), 1.0);
  std::vector<uint8_t> frame;
  ASSERT_TRUE(d->RenderNow(&frame));
  EXPECT_EQ(ReadRegDouble(*d, reg::kAcquisitionResultingFrameRate), 1.0);
  // Without AcquisitionFrameRate frames come as fast as they render: the
  // exposure does not pace them.
  WriteReg(*d, reg::kAcquisitionFrameRateEnable, Be32(0));
  d->SyncNow();
  const double rate = ReadRegDouble(*d, reg::kAcquisitionResultingFrameRate);
  EXPECT_GT(rate, 1.0);
  EXPECT_LT(rate, 1e6);
  // Read-only: a client's write is refused.
  WriteRegRefused(*d, reg::kAcquisitionResultingFrameRate, Be64(3.0));
}

// SimFocusDistance is dof.focus_distance_m: the frames follow it as the
// core renders them with that setting (the pattern's depth is a plane from
// 0.5 m to 8 m), and a distance the lens cannot focus at (not beyond its
// focal length: below the XML's Min) is refused as it arrives.
TEST(GigeRegisters, SimFocusDistanceMovesTheFocus) {
  DeviceOptions o = OfflineDevice();
  o.pattern = "checker";
  o.overrides.push_back("dof.method=diffusion");
  o.overrides.push_back("dof.focus_distance_m=1.0");
  auto d = StartDevice(o);
  ASSERT_NE(d, nullptr);
  EXPECT_EQ(ReadRegDouble(*d, reg::kSimFocusDistance), 1.0);
  const uint32_t code = genicam::BayerCode(Cfa::kBayerRG, 12);
  std::vector<uint8_t> frame;
  ASSERT_TRUE(d->RenderNow(&frame));
  EXPECT_EQ(frame, ReferenceFrame(o, 0, code, 0, 0, 64, 48));
  WriteReg(*d, reg::kSimFocusDistance, Be64(6.0));
  d->SyncNow();
  ASSERT_TRUE(d->RenderNow(&frame));
  EXPECT_EQ(frame, ReferenceFrame(o, 1, code, 0, 0, 64, 48, {"dof.focus_distance_m=6.0"}));
  EXPECT_NE(frame, ReferenceFrame(o, 1, code, 0, 0, 64, 48)) << "the focus distance changes nothing in this scene";
  WriteRegRefused(*d, reg::kSimFocusDistance, Be64(0.002));  // the demo lens's focal length is longer
  EXPECT_EQ(ReadRegDouble(*d, reg::kSimFocusDistance), 6.0) << "refused as it arrives";
  EXPECT_EQ(d->writes_refused(), 1u);
  d->SyncNow();
  EXPECT_EQ(ReadRegDouble(*d, reg::kSimFocusDistance), 6.0);
  EXPECT_EQ(d->writes_refused(), 1u);
  EXPECT_EQ(d->CheckInvariants(), "");
  // The XML's Min is a value the device takes (GenApi: bounds are valid
  // values); a millimetre less is the focal length or shorter.
  const genicam::Feature* focus = genicam::FindFeature(d->table(), "SimFocusDistance");
  ASSERT_NE(focus, nullptr);
  EXPECT_GT(focus->min, reg::kMinFocusDistanceM);
  WriteReg(*d, reg::kSimFocusDistance, Be64(focus->min));
  WriteRegRefused(*d, reg::kSimFocusDistance, Be64(focus->min - 0.001));
}

// The filter plans a pipeline write as it arrives; the sync installs that
// plan instead of planning again, but only while the registers still ask
// for its settings.
TEST(GigeRegisters, TheSyncInstallsThePlanTheWriteMade) {
  DeviceOptions o = OfflineDevice();
  auto d = StartDevice(o);
  ASSERT_NE(d, nullptr);
  const uint32_t code = genicam::BayerCode(Cfa::kBayerRG, 12);
  std::vector<uint8_t> frame;
  uint64_t planned = d->pipelines_planned();
  WriteReg(*d, reg::kExposureTime, Be64(2500.0));
  EXPECT_EQ(d->pipelines_planned(), ++planned) << "the write is planned as it arrives";
  d->SyncNow();
  EXPECT_EQ(d->pipelines_planned(), planned) << "the sync planned it again";
  ASSERT_TRUE(d->RenderNow(&frame));
  EXPECT_EQ(frame, ReferenceFrame(o, 0, code, 0, 0, 64, 48, {"exposure.exposure_time_us=2500"}));

  // A refused write plans too, and leaves the plan of the write before it.
  WriteReg(*d, reg::kExposureTime, Be64(4000.0));
  testing::internal::CaptureStderr();
  const uint32_t cfa_enable = StageEnableAddress(*d, "Stage_cfa");
  ASSERT_NE(cfa_enable, 0u);
  WriteRegRefused(*d, cfa_enable, Be32(0));  // the raw format needs the mosaic
  testing::internal::GetCapturedStderr();
  planned += 2;
  d->SyncNow();
  EXPECT_EQ(d->pipelines_planned(), planned);
  ASSERT_TRUE(d->RenderNow(&frame));
  EXPECT_EQ(frame, ReferenceFrame(o, 1, code, 0, 0, 64, 48, {"exposure.exposure_time_us=4000"}));

  // A write the filter did not see (the device's own) changes the settings
  // after the plan: the sync plans what the registers ask for.
  WriteReg(*d, reg::kExposureTime, Be64(6000.0));
  {
    const genicam::DeviceWrites own;
    const std::vector<uint8_t> t = Be64(3000.0);
    ASSERT_TRUE(d->WriteMemory(reg::kExposureTime, t.data(), static_cast<uint32_t>(t.size())));
  }
  planned += 2;
  d->SyncNow();
  EXPECT_EQ(d->pipelines_planned(), planned);
  ASSERT_TRUE(d->RenderNow(&frame));
  EXPECT_EQ(frame, ReferenceFrame(o, 2, code, 0, 0, 64, 48, {"exposure.exposure_time_us=3000"}));
  EXPECT_EQ(d->CheckInvariants(), "");
}

// The sync's fallback: pipeline settings the pipeline cannot run that
// reached the registers past the filter (a client's write is refused as it
// arrives; the device's own is not checked) go back together at the sync,
// with a line on stderr and each counted as refused; the sync's other
// settings stay, and frames keep coming from the pipeline in use.
TEST(GigeRegisters, TheSyncPutsBackPipelineSettingsItCannotRun) {
  DeviceOptions o = OfflineDevice();
  auto d = StartDevice(o);
  ASSERT_NE(d, nullptr);
  const uint32_t cfa_enable = StageEnableAddress(*d, "Stage_cfa");
  ASSERT_NE(cfa_enable, 0u);
  const double exposure = ReadRegDouble(*d, reg::kExposureTime);
  const uint64_t refused = d->writes_refused();
  {
    const genicam::DeviceWrites own;
    WriteReg(*d, cfa_enable, Be32(0));  // the raw format needs the mosaic
    WriteReg(*d, reg::kExposureTime, Be64(4000.0));
    WriteReg(*d, reg::kAcquisitionFrameRate, Be64(5.0));
  }
  testing::internal::CaptureStderr();
  d->SyncNow();
  const std::string err = testing::internal::GetCapturedStderr();
  EXPECT_NE(err.find("camsim-gige: refused:"), std::string::npos) << err;
  EXPECT_EQ(ReadReg32(*d, cfa_enable), 1u);
  EXPECT_EQ(ReadRegDouble(*d, reg::kExposureTime), exposure) << "the sync's pipeline settings go back together";
  EXPECT_EQ(ReadRegDouble(*d, reg::kAcquisitionFrameRate), 5.0) << "the other settings stay";
  EXPECT_EQ(d->writes_refused(), refused + 2);
  std::vector<uint8_t> frame;
  ASSERT_TRUE(d->RenderNow(&frame));
  EXPECT_EQ(frame, ReferenceFrame(o, 0, genicam::BayerCode(Cfa::kBayerRG, 12), 0, 0, 64, 48));
  EXPECT_EQ(d->CheckInvariants(), "");
}

// SimAutoTarget takes what the controller uses (0.01 .. 0.9), and nothing more.
TEST(GigeRegisters, SimAutoTargetAboveTheControllersMaximumIsRefused) {
  DeviceOptions o = OfflineDevice();
  auto d = StartDevice(o);
  ASSERT_NE(d, nullptr);
  WriteRegRefused(*d, reg::kSimAutoTarget, Be64(0.95));
  EXPECT_EQ(d->writes_refused(), 1u);
  d->SyncNow();
  EXPECT_EQ(d->writes_refused(), 1u);
  EXPECT_EQ(ReadRegDouble(*d, reg::kSimAutoTarget), 0.4);
  WriteReg(*d, reg::kSimAutoTarget, Be64(0.9));
  d->SyncNow();
  EXPECT_EQ(d->writes_refused(), 1u);
  EXPECT_EQ(ReadRegDouble(*d, reg::kSimAutoTarget), 0.9);
  EXPECT_EQ(d->CheckInvariants(), "");
}

// A feature that is Off keeps its value to the bit: ExposureAuto alone does
// not move Gain (the controller holds it; 3.14 is applied as its step, 3.1).
TEST(GigeRegisters, AutoExposureLeavesAGainThatIsOffAsWritten) {
  auto d = StartDevice(OfflineDevice());
  ASSERT_NE(d, nullptr);
  WriteReg(*d, reg::kGain, Be64(3.14));
  EXPECT_EQ(ReadRegDouble(*d, reg::kGain), 3.1);
  WriteReg(*d, reg::kSimAutoTarget, Be64(0.05));
  WriteReg(*d, reg::kExposureAuto, Be32(genicam::kAutoContinuous));
  d->SyncNow();
  const double t0 = ReadRegDouble(*d, reg::kExposureTime);
  std::vector<uint8_t> frame;
  for (int i = 0; i < 4; ++i) ASSERT_TRUE(d->RenderNow(&frame));
  EXPECT_NE(ReadRegDouble(*d, reg::kExposureTime), t0) << "ExposureAuto did not act";
  EXPECT_EQ(ReadRegDouble(*d, reg::kGain), 3.1);
  EXPECT_EQ(d->CheckInvariants(), "");
}

// Auto exposure asks for what the pipeline refuses: with CCD smear the core
// needs exposure >= leak (1) x row transfer time (1000 us). The controller's
// range ends there: Once stops at the limit and turns Off, Continuous holds
// there, and the refusal is logged once.
TEST(GigeRegisters, AutoExposureStopsWhereThePipelineDoes) {
  DeviceOptions o = OfflineDevice();
  o.overrides.push_back("sensor.smear_row_transfer_us=1000");
  auto d = StartDevice(o);
  ASSERT_NE(d, nullptr);
  WriteReg(*d, reg::kSimAutoTarget, Be64(0.01));  // far below the level at 1 ms
  WriteReg(*d, reg::kExposureAuto, Be32(genicam::kAutoOnce));
  d->SyncNow();
  testing::internal::CaptureStderr();
  std::vector<uint8_t> frame;
  uint32_t frames = 0;
  for (; frames < 20 && ReadReg32(*d, reg::kExposureAuto) == genicam::kAutoOnce; ++frames)
    ASSERT_TRUE(d->RenderNow(&frame));
  EXPECT_EQ(ReadReg32(*d, reg::kExposureAuto), uint32_t(genicam::kAutoOff)) << "Once ends at the limit";
  double t = ReadRegDouble(*d, reg::kExposureTime);
  EXPECT_GE(t, 1000.0);
  EXPECT_LT(t, 1001.0) << "Once stopped short of the limit";
  EXPECT_EQ(d->CheckInvariants(), "");
  ASSERT_TRUE(d->RenderNow(&frame));
  char exposure[64];
  std::snprintf(exposure, sizeof exposure, "exposure.exposure_time_us=%.17g", t);
  const uint32_t code = genicam::BayerCode(Cfa::kBayerRG, 12);
  EXPECT_TRUE(frame == ReferenceFrame(o, frames, code, 0, 0, 64, 48, {exposure})) << "not rendered as reported";
  WriteReg(*d, reg::kExposureAuto, Be32(genicam::kAutoContinuous));
  d->SyncNow();
  for (int i = 0; i < 8; ++i) ASSERT_TRUE(d->RenderNow(&frame));
  EXPECT_EQ(ReadReg32(*d, reg::kExposureAuto), uint32_t(genicam::kAutoContinuous));
  t = ReadRegDouble(*d, reg::kExposureTime);
  EXPECT_GE(t, 1000.0);
  EXPECT_LT(t, 1001.0) << "Continuous left the limit";
  const std::string log = testing::internal::GetCapturedStderr();
  const std::string refused = "the pipeline refuses";
  size_t logged = 0;
  for (size_t at = log.find(refused); at != std::string::npos; at = log.find(refused, at + 1)) ++logged;
  EXPECT_EQ(logged, 1u) << log;
  EXPECT_NE(log.find("sensor.smear_row_transfer_us"), std::string::npos) << log;
}

// The Auto features act inside their limits (AutoExposureTimeLowerLimit ..
// UpperLimit, AutoGainLowerLimit .. UpperLimit), not the features' whole
// ranges. A dark scene (the lens closed to f/128) and a target it never
// reaches: Continuous used to drive ExposureTime to 1e8 us (with
// AcquisitionFrameRateEnable, a 100 s frame); now exposure and gain stop at
// the upper limits. A change of a limit restarts the controller inside the
// new range; a bright scene and a low target stop at the lower limits.
TEST(GigeRegisters, AutoStopsAtTheAutoLimits) {
  DeviceOptions o = OfflineDevice();
  auto d = StartDevice(o);
  ASSERT_NE(d, nullptr);
  // `camsim run`'s range (core/control/auto_exposure.h, AutoExposureConfig).
  EXPECT_EQ(ReadRegDouble(*d, reg::kAutoExposureTimeLowerLimit), 20.0);
  EXPECT_EQ(ReadRegDouble(*d, reg::kAutoExposureTimeUpperLimit), 100000.0);
  EXPECT_EQ(ReadRegDouble(*d, reg::kAutoGainLowerLimit), 0.0);
  EXPECT_EQ(ReadRegDouble(*d, reg::kAutoGainUpperLimit), 24.0);
  WriteReg(*d, reg::kSimFNumber, Be64(128.0));
  WriteReg(*d, reg::kSimAutoTarget, Be64(0.9));  // the controller's largest target
  WriteReg(*d, reg::kExposureAuto, Be32(genicam::kAutoContinuous));
  WriteReg(*d, reg::kGainAuto, Be32(genicam::kAutoContinuous));
  d->SyncNow();
  std::vector<uint8_t> frame;
  // Renders `frames` frames; the gain stays inside [gain_lo, gain_hi] all along.
  const auto run = [&](int frames, double gain_lo, double gain_hi) {
    for (int i = 0; i < frames; ++i) {
      ASSERT_TRUE(d->RenderNow(&frame));
      const double g = ReadRegDouble(*d, reg::kGain);
      EXPECT_GE(g, gain_lo) << "frame " << i;
      EXPECT_LE(g, gain_hi) << "frame " << i;
    }
    EXPECT_EQ(d->CheckInvariants(), "");
  };
  ASSERT_NO_FATAL_FAILURE(run(12, 0.0, 24.0));
  EXPECT_EQ(ReadRegDouble(*d, reg::kExposureTime), 100000.0);
  EXPECT_EQ(ReadRegDouble(*d, reg::kGain), 24.0);
  EXPECT_LT(MeanLevel12(frame), 0.9 / 8) << "the target is 3 EV out of reach";
  EXPECT_EQ(ReadReg32(*d, reg::kExposureAuto), uint32_t(genicam::kAutoContinuous));
  // Narrower limits while running, the gain's between GainRaw's 0.1 dB steps.
  WriteReg(*d, reg::kAutoExposureTimeUpperLimit, Be64(40000.0));
  WriteReg(*d, reg::kAutoGainLowerLimit, Be64(3.04));
  WriteReg(*d, reg::kAutoGainUpperLimit, Be64(6.06));
  d->SyncNow();
  ASSERT_NO_FATAL_FAILURE(run(4, 3.04, 6.06));
  EXPECT_EQ(ReadRegDouble(*d, reg::kExposureTime), 40000.0);
  EXPECT_EQ(ReadRegDouble(*d, reg::kGain), 6.0) << "the last step inside the limit, not 6.1 past it";
  // The lens open again (f/2.8) and a target below what the scene gives at the lower limits.
  WriteReg(*d, reg::kAutoExposureTimeLowerLimit, Be64(2000.0));
  WriteReg(*d, reg::kSimFNumber, Be64(2.8));
  WriteReg(*d, reg::kSimAutoTarget, Be64(0.01));
  d->SyncNow();
  ASSERT_NO_FATAL_FAILURE(run(8, 3.04, 6.06));
  EXPECT_EQ(ReadRegDouble(*d, reg::kExposureTime), 2000.0);
  EXPECT_EQ(ReadRegDouble(*d, reg::kGain), 3.1) << "the first step inside the limit";
  EXPECT_GT(MeanLevel12(frame), 0.01 * 2) << "the target is out of reach below";
}

// ExposureTime written above the Auto limits before ExposureAuto goes on,
// and a pipeline that needs more than the upper limit (CCD smear: at least
// 1000 us): nothing within the limits runs. Both Auto features turn Off
// with an error that names the limits, not the controller's own keys.
TEST(GigeRegisters, AutoLimitsThePipelineRefusesTurnAutoOffNamingThem) {
  DeviceOptions o = OfflineDevice();
  o.overrides.push_back("sensor.smear_row_transfer_us=1000");
  auto d = StartDevice(o);
  ASSERT_NE(d, nullptr);
  WriteReg(*d, reg::kExposureTime, Be64(5000.0));
  WriteReg(*d, reg::kAutoExposureTimeUpperLimit, Be64(500.0));
  WriteReg(*d, reg::kExposureAuto, Be32(genicam::kAutoContinuous));
  d->SyncNow();
  testing::internal::CaptureStderr();
  std::vector<uint8_t> frame;
  for (int i = 0; i < 3; ++i) ASSERT_TRUE(d->RenderNow(&frame));
  const std::string log = testing::internal::GetCapturedStderr();
  EXPECT_EQ(ReadReg32(*d, reg::kExposureAuto), uint32_t(genicam::kAutoOff));
  EXPECT_NE(log.find("the pipeline refuses every setting within the Auto limits, ExposureTime 20..500 us"),
            std::string::npos)
      << log;
  EXPECT_GE(ReadRegDouble(*d, reg::kExposureTime), 1000.0);
  EXPECT_EQ(d->CheckInvariants(), "");
}

// An Auto lower limit above its upper limit is refused as it arrives (each
// one's pMax / pMin in the XML is the other's value); in one block with
// both, the lower one is set back and the upper one kept, as a window's
// offset and size are. The limit that widens the range goes first.
TEST(GigeRegisters, AnAutoLowerLimitAboveTheUpperIsRefused) {
  static_assert(reg::kAutoExposureTimeUpperLimit == reg::kAutoExposureTimeLowerLimit + 8);
  auto d = StartDevice(OfflineDevice());
  ASSERT_NE(d, nullptr);
  WriteRegRefused(*d, reg::kAutoExposureTimeLowerLimit, Be64(200000.0));  // above 100000 us
  WriteRegRefused(*d, reg::kAutoGainUpperLimit, Be64(-1.0));               // below Gain's range
  WriteReg(*d, reg::kAutoGainLowerLimit, Be64(10.0));
  WriteRegRefused(*d, reg::kAutoGainUpperLimit, Be64(5.0));  // below the lower limit just written
  EXPECT_EQ(d->writes_refused(), 3u);
  std::vector<uint8_t> block = Be64(500000.0), upper = Be64(400000.0);  // lower, upper: crossed
  block.insert(block.end(), upper.begin(), upper.end());
  WriteRegRefused(*d, reg::kAutoExposureTimeLowerLimit, block);
  EXPECT_EQ(d->writes_refused(), 4u);
  EXPECT_EQ(ReadRegDouble(*d, reg::kAutoExposureTimeLowerLimit), 20.0);
  EXPECT_EQ(ReadRegDouble(*d, reg::kAutoExposureTimeUpperLimit), 400000.0);
  d->SyncNow();
  EXPECT_EQ(d->CheckInvariants(), "");
  EXPECT_EQ(ReadRegDouble(*d, reg::kAutoGainLowerLimit), 10.0);
  EXPECT_EQ(ReadRegDouble(*d, reg::kAutoGainUpperLimit), 24.0);
  block = Be64(400000.0);  // in order, in one block
  upper = Be64(500000.0);
  block.insert(block.end(), upper.begin(), upper.end());
  WriteReg(*d, reg::kAutoExposureTimeLowerLimit, block);
  WriteReg(*d, reg::kAutoGainLowerLimit, Be64(24.0));  // equal limits: a fixed gain
  d->SyncNow();
  EXPECT_EQ(d->writes_refused(), 4u);
  EXPECT_EQ(d->CheckInvariants(), "");
  EXPECT_EQ(ReadRegDouble(*d, reg::kAutoExposureTimeLowerLimit), 400000.0);
  EXPECT_EQ(ReadRegDouble(*d, reg::kAutoExposureTimeUpperLimit), 500000.0);
  EXPECT_EQ(ReadRegDouble(*d, reg::kAutoGainLowerLimit), 24.0);
}

// An output the device cannot lower: the strobe stays high, and LineStatus says so.
class StuckHighLine : public hal::OutputLine {
 public:
  bool Set(bool high, std::string* error) override {
    if (high) return true;
    *error = "stuck high";
    return false;
  }
  std::string Name() const override { return "stuck"; }
};

// LineStatus on Line1 is the strobe's level as last driven.
TEST(GigeRegisters, LineStatusFollowsTheStrobe) {
  for (bool stuck : {false, true}) {
    SCOPED_TRACE(stuck ? "stuck high" : "memory line");
    hal::MemoryLine memory("strobe");
    StuckHighLine stuck_line;
    DeviceOptions o = OfflineDevice();
    o.strobe = stuck ? static_cast<hal::OutputLine*>(&stuck_line) : &memory;
    auto d = StartDevice(o);
    ASSERT_NE(d, nullptr);
    const uint32_t line0_status = genicam::reg::SelectedAddress(reg::kLineStatus, 0);
    const uint32_t line1_status = genicam::reg::SelectedAddress(reg::kLineStatus, 1);
    WriteReg(*d, genicam::reg::SelectedAddress(reg::kLineSource, 1), Be32(genicam::kLineSourceExposureActive));
    d->SyncNow();
    EXPECT_EQ(ReadReg32(*d, line1_status), 0u) << "before a frame";
    std::vector<uint8_t> frame;
    ASSERT_TRUE(d->RenderNow(&frame));
    EXPECT_EQ(ReadReg32(*d, line1_status), stuck ? 1u : 0u);
    EXPECT_EQ(d->line_error(), stuck ? "stuck high" : "");
    EXPECT_EQ(memory.edges(), stuck ? 0 : 2);
    EXPECT_EQ(ReadReg32(*d, line0_status), 0u) << "Line0: no trigger line, low";
  }
}

// An output whose next falling edge fails once; it records the edges it
// sent and the frame index each carried.
class FailsOnceLowLine : public hal::OutputLine {
 public:
  bool fail_next_low = false;
  std::vector<std::pair<bool, uint32_t>> sent;
  bool Set(bool high, std::string* error) override {
    if (!high && fail_next_low) {
      fail_next_low = false;
      *error = "failed once";
      return false;
    }
    sent.emplace_back(high, index_);
    return true;
  }
  void SetEdgeIndex(uint32_t index) override { index_ = index; }
  std::string Name() const override { return "fails once"; }

 private:
  uint32_t index_ = 0;
};

// A frame whose falling edge failed does not leave the strobe high, nor cost
// the next frame its rising edge: the next register sync lowers it.
TEST(GigeRegisters, AStrobeEdgeThatFailedIsSentBeforeTheNextPulse) {
  FailsOnceLowLine line;
  DeviceOptions o = OfflineDevice();
  o.strobe = &line;
  auto d = StartDevice(o);
  ASSERT_NE(d, nullptr);
  WriteReg(*d, genicam::reg::SelectedAddress(reg::kLineSource, 1), Be32(genicam::kLineSourceExposureActive));
  WriteReg(*d, reg::kSimFrameIndex, Be32(7));
  d->SyncNow();
  std::vector<uint8_t> frame;
  line.fail_next_low = true;
  ASSERT_TRUE(d->RenderNow(&frame));
  EXPECT_EQ(d->line_error(), "failed once");
  EXPECT_EQ(ReadReg32(*d, genicam::reg::SelectedAddress(reg::kLineStatus, 1)), 1u) << "the strobe stayed high";
  d->SyncNow();
  EXPECT_EQ(ReadReg32(*d, genicam::reg::SelectedAddress(reg::kLineStatus, 1)), 0u) << "the sync lowers it";
  EXPECT_EQ(line.sent.size(), 2u);
  ASSERT_TRUE(d->RenderNow(&frame));
  const std::vector<std::pair<bool, uint32_t>> want = {{true, 7}, {false, 7}, {true, 8}, {false, 8}};
  EXPECT_EQ(line.sent, want);
  EXPECT_EQ(ReadReg32(*d, genicam::reg::SelectedAddress(reg::kLineStatus, 1)), 0u);
}

// LineInverter[Line1] inverts the strobe on the wire: idle high (driven at
// the sync that applies it), low while a frame is made; LineStatus and the
// frame's ChunkLineStatusAll say the wire's level.
TEST(GigeRegisters, AnInvertedStrobeIsLowWhileAFrameIsMade) {
  FailsOnceLowLine line;  // (never told to fail: records the edges)
  DeviceOptions o = OfflineDevice();
  o.strobe = &line;
  auto d = StartDevice(o);
  ASSERT_NE(d, nullptr);
  const uint32_t line1_status = genicam::reg::SelectedAddress(reg::kLineStatus, 1);
  WriteReg(*d, genicam::reg::SelectedAddress(reg::kLineSource, 1), Be32(genicam::kLineSourceExposureActive));
  WriteReg(*d, genicam::reg::SelectedAddress(reg::kLineInverter, 1), Be32(1));
  WriteReg(*d, reg::kSimFrameIndex, Be32(3));
  d->SyncNow();
  EXPECT_EQ(ReadReg32(*d, line1_status), 1u) << "idle: high on the wire";
  std::vector<uint8_t> frame;
  ASSERT_TRUE(d->RenderNow(&frame));
  const std::vector<std::pair<bool, uint32_t>> want = {{true, 0}, {false, 3}, {true, 3}};
  EXPECT_EQ(line.sent, want) << "high at the sync, low for the frame, high again";
  EXPECT_EQ(ReadReg32(*d, line1_status), 1u);
  // Back to not inverted: the sync lowers the idle line.
  WriteReg(*d, genicam::reg::SelectedAddress(reg::kLineInverter, 1), Be32(0));
  d->SyncNow();
  EXPECT_EQ(ReadReg32(*d, line1_status), 0u);
  EXPECT_FALSE(line.sent.back().first);
  EXPECT_EQ(d->line_error(), "");
}

// ---------------------------------------------------------------- end to end

class GigeE2E : public ::testing::Test {
 protected:
  // Call through ASSERT_NO_FATAL_FAILURE: an ASSERT here leaves only this
  // function, and a test going on without a camera would crash.
  void StartWith(const DeviceOptions& o) {
    options_ = o;
    device_ = StartDevice(o);
    ASSERT_NE(device_, nullptr);
    client_ = std::make_unique<Client>("127.0.0.1");
    ASSERT_TRUE(client_->ok()) << client_->last_error;
    g_client = client_.get();
  }
  void TearDown() override {
    if (chunks_ != nullptr) g_object_unref(chunks_);
    chunks_ = nullptr;
    g_client = nullptr;
    client_.reset();
    device_.reset();
  }
  std::vector<uint8_t> Reference(uint32_t index, uint32_t format, int x, int y, int w, int h,
                                 const std::vector<std::string>& extra = {}) {
    return ReferenceFrame(options_, index, format, x, y, w, h, extra);
  }

  // The trigger tests' steps. StartWith with trigger_ as the Line0 input
  // (call through ASSERT_NO_FATAL_FAILURE, as StartWith).
  void StartWithTriggerLine(DeviceOptions o = SmallDevice()) {
    o.trigger = &trigger_;
    StartWith(o);
  }
  // StartWith a device whose Line0 is a trigger bus in a fresh directory
  // (bus_dir_); EndTriggerBus stops client and device and checks that the
  // directory is left empty. Call through ASSERT_NO_FATAL_FAILURE.
  void StartWithTriggerBus(const char* name) {
    bus_dir_ = testing::TempDir() + name + "-" + std::to_string(getpid());
    DeviceOptions o = SmallDevice();
    o.trigger_line = "unix:" + bus_dir_;
    StartWith(o);
  }
  void EndTriggerBus() {
    client_.reset();
    device_.reset();
    EXPECT_EQ(rmdir(bus_dir_.c_str()), 0);
  }
  // The stream opened, the acquisition started and settled (call through ASSERT_NO_FATAL_FAILURE).
  void OpenAndStart() {
    ASSERT_TRUE(client_->OpenStream());
    Start(*client_);
    Settle();
  }
  // TriggerMode On at FrameStart from `source`, on `activation` when given.
  void TriggerOn(const char* source, const char* activation = nullptr) {
    Client& c = *client_;
    Set(c, "TriggerSelector", "FrameStart");
    Set(c, "TriggerMode", "On");
    Set(c, "TriggerSource", source);
    if (activation != nullptr) Set(c, "TriggerActivation", activation);
  }
  // Chunk mode on (chunks_ parses the frames), the stream opened, the
  // acquisition started and settled. Call through ASSERT_NO_FATAL_FAILURE.
  void StartWithChunks() {
    Client& c = *client_;
    GError* e = nullptr;
    arv_camera_set_boolean(c.camera(), "ChunkModeActive", TRUE, &e);
    ASSERT_EQ(e, nullptr);
    chunks_ = arv_camera_create_chunk_parser(c.camera());
    ASSERT_TRUE(c.OpenStream());
    Start(c);
    Settle();
  }
  void Line0(bool high) {  // trigger_'s level (a MemoryLine takes every level)
    std::string error;
    trigger_.Set(high, &error);
  }
  void Pulse(int high_ms) {  // trigger_ high for high_ms, then low
    Line0(true);
    Sleep(high_ms);
    Line0(false);
  }
  bool LineStatus() { return arv_camera_get_boolean(client_->camera(), "LineStatus", nullptr); }
  // Waits up to 2 s for LineStatus to read `want` (the trigger thread takes an edge, the sync a LineInverter).
  bool WaitLineStatus(bool want) {
    for (int i = 0; i < 400 && LineStatus() != want; ++i) Sleep(5);
    return LineStatus() == want;
  }
  // TriggerSoftware executed by the client.
  testing::AssertionResult SendTriggerSoftware() {
    GError* e = nullptr;
    arv_camera_execute_command(client_->camera(), "TriggerSoftware", &e);
    if (e == nullptr) return testing::AssertionSuccess();
    testing::AssertionResult failed = testing::AssertionFailure() << "TriggerSoftware: " << e->message;
    g_clear_error(&e);
    return failed;
  }

  DeviceOptions options_;
  hal::MemoryLine trigger_{"test-trigger"}, strobe_{"test-strobe"};  // outlive the device
  std::unique_ptr<GigeDevice> device_;
  std::unique_ptr<Client> client_;
  ArvChunkParser* chunks_ = nullptr;  // StartWithChunks's
  std::string bus_dir_;               // StartWithTriggerBus's
};

TEST_F(GigeE2E, ConnectsByAddressAndReadsFeatures) {
  ASSERT_NO_FATAL_FAILURE(StartWith(SmallDevice()));
  Client& c = *client_;
  EXPECT_STREQ(arv_camera_get_vendor_name(c.camera(), nullptr), "camsim");
  EXPECT_STREQ(arv_camera_get_model_name(c.camera(), nullptr), "camsim-gige");
  EXPECT_STREQ(arv_camera_get_device_serial_number(c.camera(), nullptr), "CS0001");
  EXPECT_EQ(ReadInt(c, "SensorWidth"), 64);
  EXPECT_EQ(ReadInt(c, "HeightMax"), 48);
  EXPECT_STREQ(arv_camera_get_pixel_format_as_string(c.camera(), nullptr), "BayerRG12");
  EXPECT_EQ(ReadInt(c, "PayloadSize"), 64 * 48 * 2);
  EXPECT_DOUBLE_EQ(ReadFloat(c, "ExposureTime"), 10000.0);  // configs/camera.toml
  EXPECT_DOUBLE_EQ(ReadFloat(c, "SimFNumber"), 2.8);
  guint n = 0;
  const char** formats = arv_camera_dup_available_pixel_formats_as_strings(c.camera(), &n, nullptr);
  std::vector<std::string> names(formats, formats + n);
  g_free(formats);
  EXPECT_EQ(names, (std::vector<std::string>{"BayerRG12", "BayerRG8", "BayerRG16", "BayerRG12p", "BayerRG12Packed",
                                              "Mono8", "RGB8", "BGR8", "YCbCr422_8", "YUV422_8", "YUV422_8_UYVY"}));
  // The fake camera's names keep working: ExposureTimeAbs is ExposureTime, GainRaw is Gain in 0.1 dB.
  SetFloat(c, "ExposureTimeAbs", 2500.0);
  EXPECT_DOUBLE_EQ(ReadFloat(c, "ExposureTime"), 2500.0);
  SetInt(c, "GainRaw", 65);
  Settle();
  EXPECT_DOUBLE_EQ(ReadFloat(c, "Gain"), 6.5);
  SetFloat(c, "Gain", 3.0);
  Settle();
  EXPECT_DOUBLE_EQ(ReadFloat(c, "Gain"), 3.0);
  EXPECT_EQ(ReadInt(c, "GainRaw"), 30);
  GError* e = nullptr;
  arv_camera_set_string(c.camera(), "DeviceUserID", "left", &e);
  EXPECT_EQ(e, nullptr);
  EXPECT_STREQ(arv_camera_get_string(c.camera(), "DeviceUserID", nullptr), "left");
}

// GevSCPSPacketSize is SCPS0's low 16 bits: the flag bits above them (here
// 30, do not fragment) are not part of the size and a size write keeps them.
TEST_F(GigeE2E, PacketSizeIsTheLow16BitsOfItsRegister) {
  ASSERT_NO_FATAL_FAILURE(StartWith(SmallDevice()));
  Client& c = *client_;
  constexpr uint32_t kDoNotFragment = 1u << 30;
  GError* e = nullptr;
  arv_device_write_register(c.device(), reg::kPacketSize, kDoNotFragment | 1400, &e);
  ASSERT_EQ(e, nullptr);
  Settle();
  EXPECT_EQ(ReadInt(c, "GevSCPSPacketSize"), 1400);
  SetInt(c, "GevSCPSPacketSize", 1500);
  Settle();
  EXPECT_EQ(device_->writes_refused(), 0u);
  guint32 raw = 0;
  EXPECT_TRUE(arv_device_read_register(c.device(), reg::kPacketSize, &raw, &e));
  EXPECT_EQ(raw, kDoNotFragment | 1500);
  g_clear_error(&e);
}

TEST_F(GigeE2E, FramesEqualTheCoreOutputInEachFormat) {
  ASSERT_NO_FATAL_FAILURE(StartWith(SmallDevice()));
  Client& c = *client_;
  struct Case {
    const char* name;
    uint32_t code;
  } cases[] = {{"BayerRG12", genicam::BayerCode(Cfa::kBayerRG, 12)},
               {"BayerRG8", genicam::BayerCode(Cfa::kBayerRG, 8)},
               {"BayerRG16", genicam::BayerCode(Cfa::kBayerRG, 16)},
               {"RGB8", genicam::kRGB8}};
  for (const Case& k : cases) {
    SCOPED_TRACE(k.name);
    Set(c, "PixelFormat", k.name);
    SetInt(c, "SimFrameIndex", 7);
    Settle();
    ASSERT_TRUE(c.OpenStream()) << c.last_error;
    Start(c);
    uint64_t id0 = 0, id1 = 0;
    uint32_t format = 0;
    const std::vector<uint8_t> f0 = c.Grab(3000, &id0, nullptr, &format);
    const std::vector<uint8_t> f1 = c.Grab(3000, &id1);
    c.CloseStream();
    ASSERT_FALSE(f0.empty());
    ASSERT_FALSE(f1.empty());
    EXPECT_EQ(format, k.code);
    EXPECT_EQ(id1, id0 + 1);
    const auto r7 = Reference(7, k.code, 0, 0, 64, 48), r8 = Reference(8, k.code, 0, 0, 64, 48);
    ASSERT_EQ(f0.size(), r7.size());
    EXPECT_TRUE(f0 == r7) << "frame 7 differs from the core's output";
    EXPECT_TRUE(f1 == r8) << "frame 8 differs from the core's output";
    EXPECT_FALSE(r7 == r8) << "noise must differ between frames";
  }
  EXPECT_EQ(c.failed_buffers(), 0u);
}

TEST_F(GigeE2E, MonoSensorServesMonoFormats) {
  ASSERT_NO_FATAL_FAILURE(StartWith(SmallMonoDevice()));
  Client& c = *client_;
  guint n = 0;
  const char** formats = arv_camera_dup_available_pixel_formats_as_strings(c.camera(), &n, nullptr);
  std::vector<std::string> names(formats, formats + n);
  g_free(formats);
  EXPECT_EQ(names, (std::vector<std::string>{"Mono12", "Mono8", "Mono16", "Mono12p", "Mono12Packed"}));
  for (const char* name : {"Mono12", "Mono8", "Mono16"}) {
    SCOPED_TRACE(name);
    Set(c, "PixelFormat", name);
    SetInt(c, "SimFrameIndex", 3);
    Settle();
    ASSERT_TRUE(c.OpenStream());
    Start(c);
    uint32_t format = 0;
    const auto f = c.Grab(3000, nullptr, nullptr, &format);
    c.CloseStream();
    ASSERT_FALSE(f.empty());
    EXPECT_TRUE(f == Reference(3, format, 0, 0, 32, 24));
  }
}

// `camsim run` on the bundled scene at 96x64 from frame 4, with `extra`
// options: its .raw (one little-endian 16-bit word per DN). Its PNG is left in
// `dir`.
constexpr int kRunWidth = 96, kRunHeight = 64, kRunFrame = 4;
std::vector<uint8_t> CamsimRunRaw(const DeviceOptions& o, const std::string& dir, const std::string& extra) {
  mkdir(dir.c_str(), 0755);
  const std::string cmd = std::string(CAMSIM_BINARY) + " run --quiet --config " + o.config_path +
                          " --set sensor.width=" + std::to_string(kRunWidth) +
                          " --set sensor.height=" + std::to_string(kRunHeight) + " " + extra +
                          " --first-frame " + std::to_string(kRunFrame) + " --input " + o.inputs[0] + " --out " + dir;
  EXPECT_EQ(std::system(cmd.c_str()), 0) << cmd;
  std::ifstream raw(dir + "/aisle_0001.raw", std::ios::binary);
  return std::vector<uint8_t>((std::istreambuf_iterator<char>(raw)), std::istreambuf_iterator<char>());
}

DeviceOptions RunSceneDevice(const std::vector<std::string>& extra_overrides) {
  DeviceOptions o = SmallDevice();
  o.pattern.clear();
  o.inputs = {std::string(CAMSIM_SOURCE_DIR) + "/scenes/aisle_0001.exr"};
  o.overrides = {"sensor.width=" + std::to_string(kRunWidth), "sensor.height=" + std::to_string(kRunHeight)};
  o.overrides.insert(o.overrides.end(), extra_overrides.begin(), extra_overrides.end());
  return o;
}

// Frame `kRunFrame` as the camera sends it in `format`; `format_code` gets
// the leader's pixel format.
std::vector<uint8_t> GrabRunFrame(Client& c, const char* format, uint32_t* format_code = nullptr) {
  Set(c, "PixelFormat", format);
  SetInt(c, "SimFrameIndex", kRunFrame);
  Settle();
  if (!c.OpenStream()) {
    ADD_FAILURE() << "no stream for " << format;
    return {};
  }
  Start(c);
  uint32_t code = 0;
  std::vector<uint8_t> f = c.Grab(3000, nullptr, nullptr, &code);
  c.CloseStream();
  if (format_code != nullptr) *format_code = code;
  return f;
}

// A window of a .raw frame at another depth, written from the PFNC's
// definitions and camsim's documented choice (docs/gige.md): 8 bits keep the
// top 8 of the ADC's bits (truncated), 16 bits are the DN shifted up to the
// MSB, 12 bits the DN itself; words little-endian.
std::vector<uint8_t> RawWindowAs(const std::vector<uint8_t>& raw, int adc_bits, int bits, int x, int y, int w, int h) {
  std::vector<uint8_t> out;
  for (int r = y; r < y + h; ++r)
    for (int i = x; i < x + w; ++i) {
      const size_t at = 2 * (static_cast<size_t>(r) * kRunWidth + i);
      const uint32_t dn = raw[at] | (raw[at + 1] << 8);
      if (bits == 8) {
        out.push_back(static_cast<uint8_t>(dn >> (adc_bits - 8)));
      } else {
        const uint32_t v = bits == 16 ? dn << (16 - adc_bits) : dn;
        out.push_back(static_cast<uint8_t>(v & 0xff));
        out.push_back(static_cast<uint8_t>(v >> 8));
      }
    }
  return out;
}

TEST_F(GigeE2E, FramesEqualCamsimRunOutput) {
  // The bundled scene through `camsim run` and through the camera: same bytes,
  // in every pixel format the Bayer camera offers.
  const DeviceOptions o = RunSceneDevice({});
  const std::string dir = testing::TempDir() + "camsim_gige_run";
  const std::vector<uint8_t> expected = CamsimRunRaw(o, dir, "");
  ASSERT_EQ(expected.size(), static_cast<size_t>(kRunWidth) * kRunHeight * 2);
  ASSERT_NO_FATAL_FAILURE(StartWith(o));
  Client& c = *client_;
  const int adc_bits = device_->sensor().adc_bits;
  ASSERT_EQ(adc_bits, 12) << "configs/camera.toml's ADC; the formats below assume it";
  EXPECT_TRUE(GrabRunFrame(c, "BayerRG12") == expected) << "BayerRG12 frame differs from camsim run's .raw";
  EXPECT_TRUE(GrabRunFrame(c, "BayerRG8") == RawWindowAs(expected, adc_bits, 8, 0, 0, kRunWidth, kRunHeight))
      << "BayerRG8 is not the top 8 bits of camsim run's .raw";
  EXPECT_TRUE(GrabRunFrame(c, "BayerRG16") == RawWindowAs(expected, adc_bits, 16, 0, 0, kRunWidth, kRunHeight))
      << "BayerRG16 is not camsim run's .raw shifted to the MSB";
  // RGB8 against the PNG camsim run wrote for the same frame, decoded by
  // libpng (not through the device's own conversion code).
  png_image png{};
  png.version = PNG_IMAGE_VERSION;
  ASSERT_TRUE(png_image_begin_read_from_file(&png, (dir + "/aisle_0001.png").c_str())) << png.message;
  png.format = PNG_FORMAT_RGB;
  std::vector<uint8_t> rgb(PNG_IMAGE_SIZE(png));
  ASSERT_TRUE(png_image_finish_read(&png, nullptr, rgb.data(), 0, nullptr)) << png.message;
  ASSERT_EQ(rgb.size(), static_cast<size_t>(kRunWidth) * kRunHeight * 3);
  uint32_t format = 0;
  EXPECT_TRUE(GrabRunFrame(c, "RGB8", &format) == rgb) << "RGB8 frame differs from camsim run's .png";
  EXPECT_EQ(format, genicam::kRGB8);
}

TEST_F(GigeE2E, MonoFramesEqualCamsimRunOutput) {
  // A mono sensor: Mono8/12/16 against `camsim run`'s .raw, whole and through
  // a window at odd offsets (a mono camera's offsets step by 1).
  const DeviceOptions o = RunSceneDevice({"sensor.cfa=Mono"});
  const std::vector<uint8_t> expected =
      CamsimRunRaw(o, testing::TempDir() + "camsim_gige_run_mono", "--set sensor.cfa=Mono");
  ASSERT_EQ(expected.size(), static_cast<size_t>(kRunWidth) * kRunHeight * 2);
  ASSERT_NO_FATAL_FAILURE(StartWith(o));
  Client& c = *client_;
  const int adc_bits = device_->sensor().adc_bits;
  uint32_t format = 0;
  EXPECT_TRUE(GrabRunFrame(c, "Mono12", &format) == expected) << "Mono12 frame differs from camsim run's .raw";
  EXPECT_EQ(format, genicam::kMono12);
  EXPECT_TRUE(GrabRunFrame(c, "Mono8", &format) == RawWindowAs(expected, adc_bits, 8, 0, 0, kRunWidth, kRunHeight));
  EXPECT_EQ(format, genicam::kMono8);
  EXPECT_TRUE(GrabRunFrame(c, "Mono16", &format) == RawWindowAs(expected, adc_bits, 16, 0, 0, kRunWidth, kRunHeight));
  EXPECT_EQ(format, genicam::kMono16);
  constexpr int kX = 7, kY = 5, kW = 33, kH = 21;
  SetInt(c, "Width", kW);
  SetInt(c, "Height", kH);
  SetInt(c, "OffsetX", kX);
  SetInt(c, "OffsetY", kY);
  EXPECT_TRUE(GrabRunFrame(c, "Mono16") == RawWindowAs(expected, adc_bits, 16, kX, kY, kW, kH))
      << "a 33x21 window at (7, 5) differs from that window of camsim run's .raw";
}

// ---------------------------------------------------------------- packed formats and Mono8 from colour

// Reference unpackers, written from the specs (not from the device's code).
// Unpacked 16-bit formats: one little-endian word per pixel.
std::vector<uint32_t> Words16(const std::vector<uint8_t>& f) {
  std::vector<uint32_t> out;
  for (size_t i = 0; i + 1 < f.size(); i += 2) out.push_back(f[i] | (f[i + 1] << 8));
  return out;
}
// PFNC "p": the frame is one bit stream, LSB first: bit b of pixel k is bit
// k * bits + b of the stream, and bit j of the stream is bit j % 8 of byte j / 8.
std::vector<uint32_t> UnpackPfnc(const std::vector<uint8_t>& f, int bits, size_t pixels) {
  std::vector<uint32_t> out(pixels, 0);
  for (size_t k = 0; k < pixels; ++k)
    for (int b = 0; b < bits; ++b) {
      const size_t j = k * bits + b;
      if (j / 8 < f.size()) out[k] |= ((f[j / 8] >> (j % 8)) & 1u) << b;
    }
  return out;
}
// GigE Vision Mono12Packed / BayerXX12Packed: pixels 2i and 2i+1 in bytes
// 3i..3i+2: [p0 bits 11..4] [p1 bits 3..0 | p0 bits 3..0] [p1 bits 11..4].
std::vector<uint32_t> UnpackGige12Packed(const std::vector<uint8_t>& f, size_t pixels) {
  std::vector<uint32_t> out;
  for (size_t i = 0; 3 * i + 2 < f.size() && out.size() < pixels; ++i) {
    out.push_back(f[3 * i] << 4 | (f[3 * i + 1] & 0xf));
    if (out.size() < pixels) out.push_back(f[3 * i + 2] << 4 | f[3 * i + 1] >> 4);
  }
  return out;
}

// One frame of index `index` as the camera sends it now.
std::vector<uint8_t> GrabIndex(Client& c, uint32_t index, uint32_t* format = nullptr) {
  SetInt(c, "SimFrameIndex", index);
  Settle();
  if (!c.OpenStream()) {
    ADD_FAILURE() << c.last_error;
    return {};
  }
  Start(c);
  std::vector<uint8_t> f = c.Grab(3000, nullptr, nullptr, format);
  c.CloseStream();
  return f;
}

// Frame `index` in `format` as the camera sends it; `code` gets the leader's format.
std::vector<uint8_t> GrabAt(Client& c, const char* format, uint32_t index, uint32_t* code = nullptr) {
  Set(c, "PixelFormat", format);
  return GrabIndex(c, index, code);
}

// Each packed format of the current window: its PayloadSize, its leader's
// code, and its bytes unpacked (by the spec) equal the unpacked format's
// codes of the same frame; with chunks, ChunkPixelFormat names it.
struct PackedCase {
  const char* name;
  uint32_t code;
  int bits;
  genicam::Packing packing;
};
void CheckPackedFormats(Client& c, const char* unpacked, const std::vector<PackedCase>& cases, int w, int h,
                        int64_t index) {
  const std::vector<uint32_t> want = Words16(GrabAt(c, unpacked, index));
  ASSERT_EQ(want.size(), static_cast<size_t>(w) * h) << unpacked;
  for (const PackedCase& k : cases) {
    SCOPED_TRACE(k.name);
    uint32_t code = 0;
    const std::vector<uint8_t> f = GrabAt(c, k.name, index, &code);
    EXPECT_EQ(code, k.code);
    EXPECT_EQ(ReadInt(c, "PayloadSize"), static_cast<int64_t>(w) * h * k.bits / 8);
    ASSERT_EQ(f.size(), static_cast<size_t>(w) * h * k.bits / 8);
    const std::vector<uint32_t> got = k.packing == genicam::Packing::kPfnc
                                          ? UnpackPfnc(f, k.bits, want.size())
                                          : UnpackGige12Packed(f, want.size());
    EXPECT_TRUE(got == want) << "does not unpack to " << unpacked << "'s codes of frame " << index;
  }
  // The chunk names the format.
  GError* e = nullptr;
  arv_camera_set_boolean(c.camera(), "ChunkModeActive", TRUE, &e);
  ASSERT_EQ(e, nullptr);
  for (const PackedCase& k : cases) {
    SCOPED_TRACE(k.name);
    Set(c, "PixelFormat", k.name);
    Settle();
    ArvChunkParser* parser = arv_camera_create_chunk_parser(c.camera());
    ASSERT_TRUE(c.OpenStream());
    Start(c);
    const ChunkedFrame f = GrabChunked(c, parser);
    c.CloseStream();
    g_object_unref(parser);
    ASSERT_TRUE(f.ok);
    EXPECT_EQ(f.pixel_format, k.name);
    EXPECT_EQ(f.image.size(), (static_cast<size_t>(w) * h * k.bits / 8 + 3) / 4 * 4);
  }
  arv_camera_set_boolean(c.camera(), "ChunkModeActive", FALSE, &e);
  ASSERT_EQ(e, nullptr);
}

TEST_F(GigeE2E, PackedBayerFormatsUnpackToTheUnpackedCodes) {
  // 12-bit ADC: BayerRG12p (PFNC) and BayerRG12Packed (GigE Vision) against BayerRG12.
  ASSERT_NO_FATAL_FAILURE(StartWith(SmallDevice()));
  Client& c = *client_;
  const std::vector<PackedCase> cases = {
      {"BayerRG12p", ARV_PIXEL_FORMAT_BAYER_RG_12P, 12, genicam::Packing::kPfnc},
      {"BayerRG12Packed", ARV_PIXEL_FORMAT_BAYER_RG_12_PACKED, 12, genicam::Packing::kGigeLegacy}};
  ASSERT_NO_FATAL_FAILURE(CheckPackedFormats(c, "BayerRG12", cases, 64, 48, 5));
  GError* e = nullptr;
  arv_camera_set_region(c.camera(), 2, 4, 30, 18, &e);  // a window: rows of 15 pixel pairs
  ASSERT_EQ(e, nullptr);
  ASSERT_NO_FATAL_FAILURE(CheckPackedFormats(c, "BayerRG12", cases, 30, 18, 9));
  EXPECT_EQ(c.failed_buffers(), 0u);
}

TEST_F(GigeE2E, PackedMonoFormatsUnpackToTheUnpackedCodesInAnOddWidthWindow) {
  // A mono sensor's window of odd width: PFNC packs the frame as one stream,
  // so the rows do not start on a byte (31 x 12 bits = 46.5 bytes).
  ASSERT_NO_FATAL_FAILURE(StartWith(SmallMonoDevice()));
  Client& c = *client_;
  GError* e = nullptr;
  arv_camera_set_region(c.camera(), 1, 0, 31, 24, &e);
  ASSERT_EQ(e, nullptr);
  ASSERT_NO_FATAL_FAILURE(CheckPackedFormats(
      c, "Mono12",
      {{"Mono12p", 0x010c0047u, 12, genicam::Packing::kPfnc},
       {"Mono12Packed", ARV_PIXEL_FORMAT_MONO_12_PACKED, 12, genicam::Packing::kGigeLegacy}},
      31, 24, 4));
  // An odd pixel count would end the frame in half a byte: refused, as a
  // height (Mono12p is selected) and as a format (at 31 x 23).
  const uint64_t refused = device_->writes_refused();
  Set(c, "PixelFormat", "Mono12p");
  arv_camera_set_integer(c.camera(), "Height", 23, &e);
  EXPECT_NE(e, nullptr);
  g_clear_error(&e);
  Settle();
  EXPECT_EQ(ReadInt(c, "Height"), 24);
  Set(c, "PixelFormat", "Mono12");
  SetInt(c, "Height", 23);
  arv_camera_set_string(c.camera(), "PixelFormat", "Mono12Packed", &e);
  EXPECT_NE(e, nullptr);
  g_clear_error(&e);
  Settle();
  EXPECT_STREQ(arv_camera_get_pixel_format_as_string(c.camera(), nullptr), "Mono12");
  EXPECT_EQ(device_->writes_refused(), refused + 2);
}

TEST_F(GigeE2E, TenBitPackedFormatsUnpackToTheUnpackedCodes) {
  // A 10-bit ADC: Mono10p / BayerRG10p against Mono10 / BayerRG10 (the DN
  // as is), and the 12-bit packings against the unpacked 12-bit format (DN << 2).
  for (const bool mono : {true, false}) {
    SCOPED_TRACE(mono ? "mono" : "BayerRG");
    DeviceOptions o = mono ? SmallMonoDevice() : SmallDevice();
    o.overrides.push_back("sensor.adc_bits=10");
    ASSERT_NO_FATAL_FAILURE(StartWith(o));
    Client& c = *client_;
    guint n = 0;
    const char** formats = arv_camera_dup_available_pixel_formats_as_strings(c.camera(), &n, nullptr);
    std::vector<std::string> names(formats, formats + n);
    g_free(formats);
    const std::string base = mono ? "Mono" : "BayerRG";
    EXPECT_NE(std::find(names.begin(), names.end(), base + "10p"), names.end());
    GError* e = nullptr;
    if (mono) arv_camera_set_region(c.camera(), 1, 0, 31, 20, &e);  // 620 pixels: a multiple of 4
    ASSERT_EQ(e, nullptr);
    const int w = mono ? 31 : 64, h = mono ? 20 : 48;
    const PackedCase k = {mono ? "Mono10p" : "BayerRG10p", mono ? 0x010a0046u : ARV_PIXEL_FORMAT_BAYER_RG_10P, 10,
                          genicam::Packing::kPfnc};
    ASSERT_NO_FATAL_FAILURE(CheckPackedFormats(c, (base + "10").c_str(), {k}, w, h, 3));
    const PackedCase k12 = {mono ? "Mono12p" : "BayerRG12p", mono ? 0x010c0047u : ARV_PIXEL_FORMAT_BAYER_RG_12P, 12,
                            genicam::Packing::kPfnc};
    ASSERT_NO_FATAL_FAILURE(CheckPackedFormats(c, (base + "12").c_str(), {k12}, w, h, 3));
    if (mono) {  // 31 x 22 = 682 pixels, 6820 bits: not whole bytes
      Set(c, "PixelFormat", "Mono10p");
      arv_camera_set_integer(c.camera(), "Height", 22, &e);
      EXPECT_NE(e, nullptr);
      g_clear_error(&e);
    }
    TearDown();
  }
}

TEST_F(GigeE2E, Mono8OnAColourSensorIsTheLumaOfRgb8) {
  ASSERT_NO_FATAL_FAILURE(StartWith(SmallDevice()));
  Client& c = *client_;
  uint32_t code = 0;
  const std::vector<uint8_t> rgb = GrabAt(c, "RGB8", 6);
  const std::vector<uint8_t> mono = GrabAt(c, "Mono8", 6, &code);
  EXPECT_EQ(code, genicam::kMono8);
  EXPECT_EQ(ReadInt(c, "PayloadSize"), 64 * 48);
  ASSERT_EQ(rgb.size(), size_t{64} * 48 * 3);
  ASSERT_EQ(mono.size(), size_t{64} * 48);
  // BT.601 weights 0.299, 0.587, 0.114 in 1/256ths, rounded: 77, 150, 29.
  std::vector<uint8_t> luma;
  for (size_t i = 0; i < rgb.size(); i += 3)
    luma.push_back(static_cast<uint8_t>((77 * rgb[i] + 150 * rgb[i + 1] + 29 * rgb[i + 2] + 128) / 256));
  EXPECT_TRUE(mono == luma) << "Mono8 is not the BT.601 luma of RGB8's frame 6";
  EXPECT_NE(std::set<uint8_t>(luma.begin(), luma.end()).size(), 1u) << "a flat frame tests nothing";
  // Like RGB8 it needs the ISP: the demosaic off refuses it.
  const uint32_t demosaic = StageEnableAddress(*device_, "Stage_demosaic");
  ASSERT_NE(demosaic, 0u);
  GError* e = nullptr;
  arv_device_write_register(c.device(), demosaic, 0, &e);
  EXPECT_NE(e, nullptr);
  g_clear_error(&e);
}

TEST_F(GigeE2E, FirstFrameOfAStreamArrivesWhole) {
  // 640x480 BayerRG12 (600 KiB) is three times net.core.rmem_default: the
  // first frame arrives whole only because the device sent its leader ahead
  // (GigeDevice::PrimeReceiver), which Aravis then counts as one duplicate.
  DeviceOptions o = SmallDevice(640, 480);
  ASSERT_NO_FATAL_FAILURE(StartWith(o));
  Client& c = *client_;
  SetInt(c, "SimFrameIndex", 5);
  Settle();
  ASSERT_TRUE(c.OpenStream());
  Start(c);
  const auto f = c.Grab(5000);
  ASSERT_FALSE(f.empty()) << "the first frame was lost";
  EXPECT_TRUE(f == Reference(5, genicam::BayerCode(Cfa::kBayerRG, 12), 0, 0, 640, 480));
  EXPECT_EQ(c.failed_buffers(), 0u);
  EXPECT_EQ(arv_stream_get_info_uint64_by_name(c.stream(), "n_missing_packets"), 0u);
  EXPECT_EQ(arv_stream_get_info_uint64_by_name(c.stream(), "n_duplicated_packets"), 1u);
}

// The stream's packets leave as a link of --link-mbps carries them, with
// GevSCPD (timestamp ticks: GevTimestampTickFrequency) after each: a frame's
// first packet to its last take at least that long, and not much longer.
TEST_F(GigeE2E, TheStreamIsPacedByTheLinkAndGevSCPD) {
  DeviceOptions o = SmallDevice(640, 480);
  o.link_mbps = 100;
  ASSERT_NO_FATAL_FAILURE(StartWith(o));
  Client& c = *client_;
  const uint64_t tick_hz = arv_gv_device_get_timestamp_tick_frequency(ARV_GV_DEVICE(c.device()), nullptr);
  ASSERT_EQ(tick_hz, 1000000000u);  // Aravis's fake camera: 1 ns ticks
  SetInt(c, "GevSCPD", 20000);      // 20 us after each packet
  SetFloat(c, "AcquisitionFrameRate", 5.0);
  Settle();
  const int64_t payload = ReadInt(c, "PayloadSize"), packet_size = ReadInt(c, "GevSCPSPacketSize");
  ASSERT_EQ(payload, 640 * 480 * 2);  // BayerRG12: 451 packets of 1400 B
  const double expected_s = genicam::FrameSendSeconds(static_cast<size_t>(payload), static_cast<size_t>(packet_size),
                                                      100'000'000, 20000);
  // 1438 wire bytes at 100 Mb/s (115 us) + 20 us, for 453 packets: 61 ms.
  EXPECT_NEAR(expected_s, 0.061, 0.001);
  ASSERT_TRUE(c.OpenStream());
  Start(c);
  ASSERT_FALSE(c.Grab(5000).empty());  // the first frame's leader was sent 10 ms ahead (PrimeReceiver)
  for (int i = 0; i < 3; ++i) {
    ASSERT_FALSE(c.Grab(5000).empty()) << "frame " << i;
    const double took_s = static_cast<double>(c.last_popped_ns() - c.last_first_packet_ns()) * 1e-9;
    // From the leader to the trailer: every packet but the trailer's slot (and
    // up to kPaceAheadNs early). A loaded machine adds to it (221 ms of 61 with
    // two builds and a test run beside it), so the upper bound only catches a
    // pacing several times too slow (a unit wrong by 10 gives 610 ms).
    EXPECT_GE(took_s, expected_s * 0.97 - 1e-3) << "frame " << i;
    EXPECT_LE(took_s, expected_s * 4 + 0.2) << "frame " << i;
  }
  c.CloseStream();
  EXPECT_EQ(c.failed_buffers(), 0u);
  // Free run without AcquisitionFrameRate: no faster than rendering and sending.
  arv_camera_set_boolean(c.camera(), "AcquisitionFrameRateEnable", FALSE, nullptr);
  Settle();
  EXPECT_LT(ReadFloat(c, "AcquisitionResultingFrameRate"), 1.0 / expected_s);
}

// A client with a small socket buffer (256 KiB, a 640x480 12-bit frame is
// 600 KiB) gets every frame whole when the stream is paced. Unpaced
// (--link-mbps 0) the fake camera's burst overflows it (8 of 10 frames
// failed here) and the lost packets are never sent again. The paced link is
// 100 Mb/s: the buffer then holds 21 ms of the stream, so a receiver
// descheduled on a loaded machine catches up (at 1 Gb/s, 2 ms: a CI run
// with the other tests beside it lost 37 packets of one frame).
TEST_F(GigeE2E, ASmallReceiveBufferGetsEveryPacedFrame) {
  constexpr int kFrames = 10;
  for (const int mbps : {100, 0}) {
    DeviceOptions o = SmallDevice(640, 480);
    o.link_mbps = mbps;
    ASSERT_NO_FATAL_FAILURE(StartWith(o));
    Client& c = *client_;
    SetFloat(c, "AcquisitionFrameRate", 10.0);
    Settle();
    ASSERT_TRUE(c.OpenStream(8, 256 << 10));
    Start(c);
    int whole = 0;
    for (int i = 0; i < kFrames; ++i) whole += c.Grab(3000).empty() ? 0 : 1;
    const uint64_t missing = arv_stream_get_info_uint64_by_name(c.stream(), "n_missing_packets");
    c.CloseStream();
    std::printf("link %d Mb/s: %d of %d frames whole, %llu failed buffers, %llu packets missing\n", mbps, whole,
                kFrames, static_cast<unsigned long long>(c.failed_buffers()), static_cast<unsigned long long>(missing));
    if (mbps != 0) {
      EXPECT_EQ(whole, kFrames);
      EXPECT_EQ(c.failed_buffers(), 0u);
      EXPECT_EQ(missing, 0u);
    } else {
      EXPECT_GT(missing, 0u) << "unpaced, no packet was lost: the buffer held every burst";
    }
    TearDown();
  }
}

// The device answers PACKETRESEND (and says so in its GVCP capabilities,
// so an Aravis client asks): with every 50th payload packet lost on its
// first way (a test hook; a small socket buffer loses packets only when the
// sender outruns the receiver, which the sanitizer build did not), a client
// with Aravis's default settings gets every frame whole, byte for byte,
// from the packets sent again. The camera answers a request between frames
// (its one thread also renders), so frames come at 1 Hz, and the client
// keeps a frame 2 s for its packets (100 ms by default).
TEST_F(GigeE2E, LostPacketsAreSentAgainOnRequest) {
  constexpr int kFrames = 4;
  ASSERT_NO_FATAL_FAILURE(StartWith(SmallDevice(640, 480)));
  Client& c = *client_;
  SetFloat(c, "AcquisitionFrameRate", 1.0);
  Settle();
  const uint64_t resent_before = genicam::PacketsResent();
  ASSERT_TRUE(c.OpenStream());
  g_object_set(c.stream(), "frame-retention", 2000000u, nullptr);
  genicam::DropStreamPacketsForTest(50);
  Start(c);
  std::vector<std::vector<uint8_t>> frames;
  for (int i = 0; i < kFrames; ++i) frames.push_back(c.Grab(3000));
  genicam::DropStreamPacketsForTest(0);
  const uint64_t resent = arv_stream_get_info_uint64_by_name(c.stream(), "n_resent_packets");
  const uint64_t missing = arv_stream_get_info_uint64_by_name(c.stream(), "n_missing_packets");
  c.CloseStream();
  std::printf("%llu packets resent, %llu missing\n", static_cast<unsigned long long>(resent),
              static_cast<unsigned long long>(missing));
  // 640x480 BayerRG12 in 1400-byte packets: about 450 payload packets, 9 of them lost per frame.
  EXPECT_GE(resent, static_cast<uint64_t>(kFrames) * 8) << "lost packets were not all asked for and sent again";
  EXPECT_GE(genicam::PacketsResent() - resent_before, resent);
  EXPECT_EQ(missing, 0u);
  EXPECT_EQ(c.failed_buffers(), 0u);
  const uint32_t format = genicam::BayerCode(Cfa::kBayerRG, 12);
  for (int i = 0; i < kFrames; ++i) EXPECT_TRUE(frames[i] == Reference(i, format, 0, 0, 640, 480)) << "frame " << i;
}

TEST_F(GigeE2E, SoftwareTriggerGivesExactlyOneFrame) {
  ASSERT_NO_FATAL_FAILURE(StartWith(SmallDevice()));
  Client& c = *client_;
  TriggerOn("Software");
  Settle();  // the fake camera must be in trigger mode before the acquisition starts
  ASSERT_TRUE(c.OpenStream());
  Start(c);
  EXPECT_TRUE(c.Grab(300).empty()) << "a frame without a trigger";
  for (int i = 0; i < 3; ++i) {
    ASSERT_TRUE(SendTriggerSoftware());
    EXPECT_FALSE(c.Grab(3000).empty()) << "trigger " << i;
    EXPECT_TRUE(c.Grab(400).empty()) << "more than one frame for trigger " << i;
  }
  EXPECT_EQ(device_->frames_sent(), 3u);
  // Back to back, well within one register sync: each still gives a frame
  // (they used to be merged into one).
  for (int i = 0; i < 4; ++i) ASSERT_TRUE(SendTriggerSoftware());
  for (int i = 0; i < 4; ++i) EXPECT_FALSE(c.Grab(3000).empty()) << "back-to-back trigger " << i;
  EXPECT_TRUE(c.Grab(400).empty()) << "more frames than triggers";
  EXPECT_EQ(device_->frames_sent(), 7u);
}

// A triggered frame is read out after its exposure: it arrives no sooner
// than ExposureTime after its trigger, is stamped with its exposure's start
// (the trigger), and triggers closer than an exposure wait for the one
// before (a 1 s exposure used to give a frame 12 ms after its trigger).
TEST_F(GigeE2E, ATriggeredFrameComesAfterItsExposure) {
  ASSERT_NO_FATAL_FAILURE(StartWith(SmallDevice()));
  Client& c = *client_;
  constexpr double kExposureMs = 200.0;
  const auto now_ns = [] { return static_cast<uint64_t>(g_get_real_time()) * 1000; };
  constexpr uint64_t kMs = 1000000;
  TriggerOn("Software");
  SetFloat(c, "ExposureTime", kExposureMs * 1000.0);
  Settle();
  ASSERT_TRUE(c.OpenStream());
  Start(c);
  // One trigger.
  uint64_t sent = now_ns();
  ASSERT_TRUE(SendTriggerSoftware());
  ASSERT_FALSE(c.Grab(3000).empty());
  uint64_t arrived = now_ns();
  EXPECT_GE(arrived, sent + static_cast<uint64_t>(kExposureMs) * kMs) << "before its exposure ended";
  EXPECT_GE(c.last_timestamp_ns() + 5 * kMs, sent) << "stamped before its trigger";
  EXPECT_LE(c.last_timestamp_ns(), sent + 100 * kMs) << "stamped long after its trigger (not the exposure's start)";
  // Three back to back: exposures one after another.
  sent = now_ns();
  for (int i = 0; i < 3; ++i) ASSERT_TRUE(SendTriggerSoftware());
  std::vector<uint64_t> stamp;
  for (int i = 0; i < 3; ++i) {
    ASSERT_FALSE(c.Grab(3000).empty()) << "trigger " << i;
    arrived = now_ns();
    EXPECT_GE(arrived, sent + static_cast<uint64_t>((i + 1) * kExposureMs) * kMs) << "frame " << i << " came early";
    stamp.push_back(c.last_timestamp_ns());
  }
  for (int i = 1; i < 3; ++i)
    EXPECT_GE(stamp[i] - stamp[i - 1], static_cast<uint64_t>(kExposureMs - 2) * kMs) << "exposures overlap at " << i;
  EXPECT_TRUE(c.Grab(400).empty()) << "more frames than triggers";
  EXPECT_EQ(c.failed_buffers(), 0u);
}

// TriggerDelay (SFNC): a trigger's exposure starts TriggerDelay after it.
// The frame arrives no sooner than delay + exposure after the trigger and
// is stamped with its exposure's start, the delay after the trigger (with
// the delay ignored, the stamp is the trigger's and the frame 300 ms early).
TEST_F(GigeE2E, TriggerDelayDelaysTheExposure) {
  ASSERT_NO_FATAL_FAILURE(StartWith(SmallDevice()));
  Client& c = *client_;
  constexpr double kDelayMs = 300.0, kExposureMs = 100.0;
  const auto now_ns = [] { return static_cast<uint64_t>(g_get_real_time()) * 1000; };
  constexpr uint64_t kMs = 1000000;
  EXPECT_DOUBLE_EQ(ReadFloat(c, "TriggerDelay"), 0.0);
  double lo = 0, hi = 0;
  arv_camera_get_float_bounds(c.camera(), "TriggerDelay", &lo, &hi, nullptr);
  EXPECT_EQ(lo, 0.0);
  EXPECT_EQ(hi, reg::kMaxTriggerDelayUs);
  TriggerOn("Software");
  SetFloat(c, "TriggerDelay", kDelayMs * 1000.0);
  SetFloat(c, "ExposureTime", kExposureMs * 1000.0);
  Settle();
  EXPECT_DOUBLE_EQ(ReadFloat(c, "TriggerDelay"), kDelayMs * 1000.0);
  ASSERT_TRUE(c.OpenStream());
  Start(c);
  for (int i = 0; i < 2; ++i) {
    const uint64_t sent = now_ns();
    ASSERT_TRUE(SendTriggerSoftware());
    ASSERT_FALSE(c.Grab(3000).empty()) << "trigger " << i;
    const uint64_t arrived = now_ns();
    EXPECT_GE(arrived, sent + static_cast<uint64_t>(kDelayMs + kExposureMs) * kMs)
        << "trigger " << i << ": before its delay and exposure ended";
    // 5 ms for the clocks' reads (the camera's clock is the same real time).
    EXPECT_GE(c.last_timestamp_ns() + 5 * kMs, sent + static_cast<uint64_t>(kDelayMs) * kMs)
        << "trigger " << i << ": stamped before its delay ended";
    EXPECT_LE(c.last_timestamp_ns(), sent + static_cast<uint64_t>(kDelayMs + 100) * kMs)
        << "trigger " << i << ": stamped long after its delay ended";
  }
  // Out of range: refused by the XML's bounds, and by the device as a raw write.
  GError* e = nullptr;
  arv_camera_set_float(c.camera(), "TriggerDelay", 2 * reg::kMaxTriggerDelayUs, &e);
  EXPECT_NE(e, nullptr);
  g_clear_error(&e);
  arv_device_write_memory(c.device(), reg::kTriggerDelay, 8, Be64(-1.0).data(), &e);
  EXPECT_NE(e, nullptr);
  g_clear_error(&e);
  EXPECT_DOUBLE_EQ(ReadFloat(c, "TriggerDelay"), kDelayMs * 1000.0);
  EXPECT_EQ(c.failed_buffers(), 0u);
}

// A free-running frame is stamped when its slot comes, not when the fake
// camera asked for it (before the wait): at 5 Hz each stamp lies after the
// previous frame arrived, and stamps are a period apart.
TEST_F(GigeE2E, FrameTimestampsAreTheirSlots) {
  ASSERT_NO_FATAL_FAILURE(StartWith(SmallDevice()));
  Client& c = *client_;
  SetFloat(c, "AcquisitionFrameRate", 5.0);
  Settle();
  ASSERT_TRUE(c.OpenStream());
  Start(c);
  std::vector<uint64_t> stamp, arrival;
  for (int i = 0; i < 4; ++i) {
    ASSERT_FALSE(c.Grab(3000).empty()) << "frame " << i;
    arrival.push_back(static_cast<uint64_t>(g_get_real_time()) * 1000);
    stamp.push_back(c.last_timestamp_ns());
  }
  for (int i = 1; i < 4; ++i) {
    EXPECT_LE(stamp[i], arrival[i]) << "frame " << i << " carries a time from after it arrived";
    // Stamped when asked for, the frame would carry a time from before the
    // previous frame arrived (the fake camera asks as it sends that one).
    EXPECT_GT(stamp[i], arrival[i - 1]) << "frame " << i << " is stamped before its slot";
    // The slots' cadence, whatever the load delays up to a period (then the
    // cadence starts again: NextFrameSlot); 5 ms for the clocks' reads.
    EXPECT_NEAR(static_cast<double>(stamp[i] - stamp[i - 1]), 200e6, 5e6) << "frame " << i;
  }
}

// The fake camera's one thread answers control packets and makes frames.
// A free-run frame waiting for its slot (0.5 Hz here) used to wait inside
// the frame callback, so reads timed out and the camera dropped its client
// at a heartbeat timeout. Now every read is answered while the next frame
// waits, and the client keeps control and its stream.
TEST_F(GigeE2E, ControlAnswersWhileAFrameWaitsForItsSlot) {
  ASSERT_NO_FATAL_FAILURE(StartWith(SmallDevice()));
  Client& c = *client_;
  SetFloat(c, "AcquisitionFrameRate", 0.5);
  Settle();
  ASSERT_TRUE(c.OpenStream());
  Start(c);
  ASSERT_FALSE(c.Grab(3000).empty());
  const auto t0 = std::chrono::steady_clock::now();
  double slowest_ms = 0;
  int reads = 0;
  while (std::chrono::steady_clock::now() - t0 < std::chrono::milliseconds(1500)) {
    const auto r0 = std::chrono::steady_clock::now();
    GError* e = nullptr;
    const int64_t width = arv_camera_get_integer(c.camera(), "Width", &e);
    ASSERT_EQ(e, nullptr) << "read " << reads << ": " << e->message;
    EXPECT_EQ(width, 64);
    slowest_ms = std::max(slowest_ms, std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - r0).count());
    ++reads;
  }
  // A frame waits 2 s for its slot; a read waited for it before.
  EXPECT_LT(slowest_ms, 1000.0) << reads << " reads";
  EXPECT_FALSE(c.Grab(3000).empty()) << "the next frame after the reads";
}

TEST_F(GigeE2E, HardwareTriggerAndStrobeThroughTheLineInterface) {
  DeviceOptions o = SmallDevice();
  o.strobe = &strobe_;
  ASSERT_NO_FATAL_FAILURE(StartWithTriggerLine(o));
  Client& c = *client_;
  TriggerOn("Line0", "RisingEdge");
  Set(c, "LineSelector", "Line1");
  Settle();
  EXPECT_STREQ(arv_camera_get_string(c.camera(), "LineMode", nullptr), "Output");
  Set(c, "LineSource", "ExposureActive");
  // Each frame's ChunkLineStatusAll: the lines as it started.
  ASSERT_NO_FATAL_FAILURE(StartWithChunks());
  GError* e = nullptr;
  arv_camera_execute_command(c.camera(), "TriggerSoftware", &e);  // refused: the source is Line0
  EXPECT_TRUE(g_error_matches(e, ARV_DEVICE_ERROR, ARV_DEVICE_ERROR_PROTOCOL_ERROR_ACCESS_DENIED));
  g_clear_error(&e);
  EXPECT_TRUE(c.Grab(300).empty());
  Line0(true);  // rising edge: one frame
  ChunkedFrame f = GrabChunked(c, chunks_);
  ASSERT_TRUE(f.ok);
  EXPECT_EQ(f.values.at("ChunkLineStatusAll"), 3) << "Line0 high after its rising edge, Line1 (the strobe) high";
  Line0(false);  // falling edge: none
  EXPECT_TRUE(c.Grab(300).empty());
  EXPECT_EQ(strobe_.edges(), 2);  // high while the frame was made, then low
  EXPECT_FALSE(strobe_.level());
  Set(c, "TriggerActivation", "FallingEdge");
  Settle();
  Line0(true);
  EXPECT_TRUE(c.Grab(300).empty());
  Line0(false);
  f = GrabChunked(c, chunks_);
  ASSERT_TRUE(f.ok);
  EXPECT_EQ(f.values.at("ChunkLineStatusAll"), 2) << "Line0 low after its falling edge, the strobe high";
}

// A 1 ms trigger pulse ends before its frame's rendering starts: the frame's
// ChunkLineStatusAll still has Line0 high, the level its rising edge left
// at the exposure start (it was read when the rendering started: 0).
TEST_F(GigeE2E, AShortPulsesFrameHasLine0HighInItsLineStatus) {
  ASSERT_NO_FATAL_FAILURE(StartWithTriggerLine());
  Client& c = *client_;
  TriggerOn("Line0", "RisingEdge");
  ASSERT_NO_FATAL_FAILURE(StartWithChunks());
  for (int i = 0; i < 5; ++i) {
    Pulse(1);
    ChunkedFrame f = GrabChunked(c, chunks_);
    ASSERT_TRUE(f.ok) << i;
    EXPECT_EQ(f.values.at("ChunkLineStatusAll"), 1) << "pulse " << i << ": Line0 high at its exposure start";
  }
  Settle();
  EXPECT_FALSE(LineStatus()) << "LineStatus (Line0 selected): the level now";
}

// Pulses that come before the fake camera has looked for a trigger (at a
// stream's start it looks only every 100 ms) each give their own frame, with
// the index the pulse carries, in order. Beyond the queue, pulses are dropped
// and counted, never merged into another pulse's frame.
TEST_F(GigeE2E, QuickPulsesEachGiveTheirOwnFrame) {
  const std::string dir = testing::TempDir() + "camsim-quick-" + std::to_string(getpid());
  DeviceOptions o = SmallDevice();
  o.trigger_line = "unix:" + dir;
  ASSERT_NO_FATAL_FAILURE(StartWith(o));
  Client& c = *client_;
  TriggerOn("Line0");
  Settle();  // the fake camera must be in trigger mode before the acquisition starts
  constexpr int kPulses = 24;
  ASSERT_TRUE(c.OpenStream(kPulses + 2));
  Start(c);
  Settle();
  std::string error;
  auto bus = hal::OpenBusOutput("unix:" + dir, &error);
  ASSERT_NE(bus, nullptr) << error;
  auto pulse = [&](uint32_t index) {
    bus->SetEdgeIndex(index);
    ASSERT_TRUE(bus->Set(true, &error)) << error;
    ASSERT_TRUE(bus->Set(false, &error)) << error;
  };
  const uint32_t code = genicam::BayerCode(Cfa::kBayerRG, 12);
  // Two pulses 0 ms apart at the stream's start: frames 40 and 41.
  pulse(40);
  pulse(41);
  for (uint32_t index : {40u, 41u}) {
    const std::vector<uint8_t> f = c.Grab(3000);
    ASSERT_FALSE(f.empty()) << "no frame for pulse " << index;
    EXPECT_TRUE(f == Reference(index, code, 0, 0, 64, 48)) << "the frame for pulse " << index << " has another index";
  }
  EXPECT_TRUE(c.Grab(300).empty()) << "a frame without a pulse";
  // A burst longer than the queue at a new stream's start: frames for the
  // first pulses, in order, and the rest counted as dropped.
  GError* e = nullptr;
  arv_camera_stop_acquisition(c.camera(), &e);
  ASSERT_EQ(e, nullptr) << e->message;
  Settle();
  Start(c);
  Settle();
  for (int k = 0; k < kPulses; ++k) pulse(100 + k);
  int frames = 0;
  uint32_t next = 100;  // the lowest index the next frame may have
  for (std::vector<uint8_t> f = c.Grab(3000); !f.empty(); f = c.Grab(500)) {
    while (next < 100 + kPulses && !(f == Reference(next, code, 0, 0, 64, 48))) ++next;
    EXPECT_LT(next, 100u + kPulses) << "frame " << frames << " is none of the pulses' frames, or out of order";
    ++next;
    ++frames;
  }
  EXPECT_GE(frames, static_cast<int>(genicam::kMaxPendingTriggers)) << "a queued pulse was lost";
  EXPECT_EQ(frames + static_cast<int>(device_->triggers_dropped()), kPulses);
  EXPECT_EQ(c.failed_buffers(), 0u);
  client_.reset();
  device_.reset();
  EXPECT_EQ(rmdir(dir.c_str()), 0);
}

// LineStatus on Line0 is the trigger input's level after its last edge.
TEST_F(GigeE2E, LineStatusFollowsTheTriggerInput) {
  ASSERT_NO_FATAL_FAILURE(StartWithTriggerLine());
  Client& c = *client_;
  Set(c, "LineSelector", "Line0");
  EXPECT_FALSE(LineStatus());
  Line0(true);
  EXPECT_TRUE(WaitLineStatus(true)) << "high trigger input";
  Set(c, "LineSelector", "Line1");  // the strobe, not driven: at once, without waiting for a sync
  EXPECT_FALSE(LineStatus());
  Set(c, "LineSelector", "Line0");
  EXPECT_TRUE(LineStatus());
  Line0(false);
  EXPECT_TRUE(WaitLineStatus(false)) << "low trigger input";
}

// LineInverter[Line0] inverts the input before the trigger logic and
// LineStatus: an inverted line reads high while low on the wire, and
// RisingEdge fires on the electrical falling edge (its frame's
// ChunkLineStatusAll has Line0 high).
TEST_F(GigeE2E, AnInvertedLine0TriggersOnTheOppositeEdge) {
  ASSERT_NO_FATAL_FAILURE(StartWithTriggerLine());
  Client& c = *client_;
  Set(c, "LineSelector", "Line0");
  EXPECT_FALSE(arv_camera_get_boolean(c.camera(), "LineInverter", nullptr));
  GError* e = nullptr;
  arv_camera_set_boolean(c.camera(), "LineInverter", TRUE, &e);
  ASSERT_EQ(e, nullptr) << e->message;
  EXPECT_TRUE(WaitLineStatus(true)) << "low on the wire, inverted: high";
  Set(c, "LineSelector", "Line1");
  EXPECT_FALSE(arv_camera_get_boolean(c.camera(), "LineInverter", nullptr)) << "one per line";
  Set(c, "LineSelector", "Line0");
  TriggerOn("Line0", "RisingEdge");
  ASSERT_NO_FATAL_FAILURE(StartWithChunks());
  Line0(true);  // electrical rising: inverted, a falling edge: no frame
  EXPECT_TRUE(WaitLineStatus(false));
  EXPECT_TRUE(c.Grab(300).empty()) << "a frame on the electrical rising edge";
  Line0(false);  // electrical falling: the inverted rising edge
  ChunkedFrame f = GrabChunked(c, chunks_);
  ASSERT_TRUE(f.ok) << "no frame on the electrical falling edge";
  EXPECT_EQ(f.values.at("ChunkLineStatusAll"), 1) << "Line0 high after the inverted line's rising edge";
  EXPECT_TRUE(WaitLineStatus(true));
  // Not inverted again: the electrical rising edge triggers.
  arv_camera_set_boolean(c.camera(), "LineInverter", FALSE, &e);
  ASSERT_EQ(e, nullptr);
  EXPECT_TRUE(WaitLineStatus(false));
  Line0(true);
  f = GrabChunked(c, chunks_);
  ASSERT_TRUE(f.ok);
  EXPECT_EQ(f.values.at("ChunkLineStatusAll"), 1);
  Line0(false);
  EXPECT_TRUE(c.Grab(300).empty());
}

// LineDebouncerTime (Line0): a level is taken once it has held the debounce
// time. A pulse shorter than it gives no frame; a bouncing edge then a
// longer pulse give one frame, stamped at its last rising edge plus the
// debounce time (its exposure's start: a real camera's trigger comes that
// late too).
TEST_F(GigeE2E, LineDebouncerTimeIgnoresShortPulsesAndDelaysTheTrigger) {
  ASSERT_NO_FATAL_FAILURE(StartWithTriggerLine());
  Client& c = *client_;
  constexpr double kDebounceMs = 40.0;
  constexpr uint64_t kMs = 1000000;
  const auto now_ns = [] { return static_cast<uint64_t>(g_get_real_time()) * 1000; };
  Set(c, "LineSelector", "Line1");
  EXPECT_FALSE(arv_camera_is_feature_available(c.camera(), "LineDebouncerTime", nullptr)) << "Line1 is an output";
  Set(c, "LineSelector", "Line0");
  EXPECT_TRUE(arv_camera_is_feature_available(c.camera(), "LineDebouncerTime", nullptr));
  EXPECT_DOUBLE_EQ(ReadFloat(c, "LineDebouncerTime"), 0.0);
  double lo = -1, hi = -1;
  arv_camera_get_float_bounds(c.camera(), "LineDebouncerTime", &lo, &hi, nullptr);
  EXPECT_EQ(lo, 0.0);
  EXPECT_EQ(hi, reg::kMaxLineDebouncerTimeUs);
  SetFloat(c, "LineDebouncerTime", kDebounceMs * 1000.0);
  GError* e = nullptr;
  arv_device_write_memory(c.device(), reg::kLineDebouncerTime, 8, Be64(2 * reg::kMaxLineDebouncerTimeUs).data(), &e);
  EXPECT_NE(e, nullptr) << "beyond 1 s";
  g_clear_error(&e);
  TriggerOn("Line0", "RisingEdge");
  SetFloat(c, "ExposureTime", 1000.0);
  ASSERT_TRUE(c.OpenStream());
  Start(c);
  Settle();
  EXPECT_DOUBLE_EQ(ReadFloat(c, "LineDebouncerTime"), kDebounceMs * 1000.0);
  for (int i = 0; i < 2; ++i) {  // 10 ms pulses: no frame
    Pulse(10);
    Sleep(60);
  }
  EXPECT_TRUE(c.Grab(300).empty()) << "a frame for a pulse shorter than the debounce time";
  EXPECT_FALSE(arv_camera_get_boolean(c.camera(), "LineStatus", nullptr));
  // A bounce (5 ms high, 5 ms low), then 100 ms high: one frame.
  Pulse(5);
  Sleep(5);
  const uint64_t sent = now_ns();
  Pulse(100);
  ASSERT_FALSE(c.Grab(3000).empty()) << "no frame for a pulse longer than the debounce time";
  // 5 ms for the clocks' reads (the camera's clock is the same real time).
  EXPECT_GE(c.last_timestamp_ns() + 5 * kMs, sent + static_cast<uint64_t>(kDebounceMs) * kMs)
      << "stamped before its edge plus the debounce time";
  EXPECT_LE(c.last_timestamp_ns(), sent + static_cast<uint64_t>(kDebounceMs + 10) * kMs)
      << "stamped long after its edge plus the debounce time";
  EXPECT_TRUE(c.Grab(300).empty()) << "more than one frame";
  EXPECT_EQ(c.failed_buffers(), 0u);
}

// ExposureMode TriggerWidth: an exposure lasts as long as Line0 is active.
// Two pulses of 30 and 90 ms give frames whose ChunkExposureTime is each
// pulse's width, each equal to the core's frame at that exposure (the
// pipeline rendered it). The mode is refused with a Software source, and
// locks TriggerSource and ExposureTime while on.
TEST_F(GigeE2E, TriggerWidthExposesForThePulsesWidth) {
  ASSERT_NO_FATAL_FAILURE(StartWithTriggerLine());
  Client& c = *client_;
  EXPECT_STREQ(arv_camera_get_string(c.camera(), "ExposureMode", nullptr), "Timed");
  TriggerOn("Software");
  Settle();
  GError* e = nullptr;
  arv_camera_set_string(c.camera(), "ExposureMode", "TriggerWidth", &e);
  EXPECT_NE(e, nullptr) << "TriggerWidth with a Software source";
  g_clear_error(&e);
  arv_device_write_memory(c.device(), reg::kExposureMode, 4, Be32(genicam::kExposureTriggerWidth).data(), &e);
  EXPECT_TRUE(g_error_matches(e, ARV_DEVICE_ERROR, ARV_DEVICE_ERROR_PROTOCOL_ERROR_ACCESS_DENIED)) << "a raw write";
  g_clear_error(&e);
  EXPECT_STREQ(arv_camera_get_string(c.camera(), "ExposureMode", nullptr), "Timed");
  Set(c, "TriggerSource", "Line0");
  Set(c, "TriggerActivation", "RisingEdge");
  Set(c, "ExposureMode", "TriggerWidth");
  Settle();
  EXPECT_STREQ(arv_camera_get_string(c.camera(), "ExposureMode", nullptr), "TriggerWidth");
  const double exposure = ReadFloat(c, "ExposureTime");
  arv_device_write_memory(c.device(), reg::kExposureTime, 8, Be64(1234.0).data(), &e);
  EXPECT_TRUE(g_error_matches(e, ARV_DEVICE_ERROR, ARV_DEVICE_ERROR_PROTOCOL_ERROR_ACCESS_DENIED)) << "ExposureTime";
  g_clear_error(&e);
  arv_device_write_memory(c.device(), reg::kTriggerSource, 4, Be32(genicam::kSourceSoftware).data(), &e);
  EXPECT_TRUE(g_error_matches(e, ARV_DEVICE_ERROR, ARV_DEVICE_ERROR_PROTOCOL_ERROR_ACCESS_DENIED)) << "TriggerSource";
  g_clear_error(&e);
  Settle();
  EXPECT_EQ(ReadFloat(c, "ExposureTime"), exposure);
  EXPECT_STREQ(arv_camera_get_string(c.camera(), "TriggerSource", nullptr), "Line0");
  {
    ArvGcNode* node = arv_device_get_feature(c.device(), "ExposureTime");
    ASSERT_NE(node, nullptr);
    EXPECT_TRUE(arv_gc_feature_node_is_locked(ARV_GC_FEATURE_NODE(node), nullptr)) << "pIsLocked";
  }
  // What the pulse's exposure needs is locked too, in the XML and by the
  // device: a TriggerActivation or Line0 LineInverter change mid-pulse would
  // take the pulse's end for a new start and leave its exposure open.
  Set(c, "LineSelector", "Line0");
  for (const char* name : {"TriggerMode", "TriggerSource", "TriggerActivation", "ExposureAuto", "LineInverter"}) {
    ArvGcNode* node = arv_device_get_feature(c.device(), name);
    ASSERT_NE(node, nullptr) << name;
    EXPECT_TRUE(arv_gc_feature_node_is_locked(ARV_GC_FEATURE_NODE(node), nullptr)) << name << ": pIsLocked";
  }
  for (const uint32_t address : {reg::kTriggerActivation, reg::SelectedAddress(reg::kLineInverter, 0)}) {
    arv_device_write_memory(c.device(), address, 4, Be32(1).data(), &e);
    EXPECT_TRUE(g_error_matches(e, ARV_DEVICE_ERROR, ARV_DEVICE_ERROR_PROTOCOL_ERROR_ACCESS_DENIED))
        << "a write at " << std::hex << address;
    g_clear_error(&e);
  }
  Set(c, "LineSelector", "Line1");
  {
    ArvGcNode* node = arv_device_get_feature(c.device(), "LineInverter");
    EXPECT_FALSE(arv_gc_feature_node_is_locked(ARV_GC_FEATURE_NODE(node), nullptr)) << "Line1's: the strobe";
  }
  Settle();
  EXPECT_STREQ(arv_camera_get_string(c.camera(), "TriggerActivation", nullptr), "RisingEdge");
  ASSERT_NO_FATAL_FAILURE(StartWithChunks());
  const uint32_t code = genicam::BayerCode(Cfa::kBayerRG, 12);
  for (const int width_ms : {30, 90}) {
    Line0(true);
    Sleep(width_ms);
    EXPECT_TRUE(c.Grab(0).empty());
    Line0(false);
    ChunkedFrame f = GrabChunked(c, chunks_);
    ASSERT_TRUE(f.ok) << width_ms << " ms";
    const double us = f.values.at("ChunkExposureTime");
    EXPECT_GE(us, width_ms * 1000.0) << width_ms << " ms";
    EXPECT_LE(us, width_ms * 1000.0 + 25000.0) << width_ms << " ms";  // the sleep may overrun
    char set[64];
    std::snprintf(set, sizeof set, "exposure.exposure_time_us=%.17g", us);
    const auto index = static_cast<uint32_t>(f.values.at("ChunkSimFrameIndex"));
    EXPECT_TRUE(f.image == Reference(index, code, 0, 0, 64, 48, {set})) << "not rendered at " << set;
  }
  EXPECT_TRUE(c.Grab(300).empty()) << "more frames than pulses";
  // Timed again: ExposureTime is used (and free) again.
  arv_camera_stop_acquisition(c.camera(), &e);
  ASSERT_EQ(e, nullptr);
  Set(c, "ExposureMode", "Timed");
  SetFloat(c, "ExposureTime", 1234.0);
  Settle();
  EXPECT_EQ(ReadFloat(c, "ExposureTime"), 1234.0);
}

// TriggerWidth over the trigger bus times each edge by its sender's stamp,
// not by when the camera's reader got to it. A rising edge stamped 60 ms
// ago and a falling one stamped now, sent back to back, expose 60 ms (read
// times: a few microseconds); a BusOutput pulse exposes the time between its
// two Sets, to well under a millisecond (read times: the reader's latency).
TEST_F(GigeE2E, TriggerWidthOverTheBusTakesTheSendersEdgeTimes) {
  ASSERT_NO_FATAL_FAILURE(StartWithTriggerBus("camsim-width-bus"));
  Client& c = *client_;
  TriggerOn("Line0", "RisingEdge");
  Set(c, "ExposureMode", "TriggerWidth");
  ASSERT_NO_FATAL_FAILURE(StartWithChunks());
  ArvChunkParser* parser = chunks_;
  const std::string socket_path = BusSocketIn(bus_dir_);
  const long long now_ns = hal::MonotonicNowNs();
  SendBusEdge(socket_path, true, 10, now_ns - 60000000LL);
  SendBusEdge(socket_path, false, 10, now_ns);
  ChunkedFrame f = GrabChunked(c, parser);
  ASSERT_TRUE(f.ok) << "no frame for the stamped pulse";
  EXPECT_NEAR(f.values.at("ChunkExposureTime"), 60000.0, 200.0) << "µs: not the stamps' 60 ms";
  std::string error;
  auto bus = hal::OpenBusOutput("unix:" + bus_dir_, &error);
  ASSERT_NE(bus, nullptr) << error;
  const auto r0 = std::chrono::steady_clock::now();
  ASSERT_TRUE(bus->Set(true, &error)) << error;
  const auto r1 = std::chrono::steady_clock::now();
  Sleep(30);
  const auto f0 = std::chrono::steady_clock::now();
  ASSERT_TRUE(bus->Set(false, &error)) << error;
  const auto f1 = std::chrono::steady_clock::now();
  f = GrabChunked(c, parser);
  ASSERT_TRUE(f.ok) << "no frame for the BusOutput pulse";
  const auto us = [](auto span) { return std::chrono::duration<double, std::micro>(span).count(); };
  EXPECT_GE(f.values.at("ChunkExposureTime"), us(f0 - r1) - 50.0);
  EXPECT_LE(f.values.at("ChunkExposureTime"), us(f1 - r0) + 50.0);
  EXPECT_TRUE(c.Grab(300).empty()) << "more frames than pulses";
  EndTriggerBus();
}

// A triggered frame's timestamp is its edge's time on the device's clock
// to the nanosecond (plus LineDebouncerTime): pulses stamped 60.123457 ms
// apart give frames 60.123457 ms apart. The clock was the host's real time
// in microseconds, read apart from the steady clock the edges are on, so a
// user's review saw debounced frames 90-250 us late now and then.
TEST_F(GigeE2E, TriggeredFramesAreStampedAtTheirEdgesToTheNanosecond) {
  ASSERT_NO_FATAL_FAILURE(StartWithTriggerBus("camsim-stamp-bus"));
  Client& c = *client_;
  TriggerOn("Line0", "RisingEdge");
  Set(c, "LineSelector", "Line0");
  ASSERT_NO_FATAL_FAILURE(OpenAndStart());
  const std::string socket_path = BusSocketIn(bus_dir_);
  constexpr long long kApart = 60123457, kHigh = 25000000;  // ns
  for (const double debounce_us : {0.0, 20000.0}) {
    SetFloat(c, "LineDebouncerTime", debounce_us);
    Settle();
    const long long t0 = hal::MonotonicNowNs() - 200000000LL;
    for (int k = 0; k < 2; ++k) {
      SendBusEdge(socket_path, true, 20 + k, t0 + k * kApart);
      SendBusEdge(socket_path, false, 20 + k, t0 + k * kApart + kHigh);
    }
    uint64_t stamps[2] = {};
    for (uint64_t& t : stamps) {
      ASSERT_FALSE(c.Grab(3000).empty()) << "debounce " << debounce_us << " us: a pulse gave no frame";
      t = c.last_timestamp_ns();
    }
    EXPECT_EQ(stamps[1] - stamps[0], static_cast<uint64_t>(kApart)) << "debounce " << debounce_us << " us";
    EXPECT_TRUE(c.Grab(300).empty()) << "more frames than pulses";
  }
  EndTriggerBus();
}

// Edges are taken in order even when a stamp falls back to its read time
// (a reader stalled past kMaxEdgeAgeS): a rising edge stamped 11 s ago
// counts from when it was read, and the falling and rising edges after it,
// stamped 1 s and 0.5 s ago, cannot move the line back before it; the
// debounced trigger comes 20 ms after the read, not 480 ms before it.
TEST_F(GigeE2E, AStaleEdgeStampDoesNotTakeTheLineBackInTime) {
  ASSERT_NO_FATAL_FAILURE(StartWithTriggerBus("camsim-stale-bus"));
  Client& c = *client_;
  TriggerOn("Line0", "RisingEdge");
  Set(c, "LineSelector", "Line0");
  SetFloat(c, "LineDebouncerTime", 20000.0);
  Settle();
  ASSERT_NO_FATAL_FAILURE(OpenAndStart());
  GError* e = nullptr;
  arv_camera_execute_command(c.camera(), "GevTimestampControlLatch", &e);
  ASSERT_EQ(e, nullptr);
  const int64_t before = arv_camera_get_integer(c.camera(), "GevTimestampValue", &e);
  ASSERT_EQ(e, nullptr);
  const std::string socket_path = BusSocketIn(bus_dir_);
  const long long now_ns = hal::MonotonicNowNs();
  SendBusEdge(socket_path, true, 30, now_ns - 11000000000LL);
  SendBusEdge(socket_path, false, 30, now_ns - 1000000000LL);
  SendBusEdge(socket_path, true, 31, now_ns - 500000000LL);
  ASSERT_FALSE(c.Grab(3000).empty()) << "no frame for the last rising edge";
  EXPECT_GE(static_cast<int64_t>(c.last_timestamp_ns()), before + 20000000) << "stamped before the edges were read";
  EXPECT_TRUE(c.Grab(300).empty()) << "more frames than rising levels";
  EndTriggerBus();
}

// One mechanism for the XML and the device: for every feature and entry with
// an availability or lock formula, over every value of the formula's
// variables (a selected feature's own selector at each selection), Aravis's
// view from the downloaded XML (the node's is_available or is_locked) agrees
// with whether the device takes a raw write that changes the value (or, for
// an entry, changes to it); each formula is seen both ways.
TEST_F(GigeE2E, TheDeviceRefusesWhatTheXmlsFormulasSay) {
  DeviceOptions o = SmallDevice();
  o.trigger = &trigger_;  // TriggerSource Line0: ExposureMode TriggerWidth can be reached
  ASSERT_NO_FATAL_FAILURE(StartWith(o));
  Client& c = *client_;
  ArvDevice* dev = c.device();
  ArvGc* gc = arv_device_get_genicam(dev);
  const std::vector<genicam::Feature>& table = device_->table();
  // A raw write (Aravis checks nothing): taken, or refused with access denied.
  const auto takes = [&](uint32_t address, std::vector<uint8_t> bytes) {
    GError* e = nullptr;
    arv_device_write_memory(dev, address, static_cast<guint32>(bytes.size()), bytes.data(), &e);
    const bool taken = e == nullptr;
    EXPECT_TRUE(taken || g_error_matches(e, ARV_DEVICE_ERROR, ARV_DEVICE_ERROR_PROTOCOL_ERROR_ACCESS_DENIED))
        << "at 0x" << std::hex << address << ": " << e->message;
    g_clear_error(&e);
    return taken;
  };
  using State = std::vector<std::pair<const genicam::Feature*, int64_t>>;
  // ExposureMode Timed (it locks the trigger), then TriggerMode On,
  // TriggerSource Line0 and ExposureAuto Off (where TriggerWidth is
  // available), then the state, ExposureMode last; false when the device
  // did not take it all (a state the rules leave out).
  const auto reach = [&](const State& state) {
    takes(reg::kExposureMode, Be32(genicam::kExposureTimed));
    takes(reg::kTriggerMode, Be32(1));
    takes(reg::kTriggerSource, Be32(genicam::kSourceLine0));
    takes(reg::kExposureAuto, Be32(genicam::kAutoOff));
    for (const bool mode : {false, true})
      for (const auto& [f, v] : state)
        if ((f->address == reg::kExposureMode) == mode) takes(f->address, Be32(static_cast<uint32_t>(v)));
    for (const auto& [f, v] : state)
      if (ReadReg32(*device_, f->address) != static_cast<uint32_t>(v)) return false;
    return true;
  };
  const auto says = [](const State& state) {
    std::string s;
    for (const auto& [f, v] : state) s += " " + f->name + "=" + std::to_string(v);
    return s;
  };
  // Every state of the variables: each one's values (an Enumeration's
  // entries, a Boolean's 0 and 1), a selected feature's selector at `selection`.
  const auto each_state = [&](const genicam::Feature& f, const std::vector<std::pair<std::string, std::string>>& vars,
                              int selection, const std::function<void(const State&)>& check) {
    std::vector<const genicam::Feature*> features;
    std::vector<std::vector<int64_t>> values;
    for (const auto& [name, feature] : vars) {
      const genicam::Feature* v = genicam::FindFeature(table, feature);
      ASSERT_NE(v, nullptr) << f.name << ": " << feature;
      features.push_back(v);
      values.emplace_back();
      if (feature == f.selected_by) values.back() = {selection};
      else if (v->kind == genicam::Kind::kBoolean) values.back() = {0, 1};
      else if (v->kind == genicam::Kind::kEnum)
        for (const genicam::EnumEntry& e : v->entries) values.back().push_back(e.value);
      else FAIL() << f.name << ": give the values of " << feature;
    }
    std::vector<size_t> at(features.size(), 0);
    for (;;) {
      State state;
      for (size_t i = 0; i < features.size(); ++i) state.push_back({features[i], values[i][at[i]]});
      check(state);
      size_t i = 0;
      while (i < at.size() && at[i] + 1 == values[i].size()) at[i++] = 0;
      if (i == at.size()) return;
      ++at[i];
    }
  };
  int formulas = 0, states = 0;
  for (const genicam::Feature& f : table) {
    // The feature's own formula: a change of its value.
    const bool lock = !f.locked_formula.empty();
    if (lock || !f.available_formula.empty()) {
      ++formulas;
      ArvGcNode* node = arv_gc_get_node(gc, f.name.c_str());
      ASSERT_NE(node, nullptr) << f.name;
      for (int selection = 0; selection < f.selections; ++selection) {
        const uint32_t address = reg::SelectedAddress(f.address, static_cast<size_t>(selection), f.length);
        bool seen[2] = {false, false};
        each_state(f, f.variables, selection, [&](const State& state) {
          if (!reach(state)) return;
          ++states;
          const bool xml = lock ? !arv_gc_feature_node_is_locked(ARV_GC_FEATURE_NODE(node), nullptr)
                                : arv_gc_feature_node_is_available(ARV_GC_FEATURE_NODE(node), nullptr);
          // Another valid value, and the value now to put back.
          std::vector<uint8_t> other, now;
          switch (f.kind) {
            case genicam::Kind::kFloat: {
              const double x = ReadRegDouble(*device_, address);
              other = Be64(x == 0 ? f.max / 4 : x * 2 <= f.max ? x * 2 : x / 2);
              now = Be64(x);
              break;
            }
            case genicam::Kind::kCommand: other = Be32(static_cast<uint32_t>(f.command_value)); break;
            default: {
              const uint32_t x = ReadReg32(*device_, address);
              uint32_t y = x == 0 ? 1 : 0;  // a Boolean's other value, an Enumeration's first other entry
              if (f.kind == genicam::Kind::kInteger) y = x + f.inc <= f.max ? x + uint32_t(f.inc) : x - uint32_t(f.inc);
              for (size_t e = f.entries.size(); e-- > 0;)
                if (f.entries[e].value != x && f.entries[e].available) y = static_cast<uint32_t>(f.entries[e].value);
              other = Be32(y);
              now = Be32(x);
            }
          }
          const bool taken = takes(address, other);
          if (taken && !now.empty()) {
            EXPECT_TRUE(takes(address, now)) << f.name << ": put back";
          }
          EXPECT_EQ(taken, xml) << f.name << "[" << selection << "]" << (lock ? " locked" : " available")
                                << " by the XML: " << !xml << "; the device " << (taken ? "took" : "refused")
                                << " a change at" << says(state);
          seen[taken] = true;
        });
        if (f.name != "LineInverter" || selection == 0) {  // (Line1's is never locked)
          EXPECT_TRUE(seen[0] && seen[1]) << f.name << "[" << selection << "]: taken " << seen[1] << ", refused "
                                          << seen[0];
        }
      }
    }
    // Its entries' formulas: a change to the entry.
    for (const genicam::EnumEntry& entry : f.entries) {
      if (entry.available_formula.empty()) continue;
      ++formulas;
      ArvGcNode* node = nullptr;
      for (const GSList* e = arv_gc_enumeration_get_entries(ARV_GC_ENUMERATION(arv_gc_get_node(gc, f.name.c_str())));
           e != nullptr; e = e->next)
        if (entry.name == arv_gc_feature_node_get_name(ARV_GC_FEATURE_NODE(e->data))) node = ARV_GC_NODE(e->data);
      ASSERT_NE(node, nullptr) << f.name << " " << entry.name;
      bool seen[2] = {false, false};
      each_state(f, entry.variables, 0, [&](const State& state) {
        if (!reach(state)) return;
        const uint32_t now = ReadReg32(*device_, f.address);
        if (now == static_cast<uint32_t>(entry.value)) return;  // no change to it
        ++states;
        const bool xml = arv_gc_feature_node_is_available(ARV_GC_FEATURE_NODE(node), nullptr);
        const bool taken = takes(f.address, Be32(static_cast<uint32_t>(entry.value)));
        if (taken) {
          EXPECT_TRUE(takes(f.address, Be32(now))) << f.name << ": put back";
        }
        EXPECT_EQ(taken, xml) << f.name << " entry " << entry.name << " available by the XML: " << xml
                              << "; the device " << (taken ? "took" : "refused") << " it at" << says(state);
        seen[taken] = true;
      });
      EXPECT_TRUE(seen[0] && seen[1]) << f.name << " " << entry.name;
    }
  }
  EXPECT_GE(formulas, 14) << "ExposureTime(Abs), Gain(Raw), the trigger's, Gamma, the lines', UserSetSave, ...";
  EXPECT_GE(states, 45);
}

using reg::kControlChannelPrivilege, reg::kHeartbeatTimeout, reg::kStreamPort, reg::kStreamDestAddress;

// A controller that speaks raw GVCP from its own socket, so the test can let
// it die mid-stream (no heartbeat, no AcquisitionStop) as a killed process would.
class RawController {
 public:
  RawController() {
    fd_ = socket(AF_INET, SOCK_DGRAM | SOCK_CLOEXEC, 0);
    sink_ = socket(AF_INET, SOCK_DGRAM | SOCK_CLOEXEC, 0);
    sockaddr_in a{};
    a.sin_family = AF_INET;
    a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    bind(sink_, reinterpret_cast<sockaddr*>(&a), sizeof a);
    socklen_t n = sizeof a;
    getsockname(sink_, reinterpret_cast<sockaddr*>(&a), &n);
    sink_port_ = ntohs(a.sin_port);
  }
  ~RawController() {
    close(fd_);
    close(sink_);
  }
  // WRITEREG_CMD (0x0082) of one register; true when acknowledged.
  bool Write(uint32_t address, uint32_t value) {
    std::vector<uint8_t> body;
    Put32(&body, address);
    Put32(&body, value);
    return Command(0x82, body, nullptr);
  }
  // WRITEREG_CMD with an address and no value (a malformed packet).
  bool WriteWithoutValue(uint32_t address) {
    std::vector<uint8_t> body;
    Put32(&body, address);
    return Command(0x82, body, nullptr);
  }
  // READREG_CMD (0x0080) of one register; true when acknowledged.
  bool Read(uint32_t address, uint32_t* value) {
    std::vector<uint8_t> body, ack;
    Put32(&body, address);
    if (!Command(0x80, body, &ack) || ack.size() < 12) return false;
    *value = Get32(ack, 8);
    return true;
  }
  // READMEM_CMD (0x0084) of `size` bytes; true when acknowledged with them.
  bool ReadMemory(uint32_t address, uint16_t size, std::vector<uint8_t>* data) {
    std::vector<uint8_t> body, ack;
    Put32(&body, address);
    Put32(&body, size);
    if (!Command(0x84, body, &ack) || ack.size() < 12u + size) return false;
    data->assign(ack.begin() + 12, ack.begin() + 12 + size);
    return true;
  }
  // WRITEMEM_CMD (0x0086) of `data` at address, its header's length field
  // set to `length` (4 + data.size() in a well-formed packet).
  bool WriteMemory(uint32_t address, const std::vector<uint8_t>& data, uint16_t length) {
    std::vector<uint8_t> body;
    Put32(&body, address);
    body.insert(body.end(), data.begin(), data.end());
    return Command(0x86, body, nullptr, length);
  }
  // True when a frame's GVSP trailer (packet format 2: the frame was sent
  // whole; a leader alone may be the device's primer) reaches the stream sink
  // within timeout_ms.
  bool FrameArrives(int timeout_ms) {
    const auto end = std::chrono::steady_clock::now() + std::chrono::milliseconds(timeout_ms);
    uint8_t packet[9000];
    for (;;) {
      const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(end - std::chrono::steady_clock::now());
      pollfd p{sink_, POLLIN, 0};
      if (left.count() <= 0 || poll(&p, 1, static_cast<int>(left.count())) <= 0) return false;
      if (recv(sink_, packet, sizeof packet, 0) >= 8 && packet[4] == 2) return true;
    }
  }
  // The next GVSP packet at the stream sink within timeout_ms (empty: none).
  std::vector<uint8_t> NextStreamPacket(int timeout_ms) {
    std::vector<uint8_t> packet(9000);
    pollfd p{sink_, POLLIN, 0};
    if (poll(&p, 1, timeout_ms) <= 0) return {};
    const ssize_t got = recv(sink_, packet.data(), packet.size(), 0);
    packet.resize(got < 0 ? 0 : static_cast<size_t>(got));
    return packet;
  }
  // PACKETRESEND_CMD (0x0040, standard IDs) for packets first..last of a
  // block: stream channel 0, block ID, the two packet IDs. No
  // acknowledgement comes back.
  void AskResend(uint16_t block, uint32_t first, uint32_t last) {
    std::vector<uint8_t> body = {0, 0, uint8_t(block >> 8), uint8_t(block)};
    Put32(&body, first);
    Put32(&body, last);
    Send(0x40, body, ++id_, -1);
  }
  uint16_t sink_port() const { return sink_port_; }
  // The GVCP status of the last command's acknowledgement (0: success;
  // kNoAck: none came).
  static constexpr uint16_t kNoAck = 0xffff;
  uint16_t status() const { return status_; }
  // Sends `datagram` as it is; true when any reply comes within timeout_ms.
  bool SendRaw(const std::vector<uint8_t>& datagram, int timeout_ms) {
    sockaddr_in to{};
    to.sin_family = AF_INET;
    to.sin_port = htons(3956);
    to.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    sendto(fd_, datagram.data(), datagram.size(), 0, reinterpret_cast<sockaddr*>(&to), sizeof to);
    pollfd p{fd_, POLLIN, 0};
    if (poll(&p, 1, timeout_ms) <= 0) return false;
    uint8_t reply[2048];
    return recv(fd_, reply, sizeof reply, 0) >= 0;
  }

 private:
  static void Put32(std::vector<uint8_t>* b, uint32_t v) {
    for (int i = 0; i < 4; ++i) b->push_back(static_cast<uint8_t>(v >> (24 - 8 * i)));
  }
  bool Send(uint16_t command, const std::vector<uint8_t>& body, uint16_t id, int length) {
    const uint16_t n = static_cast<uint16_t>(length < 0 ? body.size() : length);
    std::vector<uint8_t> cmd = {0x42, 0x01, uint8_t(command >> 8), uint8_t(command), uint8_t(n >> 8), uint8_t(n),
                                uint8_t(id >> 8), uint8_t(id)};
    cmd.insert(cmd.end(), body.begin(), body.end());
    sockaddr_in to{};
    to.sin_family = AF_INET;
    to.sin_port = htons(3956);
    to.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    return sendto(fd_, cmd.data(), cmd.size(), 0, reinterpret_cast<sockaddr*>(&to), sizeof to) ==
           static_cast<ssize_t>(cmd.size());
  }
  static uint32_t Get32(const std::vector<uint8_t>& b, size_t at) {
    return uint32_t{b[at]} << 24 | uint32_t{b[at + 1]} << 16 | uint32_t{b[at + 2]} << 8 | b[at + 3];
  }

 public:
  // WRITEREG_CMD of one register, sent without waiting for its
  // acknowledgement (the next Command skips it).
  void PostWrite(uint32_t address, uint32_t value) {
    std::vector<uint8_t> body;
    Put32(&body, address);
    Put32(&body, value);
    Send(0x82, body, ++id_, -1);
    posted_ = id_;
  }
  // Sends a GVCP command (header: key 0x42, flag "acknowledge", command,
  // length of body, request id) and waits for its acknowledgement (command
  // + 1, same request id). length < 0: the body's length.
  bool Command(uint16_t command, const std::vector<uint8_t>& body, std::vector<uint8_t>* ack, int length = -1) {
    status_ = kNoAck;
    const uint16_t id = ++id_;
    if (!Send(command, body, id, length)) return false;
    // The fake camera answers between frames: one packet per frame when they
    // come back to back. Acknowledgements of commands Post sent are skipped.
    std::vector<uint8_t> reply(2048);
    ssize_t got = 0;
    for (;;) {
      pollfd p{fd_, POLLIN, 0};
      if (poll(&p, 1, 10000) <= 0) return false;
      got = recv(fd_, reply.data(), reply.size(), 0);
      if (got < 8 || (uint16_t(reply[6] << 8 | reply[7])) != id) {
        if (got >= 8 && (uint16_t(reply[6] << 8 | reply[7])) <= posted_) continue;
        return false;
      }
      break;
    }
    if ((uint16_t(reply[2] << 8 | reply[3])) != command + 1) return false;
    reply.resize(static_cast<size_t>(got));
    status_ = static_cast<uint16_t>(reply[0] << 8 | reply[1]);
    if (ack != nullptr) *ack = reply;
    return true;
  }

 private:
  int fd_ = -1, sink_ = -1;
  uint16_t sink_port_ = 0, id_ = 0, status_ = 0, posted_ = 0;  // posted_: the last PostWrite's id
};

constexpr int kTestHeartbeatMs = 1500;

// The first controller sets a 64x48 window, its stream and AcquisitionStart
// at once, streams, and dies (no heartbeat, no AcquisitionStop). Returns when
// its stream has reached its port.
void StartAndDie(GigeDevice& d, int stream_wait_ms) {
  RawController dead;
  ASSERT_TRUE(dead.Write(kControlChannelPrivilege, 2));  // control
  // Heartbeat timeout: the test waits less than the default 3 s, and the next
  // controller still has time to write its own between two slow frames.
  ASSERT_TRUE(dead.Write(kHeartbeatTimeout, kTestHeartbeatMs));
  ASSERT_TRUE(dead.Write(reg::kAcquisitionFrameRateEnable, 0));  // frames back to back
  ASSERT_TRUE(dead.Write(reg::kWidth, 64));
  ASSERT_TRUE(dead.Write(reg::kHeight, 48));
  ASSERT_TRUE(dead.Write(kStreamDestAddress, INADDR_LOOPBACK));
  ASSERT_TRUE(dead.Write(kStreamPort, dead.sink_port()));
  ASSERT_TRUE(dead.Write(reg::kAcquisition, 1));
  ASSERT_TRUE(dead.FrameArrives(stream_wait_ms)) << "the first client's stream";
  EXPECT_EQ(d.writes_refused(), 0u) << "the window written just before AcquisitionStart was refused";
}

// A client killed mid-stream leaves the acquisition running to its port. An
// Aravis client that comes after the heartbeat timeout gets control, and its
// frames (of the window the dead client set) come to it.
TEST_F(GigeE2E, AClientKilledMidStreamDoesNotKeepTheStream) {
  device_ = StartDevice(SmallDevice(320, 240));
  ASSERT_NE(device_, nullptr);
  for (int round = 0; round < 2; ++round) {
    SCOPED_TRACE("round " + std::to_string(round));
    ASSERT_NO_FATAL_FAILURE(StartAndDie(*device_, 5000));
    Sleep(kTestHeartbeatMs + 100);  // past the heartbeat timeout
    Client c;
    ASSERT_TRUE(c.ok()) << c.last_error;
    arv_device_write_register(c.device(), kHeartbeatTimeout, 3000, nullptr);  // the default again
    ASSERT_TRUE(c.OpenStream());
    Start(c);  // at once, as a client does
    for (int i = 0; i < 3; ++i) {
      const std::vector<uint8_t> f = c.Grab(5000);
      ASSERT_EQ(f.size(), 64u * 48 * 2) << "frame " << i << " of the next client";
    }
    EXPECT_EQ(c.failed_buffers(), 0u);
  }
}

// The same, with a controller whose first packet after the timeout is its
// control request: the fake camera hands control over inside that one packet
// and keeps streaming to the dead port, so the device must make it drop that
// stream (GigeDevice::RestartStream). Frames back to back leave the fake
// camera one packet per frame, and frames here take longer than the device
// used to wait for its packet to be handled (200 ms).
TEST_F(GigeE2E, ATakeoverInOnePacketMovesTheStream) {
#ifdef NDEBUG
  DeviceOptions o = SmallDevice(4096, 3072);  // about 0.4 s a frame on one thread
#else
  DeviceOptions o = SmallDevice(640, 480);  // unoptimised, with sanitizers: as slow
#endif
  // The device's own probe would end the dead client's control before the
  // next client's request comes (ASilentControllersAcquisitionStops); this
  // is the case of a request that comes first.
  o.probe_heartbeat = false;
  device_ = StartDevice(o);
  ASSERT_NE(device_, nullptr);
  ASSERT_NO_FATAL_FAILURE(StartAndDie(*device_, 20000));
  Sleep(kTestHeartbeatMs + 100);
  RawController next;
  ASSERT_TRUE(next.Write(kControlChannelPrivilege, 2)) << "control after the heartbeat timeout";
  ASSERT_TRUE(next.Write(kHeartbeatTimeout, 60000));  // this controller sends no heartbeats
  ASSERT_TRUE(next.Write(kStreamDestAddress, INADDR_LOOPBACK));
  ASSERT_TRUE(next.Write(kStreamPort, next.sink_port()));
  ASSERT_TRUE(next.Write(reg::kAcquisition, 1));
  EXPECT_TRUE(next.FrameArrives(20000)) << "the stream still goes to the dead client";
  ASSERT_TRUE(next.Write(reg::kAcquisition, 0));
}

// The fake camera checks its controller's heartbeat only when a packet
// comes: a killed client's free run went on rendering and sending (287
// frames in 11 s in a review) until some other packet came. The device now
// sends its camera a packet itself (ProbeHeartbeat): a controller that
// keeps reading the privilege register keeps its stream, a silent one
// loses it, and the rendering stops, within the timeout and a margin.
TEST_F(GigeE2E, ASilentControllersAcquisitionStops) {
  device_ = StartDevice(SmallDevice());
  ASSERT_NE(device_, nullptr);
  constexpr int kTimeoutMs = 1000;
  RawController ctl;
  ASSERT_TRUE(ctl.Write(kControlChannelPrivilege, 2));
  ASSERT_TRUE(ctl.Write(kHeartbeatTimeout, kTimeoutMs));
  ASSERT_TRUE(ctl.Write(kStreamDestAddress, INADDR_LOOPBACK));
  ASSERT_TRUE(ctl.Write(kStreamPort, ctl.sink_port()));
  ASSERT_TRUE(ctl.Write(reg::kAcquisition, 1));  // free run at 25 Hz
  ASSERT_TRUE(ctl.FrameArrives(5000));
  // Alive for three timeouts: a privilege read every quarter of one.
  for (int i = 0; i < 12; ++i) {
    const uint64_t before = device_->frames_sent();
    uint32_t privilege = 0;
    ASSERT_TRUE(ctl.Read(kControlChannelPrivilege, &privilege));
    EXPECT_EQ(privilege, 2u) << "a live controller lost control, read " << i;
    Sleep(kTimeoutMs / 4);
    EXPECT_GT(device_->frames_sent(), before) << "a live controller's stream stopped, read " << i;
  }
  // Silent from here: the frames stop within the timeout and a margin.
  const auto silent = std::chrono::steady_clock::now();
  uint64_t last = device_->frames_sent();
  auto last_change = silent;
  while (std::chrono::steady_clock::now() - last_change < std::chrono::milliseconds(500) &&
         std::chrono::steady_clock::now() - silent < std::chrono::seconds(10)) {
    Sleep(20);
    const uint64_t now = device_->frames_sent();
    if (now != last) {
      last = now;
      last_change = std::chrono::steady_clock::now();
    }
  }
  const double stopped_ms = std::chrono::duration<double, std::milli>(last_change - silent).count();
  EXPECT_LT(stopped_ms, kTimeoutMs + 500) << "frames went on " << stopped_ms << " ms after the controller fell silent";
  Sleep(1000);
  EXPECT_EQ(device_->frames_sent(), last) << "the rendering started again";
  EXPECT_EQ(ReadReg32(*device_, reg::kAcquisition), 0u) << "the device did not stop the acquisition";
  EXPECT_EQ(ReadReg32(*device_, kControlChannelPrivilege), 0u) << "the silent controller still has control";
}

// GigE Vision has every command from the controller renew its heartbeat;
// the fake camera renews it only on a read of the privilege register. The
// device's probe reads that register when the controller sent a command
// since the last probe (ControllerPackets): a client that keeps itself alive
// by writing GevHeartbeatTimeout (as Pylon does) or other reads keeps
// control, idle or acquiring. Another client's commands renew nothing.
TEST_F(GigeE2E, AnyCommandFromTheControllerRenewsItsHeartbeat) {
  device_ = StartDevice(SmallDevice());
  ASSERT_NE(device_, nullptr);
  constexpr int kTimeoutMs = 1000;
  RawController ctl, other;
  ASSERT_TRUE(ctl.Write(kControlChannelPrivilege, 2));
  ASSERT_TRUE(ctl.Write(kHeartbeatTimeout, kTimeoutMs));
  // Never a read of the privilege register: writes of the timeout and
  // reads of another register, every quarter of the timeout.
  uint32_t value = 0;
  const auto keep_alive = [&](int i) {
    const bool acked = i % 2 == 0 ? ctl.Write(kHeartbeatTimeout, kTimeoutMs) : ctl.Read(kStreamPort, &value);
    EXPECT_TRUE(acked && ctl.status() == 0) << "command " << i << " status " << ctl.status();
  };
  for (int i = 0; i < 8; ++i) {  // idle, twice the timeout
    keep_alive(i);
    Sleep(kTimeoutMs / 4);
  }
  EXPECT_EQ(ReadReg32(*device_, kControlChannelPrivilege), 2u) << "an idle controller lost control";
  ASSERT_TRUE(ctl.Write(kStreamDestAddress, INADDR_LOOPBACK));
  ASSERT_EQ(ctl.status(), 0) << "an idle controller's write was refused";
  ASSERT_TRUE(ctl.Write(kStreamPort, ctl.sink_port()));
  ASSERT_TRUE(ctl.Write(reg::kAcquisition, 1));  // free run at 25 Hz
  ASSERT_TRUE(ctl.FrameArrives(5000));
  for (int i = 0; i < 12; ++i) {  // acquiring, three timeouts
    const uint64_t before = device_->frames_sent();
    keep_alive(i);
    Sleep(kTimeoutMs / 4);
    EXPECT_GT(device_->frames_sent(), before) << "a live controller's stream stopped, command " << i;
  }
  EXPECT_EQ(ReadReg32(*device_, kControlChannelPrivilege), 2u) << "an acquiring controller lost control";
  // The controller falls silent; another client reads and writes (refused)
  // every quarter of the timeout. The frames stop within the timeout and a margin.
  const auto silent = std::chrono::steady_clock::now();
  auto last_change = silent, last_other = silent - std::chrono::seconds(1);
  uint64_t last = device_->frames_sent();
  int other_denied = 0;
  while (std::chrono::steady_clock::now() - last_change < std::chrono::milliseconds(500) &&
         std::chrono::steady_clock::now() - silent < std::chrono::seconds(10)) {
    if (std::chrono::steady_clock::now() - last_other >= std::chrono::milliseconds(kTimeoutMs / 4)) {
      last_other = std::chrono::steady_clock::now();
      EXPECT_TRUE(other.Read(kStreamPort, &value));
      EXPECT_TRUE(other.Write(kHeartbeatTimeout, kTimeoutMs));
      other_denied += other.status() == 0x8006;
    }
    Sleep(20);
    const uint64_t now = device_->frames_sent();
    if (now != last) {
      last = now;
      last_change = std::chrono::steady_clock::now();
    }
  }
  EXPECT_GT(other_denied, 0) << "the other client was never refused: not a test of its packets";
  const double stopped_ms = std::chrono::duration<double, std::milli>(last_change - silent).count();
  EXPECT_LT(stopped_ms, kTimeoutMs + 500) << "frames went on " << stopped_ms << " ms after the controller fell silent";
  EXPECT_EQ(ReadReg32(*device_, kControlChannelPrivilege), 0u) << "the silent controller still has control";
}

// The GigE Vision transport-layer features a GenTL producer or vendor SDK
// reads, through an Aravis client; the MAC address in the discovery answer;
// frame timestamps on the clock GevTimestampControlLatch reads.
TEST_F(GigeE2E, TransportLayerFeaturesDescribeTheDeviceAndItsClock) {
  ASSERT_NO_FATAL_FAILURE(StartWith(SmallDevice()));
  Client& c = *client_;
  ArvDevice* dev = c.device();
  GError* e = nullptr;
  const auto get = [&](const char* name) {
    const int64_t v = arv_device_get_integer_feature_value(dev, name, &e);
    EXPECT_EQ(e, nullptr) << name << ": " << (e ? e->message : "");
    g_clear_error(&e);
    return v;
  };
  const auto execute = [&](const char* name) {
    arv_device_execute_command(dev, name, &e);
    EXPECT_EQ(e, nullptr) << name << ": " << (e ? e->message : "");
    g_clear_error(&e);
  };
  arv_device_set_integer_feature_value(dev, "GevHeartbeatTimeout", 10000, &e);
  EXPECT_EQ(e, nullptr) << (e ? e->message : "");
  g_clear_error(&e);
  EXPECT_EQ(get("GevHeartbeatTimeout"), 10000);
  EXPECT_EQ(get("GevVersionMajor"), 2);
  EXPECT_EQ(get("GevVersionMinor"), 0);
  EXPECT_TRUE(arv_device_get_boolean_feature_value(dev, "GevDeviceModeIsBigEndian", nullptr));
  EXPECT_EQ(get("GevCurrentIPAddress"), 0x7f000001);
  EXPECT_EQ(get("GevStreamChannelCount"), 1);
  EXPECT_EQ(get("GevTimestampTickFrequency"), 1000000000);
  EXPECT_EQ(arv_gv_device_get_timestamp_tick_frequency(ARV_GV_DEVICE(dev), nullptr), 1000000000u);
  arv_device_set_integer_feature_value(dev, "GevSCPD", 2000, &e);
  EXPECT_EQ(e, nullptr) << (e ? e->message : "");
  g_clear_error(&e);
  EXPECT_EQ(get("GevSCPD"), 2000);
  const int64_t mac = get("GevMACAddress");
  EXPECT_EQ(mac >> 40, 0x02);
  // The discovery answer carries the bootstrap's first bytes: the MAC at 0x0a..0x0f.
  RawController raw;
  std::vector<uint8_t> ack;
  ASSERT_TRUE(raw.Command(0x0002, {}, &ack)) << "discovery";
  ASSERT_GE(ack.size(), 8u + 0x10);
  int64_t announced = 0;
  for (int i = 0x0a; i < 0x10; ++i) announced = announced << 8 | ack[8 + i];
  EXPECT_EQ(announced, mac);
  // The latch: the host's real time (ns) until a reset, from 0 after one.
  const int64_t host = g_get_real_time() * 1000;
  execute("GevTimestampControlLatch");
  EXPECT_NEAR(static_cast<double>(get("GevTimestampValue")), static_cast<double>(host), 1e9);
  execute("GevTimestampControlReset");
  execute("GevTimestampControlLatch");
  const int64_t t0 = get("GevTimestampValue");
  EXPECT_LT(t0, 1000000000);
  // A frame's timestamp is on the same clock: between two latches.
  ASSERT_TRUE(c.OpenStream());
  Start(c);
  ASSERT_FALSE(c.Grab(5000).empty());
  execute("GevTimestampControlLatch");
  const int64_t t1 = get("GevTimestampValue");
  EXPECT_GT(static_cast<int64_t>(c.last_timestamp_ns()), t0);
  EXPECT_LE(static_cast<int64_t>(c.last_timestamp_ns()), t1);
  arv_camera_stop_acquisition(c.camera(), nullptr);
}

// Aravis 0.8.26's fake camera sums addresses in 32 bits and does not check a
// read past its GenICam XML: each access below made it copy gigabytes and
// crash the camera. genicam/fake_camera_hooks.cc checks the range.
TEST_F(GigeE2E, AccessesOutsideTheMemoryMapLeaveTheCameraServing) {
  device_ = StartDevice(SmallDevice());
  ASSERT_NE(device_, nullptr);
  std::ifstream file(device_->xml_path(), std::ios::binary);
  const std::string xml((std::istreambuf_iterator<char>(file)), std::istreambuf_iterator<char>());
  ASSERT_FALSE(xml.empty());
  const uint32_t xml_start = ARV_FAKE_CAMERA_MEMORY_SIZE, end = xml_start + static_cast<uint32_t>(xml.size());

  // GVCP status codes (GigE Vision 2.x, table 19-1).
  constexpr uint16_t kSuccess = 0, kInvalidParameter = 0x8002, kInvalidAddress = 0x8003, kWriteProtect = 0x8004,
                     kBadAlignment = 0x8005;
  RawController raw;
  ASSERT_TRUE(raw.Write(kControlChannelPrivilege, 2));
  EXPECT_EQ(raw.status(), kSuccess);
  // Each refused write counts once, whether the hooks refused it or the
  // device's filter; refused reads do not.
  uint64_t refused = 0;
  const auto counted = [&] { return device_->writes_refused() == refused; };
  uint32_t value = 0;
  EXPECT_TRUE(raw.Read(0x20000 + static_cast<uint32_t>(xml.size()), &value));  // past the XML
  EXPECT_EQ(raw.status(), kInvalidAddress);
  EXPECT_TRUE(raw.Read(0xFFFFFFFCu, &value));  // address + 4 wraps to 0
  EXPECT_EQ(raw.status(), kInvalidAddress);
  std::vector<uint8_t> block;
  EXPECT_FALSE(raw.ReadMemory(0xFFFFFFF0u, 32, &block));  // an error acknowledgement carries no data
  EXPECT_EQ(raw.status(), kInvalidAddress);
  // A block that runs past the XML's end: its last bytes, then zeros.
  const uint32_t last = (end - 2) & ~3u;
  ASSERT_TRUE(raw.ReadMemory(last, 8, &block));
  EXPECT_EQ(raw.status(), kSuccess);
  std::vector<uint8_t> expected(xml.begin() + (last - xml_start), xml.end());
  expected.resize(8, 0);
  EXPECT_EQ(block, expected);
  // The first bytes of the XML, read as a register.
  ASSERT_TRUE(raw.Read(xml_start, &value));
  EXPECT_EQ(raw.status(), kSuccess);
  EXPECT_EQ(value, uint32_t{uint8_t(xml[0])} << 24 | uint32_t{uint8_t(xml[1])} << 16 |
                       uint32_t{uint8_t(xml[2])} << 8 | uint8_t(xml[3]));

  EXPECT_TRUE(counted()) << "reads are not writes";
  uint32_t width = 0;
  ASSERT_TRUE(raw.Read(reg::kWidth, &width));
  EXPECT_TRUE(raw.Write(0xFFFFFFFCu, 1));  // address + 4 wraps to 0
  EXPECT_EQ(raw.status(), kInvalidAddress);
  ++refused;
  EXPECT_TRUE(counted());
  EXPECT_TRUE(raw.WriteMemory(0xFFFFFFF8u, std::vector<uint8_t>(16, 0xff), 20));
  EXPECT_EQ(raw.status(), kInvalidAddress);
  ++refused;
  EXPECT_TRUE(counted());
  // A length field below 4 leaves a data length of about 4 GiB.
  EXPECT_TRUE(raw.WriteMemory(reg::kWidth, {0, 0, 0, 2}, 2));
  EXPECT_EQ(raw.status(), kInvalidParameter);
  ++refused;
  EXPECT_TRUE(counted());
  EXPECT_TRUE(raw.WriteMemory(xml_start, {'x', 'x', 'x', 'x'}, 8));  // the XML is read-only
  EXPECT_EQ(raw.status(), kWriteProtect);
  ++refused;
  EXPECT_TRUE(counted());
  uint32_t scenes = 0;
  ASSERT_TRUE(raw.Read(reg::kSimSceneCount, &scenes));
  EXPECT_TRUE(raw.Write(reg::kSimSceneCount, scenes + 7));  // so is a read-only feature (the device's refusal)
  EXPECT_EQ(raw.status(), kWriteProtect);
  ++refused;
  EXPECT_TRUE(counted());
  ASSERT_TRUE(raw.Read(reg::kSimSceneCount, &value));
  EXPECT_EQ(value, scenes);
  EXPECT_TRUE(raw.WriteMemory(reg::kWidth + 2, {0, 0, 0, 2}, 8));  // half of two registers
  EXPECT_EQ(raw.status(), kBadAlignment);
  ++refused;
  EXPECT_TRUE(counted());
  EXPECT_TRUE(raw.WriteMemory(reg::kWidth, std::vector<uint8_t>(540, 0), 544));  // over GVCP's 536 bytes
  EXPECT_EQ(raw.status(), kInvalidParameter);
  ++refused;
  EXPECT_TRUE(counted());
  ASSERT_TRUE(raw.Read(reg::kWidth, &value));
  EXPECT_EQ(value, width);
  // A length field far beyond the packet: the fake camera would copy what
  // its 64 KiB receive buffer held before (and 7 bytes past it) over the
  // registers (the bootstrap's XML URL at 0x200, control, stream).
  std::vector<uint8_t> url_before, url_after;
  ASSERT_TRUE(raw.ReadMemory(0x200, 64, &url_before));
  EXPECT_TRUE(raw.WriteMemory(0, {1, 2, 3, 4}, 0xffff));
  EXPECT_EQ(raw.status(), kInvalidParameter);
  ++refused;
  EXPECT_TRUE(counted());
  ASSERT_TRUE(raw.ReadMemory(0x200, 64, &url_after));
  EXPECT_EQ(url_after, url_before);
  ASSERT_TRUE(raw.Read(kControlChannelPrivilege, &value));
  EXPECT_EQ(value, 2u);
  ASSERT_TRUE(raw.Read(xml_start, &value));
  EXPECT_NE(value, 0x78787878u);
  value = 0;
  ASSERT_TRUE(raw.Read(reg::kWidth, &value));
  EXPECT_EQ(value, width);
  // Malformed packets: the fake camera parses each one from its receive
  // buffer, so what a packet lacks would be the previous packet's bytes.
  uint32_t height = 0;
  ASSERT_TRUE(raw.Read(reg::kHeight, &height));
  const auto be32 = [](uint32_t v) { return std::vector<uint8_t>{uint8_t(v >> 24), uint8_t(v >> 16), uint8_t(v >> 8), uint8_t(v)}; };
  // WRITEMEM claiming 8 bytes and carrying 4, after one whose Height would be stored with them.
  std::vector<uint8_t> window = be32(32), height24 = be32(24);
  window.insert(window.end(), height24.begin(), height24.end());
  ASSERT_TRUE(raw.WriteMemory(reg::kWidth, window, 12));  // Width 32, Height 24
  ASSERT_EQ(raw.status(), kSuccess);
  EXPECT_TRUE(raw.WriteMemory(reg::kWidth, be32(48), 12));
  EXPECT_EQ(raw.status(), kInvalidParameter);
  ++refused;
  EXPECT_TRUE(counted());
  ASSERT_TRUE(raw.Read(reg::kWidth, &value));
  EXPECT_EQ(value, 32u);
  // WRITEREG with an address and no value, after one whose value (24) would be taken.
  ASSERT_TRUE(raw.Write(reg::kHeight, 24));
  EXPECT_TRUE(raw.WriteWithoutValue(reg::kWidth));
  EXPECT_EQ(raw.status(), kInvalidParameter);
  ++refused;
  EXPECT_TRUE(counted());
  ASSERT_TRUE(raw.Read(reg::kWidth, &value));
  EXPECT_EQ(value, 32u);
  // The same without the acknowledge flag: refused, and not answered.
  EXPECT_FALSE(raw.SendRaw({0x42, 0x00, 0x00, 0x86, 0x00, 0x0c, 0x00, 0x60, 0, 0, 0x01, 0x00, 0, 0, 0, 48}, 300));
  ++refused;
  ASSERT_TRUE(raw.Read(reg::kWidth, &value));
  EXPECT_EQ(value, 32u);
  EXPECT_TRUE(counted());
  // A datagram shorter than a header: the last command (Width 32 again) would run.
  ASSERT_TRUE(raw.Write(reg::kWidth, 32));
  ASSERT_TRUE(device_->WriteMemory(reg::kWidth, be32(width).data(), 4));
  EXPECT_FALSE(raw.SendRaw({0x42}, 200)) << "a 1-byte datagram was answered";
  ASSERT_TRUE(raw.Read(reg::kWidth, &value));
  EXPECT_EQ(value, width);
  EXPECT_TRUE(counted()) << "no command, so no write: " << device_->writes_refused();
  ASSERT_TRUE(raw.Write(reg::kHeight, height));
  EXPECT_EQ(raw.status(), kSuccess);
  ASSERT_TRUE(raw.Write(kControlChannelPrivilege, 0));

  Client client;
  ASSERT_TRUE(client.ok()) << client.last_error;
  GError* error = nullptr;
  EXPECT_EQ(arv_camera_get_integer(client.camera(), "Width", &error), static_cast<gint64>(width));
  EXPECT_EQ(error, nullptr);
  g_clear_error(&error);
}

// What Aravis's fake camera leaves unanswered gets a camera's answer: a
// write from a client not in control is denied (the fake camera dropped it,
// so the client waited for its timeout and retried), a command it does not
// know is not implemented; PACKETRESEND and a packet without the
// acknowledge flag get no answer (GVCP).
TEST_F(GigeE2E, UnansweredCommandsGetACamerasAnswer) {
  device_ = StartDevice(SmallDevice());
  ASSERT_NE(device_, nullptr);
  constexpr uint16_t kNotImplemented = 0x8001, kAccessDenied = 0x8006;
  RawController owner, other;
  ASSERT_TRUE(owner.Write(kControlChannelPrivilege, 2));
  ASSERT_EQ(owner.status(), 0);
  ASSERT_TRUE(owner.Write(kHeartbeatTimeout, 30000));  // the owner sends no heartbeat
  uint32_t width = 0, value = 0;
  ASSERT_TRUE(other.Read(reg::kWidth, &width));  // reads are open to every client
  EXPECT_EQ(other.status(), 0);
  EXPECT_TRUE(other.Write(reg::kWidth, 32));
  EXPECT_EQ(other.status(), kAccessDenied);
  EXPECT_EQ(device_->writes_refused(), 1u) << "a write the fake camera dropped counts as refused";
  EXPECT_TRUE(other.WriteMemory(reg::kWidth, {0, 0, 0, 32}, 8));
  EXPECT_EQ(other.status(), kAccessDenied);
  EXPECT_TRUE(other.Write(kControlChannelPrivilege, 2));  // no takeover while the owner is alive
  EXPECT_EQ(other.status(), kAccessDenied);
  EXPECT_EQ(device_->writes_refused(), 3u);
  ASSERT_TRUE(owner.Read(reg::kWidth, &value));
  EXPECT_EQ(value, width);
  EXPECT_TRUE(other.Command(0x0100, std::vector<uint8_t>(12, 0), nullptr));  // ACTION_CMD
  EXPECT_EQ(other.status(), kNotImplemented);
  // PACKETRESEND (stream channel 0, block 1, packets 1..2), then a write
  // without the acknowledge flag: no answer to either.
  EXPECT_FALSE(other.SendRaw({0x42, 0x01, 0x00, 0x40, 0x00, 0x0c, 0x00, 0x70, 0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 2}, 300));
  EXPECT_FALSE(other.SendRaw({0x42, 0x00, 0x00, 0x82, 0x00, 0x08, 0x00, 0x71, 0, 0, 0x01, 0x00, 0, 0, 0, 32}, 300));
  ASSERT_TRUE(owner.Read(reg::kWidth, &value));
  EXPECT_EQ(value, width);
  EXPECT_EQ(device_->writes_refused(), 4u) << "the unacknowledged write too, not the ACTION_CMD or PACKETRESEND";
  // The owner's write without the acknowledge flag is taken, not refused
  // (the fake camera acknowledges it all the same).
  EXPECT_TRUE(owner.SendRaw({0x42, 0x00, 0x00, 0x82, 0x00, 0x08, 0x00, 0x72, 0, 0, 0x01, 0x00, 0, 0, 0, 32}, 300));
  ASSERT_TRUE(owner.Read(reg::kWidth, &value));
  EXPECT_EQ(value, 32u);
  EXPECT_EQ(device_->writes_refused(), 4u);
  ASSERT_TRUE(owner.Write(reg::kWidth, width));
  ASSERT_TRUE(owner.Write(kControlChannelPrivilege, 0));
  EXPECT_EQ(owner.status(), 0);
  // A camera started again at the same address counts from its own start.
  device_.reset();
  device_ = StartDevice(SmallDevice());
  ASSERT_NE(device_, nullptr);
  EXPECT_EQ(device_->writes_refused(), 0u);
  EXPECT_TRUE(other.Write(kControlChannelPrivilege, 2));  // the new camera has no controller
  EXPECT_EQ(other.status(), 0);
  ASSERT_TRUE(other.Write(kControlChannelPrivilege, 0));
  EXPECT_EQ(other.status(), 0);
  EXPECT_EQ(device_->writes_refused(), 0u);
}

// The fake camera's trigger register (0x30c) is the device's: the device
// writes 1 to ask the fake camera for a frame, and the fake camera writes 0
// as it takes the request. A client's 0 there passed the filter as that
// acknowledgement would, withdrew the frame asked for, and each queued
// trigger then answered one late. Now every client write to it is refused
// (invalid address, as the other registers only the device writes), even
// one that comes between a trigger and its frame, and each trigger gets its
// own frame.
TEST_F(GigeE2E, AClientCannotWithdrawTheFrameATriggerAskedFor) {
  device_ = StartDevice(SmallDevice());
  ASSERT_NE(device_, nullptr);
  constexpr uint16_t kInvalidAddress = 0x8003;
  RawController raw;
  ASSERT_TRUE(raw.Write(kControlChannelPrivilege, 2));
  ASSERT_TRUE(raw.Write(kHeartbeatTimeout, 30000));  // no heartbeats from this client
  ASSERT_TRUE(raw.Write(reg::kTriggerMode, 1));
  ASSERT_TRUE(raw.Write(reg::kTriggerSource, genicam::kSourceSoftware));
  ASSERT_TRUE(raw.Write(kStreamDestAddress, INADDR_LOOPBACK));
  ASSERT_TRUE(raw.Write(kStreamPort, raw.sink_port()));
  uint32_t syncs = 0, now = 0;  // trigger mode in use before the acquisition starts
  ASSERT_TRUE(raw.Read(reg::kSimSyncCount, &syncs));
  for (int i = 0; i < 1000 && raw.Read(reg::kSimSyncCount, &now) && now < syncs + 2; ++i) Sleep(1);
  ASSERT_GE(now, syncs + 2);
  ASSERT_TRUE(raw.Write(reg::kAcquisitionStart, 1));
  EXPECT_FALSE(raw.FrameArrives(300)) << "a frame without a trigger";
  uint32_t value = 1;
  ASSERT_TRUE(raw.Write(reg::kFakeTriggerSoftware, 0));
  EXPECT_EQ(raw.status(), kInvalidAddress);
  constexpr int kTriggers = 8;
  for (int i = 0; i < kTriggers; ++i) {
    // The 0 goes out right behind the trigger, before the fake camera takes
    // the device's request (it looks every millisecond) or after.
    raw.PostWrite(reg::kTriggerSoftware, 1);
    ASSERT_TRUE(raw.Write(reg::kFakeTriggerSoftware, 0));
    EXPECT_EQ(raw.status(), kInvalidAddress) << "trigger " << i;
    EXPECT_TRUE(raw.FrameArrives(3000)) << "no frame for trigger " << i;
  }
  EXPECT_FALSE(raw.FrameArrives(300)) << "more frames than triggers";
  EXPECT_EQ(device_->frames_sent(), static_cast<uint64_t>(kTriggers));
  EXPECT_EQ(device_->writes_refused(), static_cast<uint64_t>(kTriggers + 1));
  ASSERT_TRUE(raw.Read(reg::kFakeTriggerSoftware, &value));
  EXPECT_EQ(value, 0u) << "a request left in the trigger register";
  ASSERT_TRUE(raw.Write(reg::kAcquisitionStop, 1));
  ASSERT_TRUE(raw.Write(kControlChannelPrivilege, 0));
}

// A WRITEREG_ACK's data is 2 reserved bytes and an index: the number of
// registers written on success, the index (from 0) of the write that failed
// on an error (GigE Vision, WRITEREG_ACK). The fake camera writes the one
// register of a WRITEREG and answers index 1; a refused write kept that 1,
// saying the register was written. Each refusal now answers index 0: by the
// device's filter, by the hooks (outside the memory map), and for a client
// not in control.
TEST_F(GigeE2E, ARefusedWriteRegSaysNoRegisterWasWritten) {
  device_ = StartDevice(SmallDevice());
  ASSERT_NE(device_, nullptr);
  constexpr uint16_t kInvalidParameter = 0x8002, kInvalidAddress = 0x8003, kAccessDenied = 0x8006;
  RawController raw, other;
  ASSERT_TRUE(raw.Write(kControlChannelPrivilege, 2));
  ASSERT_TRUE(raw.Write(kHeartbeatTimeout, 30000));
  uint32_t width = 0;
  ASSERT_TRUE(raw.Read(reg::kWidth, &width));
  // The acknowledgement of WRITEREG `address` = `value` from `c`: its status
  // and index (kNoAck: none, or not 12 bytes with a data length of 4).
  const auto write_reg = [](RawController& c, uint32_t address, uint32_t value, uint16_t* status) -> uint32_t {
    std::vector<uint8_t> body, ack;
    for (uint32_t v : {address, value})
      for (int i = 0; i < 4; ++i) body.push_back(static_cast<uint8_t>(v >> (24 - 8 * i)));
    *status = RawController::kNoAck;
    if (!c.Command(0x82, body, &ack) || ack.size() != 12 || ack[4] != 0 || ack[5] != 4) return RawController::kNoAck;
    *status = c.status();
    return uint32_t{ack[8]} << 24 | uint32_t{ack[9]} << 16 | uint32_t{ack[10]} << 8 | ack[11];
  };
  uint16_t status = 0;
  EXPECT_EQ(write_reg(raw, reg::kWidth, 32, &status), 1u) << "one register written";
  EXPECT_EQ(status, 0);
  EXPECT_EQ(write_reg(raw, reg::kWidth, 99999, &status), 0u) << "refused by the filter";
  EXPECT_EQ(status, kInvalidParameter);
  EXPECT_EQ(write_reg(raw, reg::kFakeTriggerSoftware, 1, &status), 0u) << "a register only the device writes";
  EXPECT_EQ(status, kInvalidAddress);
  EXPECT_EQ(write_reg(raw, 0xFFFFFFFCu, 1, &status), 0u) << "refused by the hooks";
  EXPECT_EQ(status, kInvalidAddress);
  EXPECT_EQ(write_reg(other, reg::kWidth, 48, &status), 0u) << "a client not in control";
  EXPECT_EQ(status, kAccessDenied);
  uint32_t value = 0;
  ASSERT_TRUE(raw.Read(reg::kWidth, &value));
  EXPECT_EQ(value, 32u);
  EXPECT_EQ(write_reg(raw, reg::kWidth, width, &status), 1u);
  EXPECT_EQ(status, 0);
  ASSERT_TRUE(raw.Write(kControlChannelPrivilege, 0));
}

// GigE Vision limits a READMEM to 536 bytes of data (a 576-byte GVCP
// packet) and a device answers a longer one with INVALID_PARAMETER; the fake
// camera served any length up to 65535 (the XML in one read, in a datagram
// past UDP's limit at the top). 536 bytes are still served.
TEST_F(GigeE2E, AReadMemOverGvcpsLimitIsRefused) {
  device_ = StartDevice(SmallDevice());
  ASSERT_NE(device_, nullptr);
  constexpr uint16_t kInvalidParameter = 0x8002;
  const uint32_t xml_start = ARV_FAKE_CAMERA_MEMORY_SIZE;
  RawController raw;  // reads need no control
  std::vector<uint8_t> block;
  ASSERT_TRUE(raw.ReadMemory(xml_start, 536, &block));
  EXPECT_EQ(raw.status(), 0);
  EXPECT_EQ(block.size(), 536u);
  for (const uint16_t size : {540, 1024, 65532, 65535}) {
    std::vector<uint8_t> body, ack;
    for (uint32_t v : {xml_start, uint32_t{size}})
      for (int i = 0; i < 4; ++i) body.push_back(static_cast<uint8_t>(v >> (24 - 8 * i)));
    ASSERT_TRUE(raw.Command(0x84, body, &ack)) << size << " bytes: no acknowledgement";
    EXPECT_EQ(raw.status(), kInvalidParameter) << size << " bytes";
    // The error form: the header and the address read, no data.
    ASSERT_EQ(ack.size(), 12u) << size << " bytes";
    EXPECT_EQ(std::vector<uint8_t>(ack.begin() + 8, ack.end()), std::vector<uint8_t>(body.begin(), body.begin() + 4));
  }
  EXPECT_TRUE(raw.ReadMemory(xml_start, 512, &block)) << "the camera stopped serving";
  EXPECT_EQ(raw.status(), 0);
  EXPECT_EQ(device_->writes_refused(), 0u) << "reads are not writes";
}

// A PACKETRESEND the camera cannot answer gets a GVSP packet whose status
// says why (GigE Vision 2.0), so the receiver stops asking: for a frame
// older than the kResendFrames kept, PACKET_AND_PREV_REMOVED_FROM_MEMORY;
// for packet IDs past a frame's trailer, PACKET_UNAVAILABLE; for a frame
// not sent yet, PACKET_NOT_YET_AVAILABLE. Before, nothing came, and the
// receiver asked again until it gave the frame up.
TEST_F(GigeE2E, AResendTheCameraCannotAnswerSaysWhy) {
  device_ = StartDevice(SmallDevice(320, 240));
  ASSERT_NE(device_, nullptr);
  constexpr uint16_t kUnavailable = 0x800C, kNotYet = 0x8010, kRemoved = 0x8011;
  RawController raw;
  ASSERT_TRUE(raw.Write(kControlChannelPrivilege, 2));
  ASSERT_TRUE(raw.Write(kHeartbeatTimeout, 30000));  // no heartbeats from this client
  ASSERT_TRUE(raw.Write(reg::kWidth, 64));
  ASSERT_TRUE(raw.Write(reg::kHeight, 48));
  ASSERT_TRUE(raw.Write(kStreamDestAddress, INADDR_LOOPBACK));
  ASSERT_TRUE(raw.Write(kStreamPort, raw.sink_port()));
  ASSERT_TRUE(raw.Write(reg::kAcquisitionStart, 1));
  // Frames until the first whole one is more than kResendFrames behind.
  uint16_t first_block = 0, last_block = 0;
  uint32_t last_trailer_id = 0;
  constexpr int kBehind = static_cast<int>(genicam::kResendFrames) + 1;
  for (int i = 0; i < 1000 && (first_block == 0 || last_block - first_block < kBehind); ++i) {
    const std::vector<uint8_t> p = raw.NextStreamPacket(3000);
    ASSERT_GE(p.size(), genicam::kGvspHeaderBytes) << "the stream stopped";
    if ((p[4] & 0x0f) != 2) continue;  // trailers only: a frame sent whole
    last_block = static_cast<uint16_t>(p[2] << 8 | p[3]);
    last_trailer_id = uint32_t{p[5]} << 16 | uint32_t{p[6]} << 8 | p[7];
    if (first_block == 0) first_block = last_block;
  }
  ASSERT_GE(last_block - first_block, kBehind);
  ASSERT_TRUE(raw.Write(reg::kAcquisitionStop, 1));
  while (!raw.NextStreamPacket(300).empty()) {
  }
  // The answer to a resend of block, first..last: its status, block and packet ID.
  struct Answer {
    uint16_t status = 0xffff, block = 0;
    uint32_t id = 0;
    size_t bytes = 0;
  };
  const auto ask = [&](uint16_t block, uint32_t first, uint32_t last) {
    raw.AskResend(block, first, last);
    const std::vector<uint8_t> p = raw.NextStreamPacket(2000);
    Answer a;
    if (p.size() < genicam::kGvspHeaderBytes) return a;
    a.status = static_cast<uint16_t>(p[0] << 8 | p[1]);
    a.block = static_cast<uint16_t>(p[2] << 8 | p[3]);
    a.id = uint32_t{p[5]} << 16 | uint32_t{p[6]} << 8 | p[7];
    a.bytes = p.size();
    return a;
  };
  const uint64_t refused_before = genicam::ResendRequestsRefused();
  // The newest frame's packet 1 comes again, whole.
  Answer a = ask(last_block, 1, 1);
  EXPECT_EQ(a.status, 0u);
  EXPECT_EQ(a.block, last_block);
  EXPECT_EQ(a.id, 1u);
  EXPECT_GT(a.bytes, genicam::kGvspHeaderBytes);
  a = ask(first_block, 1, 3);
  EXPECT_EQ(a.status, kRemoved) << "a frame older than the ones kept";
  EXPECT_EQ(a.block, first_block);
  EXPECT_EQ(a.id, 1u);
  EXPECT_EQ(a.bytes, genicam::kGvspHeaderBytes);
  a = ask(last_block, last_trailer_id + 1, last_trailer_id + 5);
  EXPECT_EQ(a.status, kUnavailable) << "packets past the trailer";
  EXPECT_EQ(a.id, last_trailer_id + 1);
  a = ask(static_cast<uint16_t>(last_block + 2), 1, 1);
  EXPECT_EQ(a.status, kNotYet) << "a frame not sent yet";
  EXPECT_EQ(a.block, static_cast<uint16_t>(last_block + 2));
  EXPECT_EQ(genicam::ResendRequestsRefused() - refused_before, 3u);
  ASSERT_TRUE(raw.Write(kControlChannelPrivilege, 0));
}

TEST_F(GigeE2E, RoiExposureAndGainTakeEffect) {
  ASSERT_NO_FATAL_FAILURE(StartWith(SmallDevice()));
  Client& c = *client_;
  GError* e = nullptr;
  arv_camera_set_region(c.camera(), 8, 4, 32, 24, &e);
  ASSERT_EQ(e, nullptr);
  Settle();
  EXPECT_EQ(ReadInt(c, "PayloadSize"), 32 * 24 * 2);
  SetInt(c, "SimFrameIndex", 0);
  Settle();
  ASSERT_TRUE(c.OpenStream());
  Start(c);
  uint64_t id = 0;
  int width = 0;
  auto f = c.Grab(3000, &id, &width);
  const uint32_t code = genicam::BayerCode(Cfa::kBayerRG, 12);
  EXPECT_EQ(width, 32);
  EXPECT_TRUE(f == Reference(0, code, 8, 4, 32, 24));
  // While acquiring: new exposure and gain apply from the next frame on.
  const uint64_t first_id = id;
  SetFloat(c, "ExposureTime", 4000.0);
  SetFloat(c, "Gain", 6.0);
  const std::vector<std::string> changed = {"exposure.exposure_time_us=4000.0", "sensor.gain_db=6.0"};
  const std::vector<std::string> exposure_only = {"exposure.exposure_time_us=4000.0"};
  bool switched = false;
  int old_after_write = 0;
  // Comparing with three references per frame is slower than the stream:
  // frames the client had no buffer for are dropped; the index follows the id.
  int good = 0;
  for (int i = 0; i < 16 && good < 6; ++i) {
    f = c.Grab(3000, &id);
    if (f.empty()) continue;
    ++good;
    const uint32_t index = static_cast<uint32_t>(id - first_id);
    const bool is_new = f == Reference(index, code, 8, 4, 32, 24, changed);
    const bool is_old = f == Reference(index, code, 8, 4, 32, 24);
    // The two writes may reach the device in different syncs.
    const bool is_between = f == Reference(index, code, 8, 4, 32, 24, exposure_only);
    ASSERT_TRUE(is_new || is_old || is_between) << "frame " << index << " matches no setting";
    if (switched) {
      EXPECT_TRUE(is_new) << "frame " << index << " went back to the old settings";
    }
    if (is_new) {
      switched = true;
    } else {
      ++old_after_write;
    }
  }
  EXPECT_EQ(good, 6);
  EXPECT_TRUE(switched);
  // Old frames: those already in the client's 4 buffers or being rendered
  // when the write landed; no more.
  EXPECT_LE(old_after_write, 4 + 1) << "old settings after the write was applied";
}

// The payload's features say they are locked (pIsLocked) exactly when the
// device refuses their writes: while TLParamsLocked is 1 and while acquiring.
TEST_F(GigeE2E, PayloadFeaturesReadLockedWhenWritesAreRefused) {
  ASSERT_NO_FATAL_FAILURE(StartWith(SmallDevice()));
  Client& c = *client_;
  ArvDevice* device = arv_camera_get_device(c.camera());
  auto locked = [&](const char* name) {
    ArvGcNode* node = arv_device_get_feature(device, name);
    EXPECT_NE(node, nullptr) << name;
    GError* e = nullptr;
    const bool is = node != nullptr && arv_gc_feature_node_is_locked(ARV_GC_FEATURE_NODE(node), &e);
    EXPECT_EQ(e, nullptr) << name;
    return is;
  };
  const char* payload[] = {"Width", "Height", "OffsetX", "OffsetY", "PixelFormat"};
  for (const char* f : payload) EXPECT_FALSE(locked(f)) << f;
  SetInt(c, "TLParamsLocked", 1);
  for (const char* f : payload) EXPECT_TRUE(locked(f)) << f << " with TLParamsLocked";
  EXPECT_FALSE(locked("ExposureTime"));
  SetInt(c, "TLParamsLocked", 0);
  for (const char* f : payload) EXPECT_FALSE(locked(f)) << f;
  ASSERT_TRUE(c.OpenStream());
  Start(c);
  for (const char* f : payload) EXPECT_TRUE(locked(f)) << f << " while acquiring";
  GError* e = nullptr;
  arv_camera_stop_acquisition(c.camera(), &e);
  ASSERT_EQ(e, nullptr);
  c.CloseStream();
  for (const char* f : payload) EXPECT_FALSE(locked(f)) << f << " after the stop";
}

// GigE Vision chunk mode: each frame's image as a chunk, then the enabled
// chunks (the settings it was rendered with), read by Aravis's chunk parser
// from the XML's chunk ports. Packet sizes put the chunks inside the last
// image packet, across two packets, and after a full last image packet.
TEST_F(GigeE2E, ChunksCarryEachFramesSettings) {
  ASSERT_NO_FATAL_FAILURE(StartWith(SmallDevice()));
  Client& c = *client_;
  constexpr int64_t kImage = 64 * 48 * 2;  // BayerRG12
  EXPECT_EQ(ReadInt(c, "PayloadSize"), kImage);
  GError* e = nullptr;
  arv_camera_set_boolean(c.camera(), "ChunkModeActive", TRUE, &e);
  ASSERT_EQ(e, nullptr);
  EXPECT_EQ(ReadInt(c, "PayloadSize"), kImage + 8 + 12 * 16) << "every chunk (12) is on by default";
  SetFloat(c, "ExposureTime", 4000.0);
  SetFloat(c, "Gain", 2.5);
  const std::vector<std::string> kSettings = {"exposure.exposure_time_us=4000", "sensor.gain_db=2.5"};
  ArvChunkParser* parser = arv_camera_create_chunk_parser(c.camera());
  ASSERT_NE(parser, nullptr);
  // 6144 image bytes in packets of 1364 (chunks in the 5th packet), 1028 (the
  // 6th packet has room for 24 of their 88 bytes) and 1024 (6 full packets).
  uint32_t index = 7;
  for (const int data_bytes : {1364, 1028, 1024}) {
    SCOPED_TRACE(data_bytes);
    SetInt(c, "GevSCPSPacketSize", data_bytes + static_cast<int>(genicam::kGvspOverheadBytes));
    SetInt(c, "SimFrameIndex", index);
    Settle();
    ASSERT_TRUE(c.OpenStream()) << c.last_error;
    Start(c);
    const ChunkedFrame f0 = GrabChunked(c, parser), f1 = GrabChunked(c, parser);
    c.CloseStream();
    for (const ChunkedFrame* f : {&f0, &f1}) {
      ASSERT_TRUE(f->ok);
      ASSERT_TRUE(f->has_chunks);
      const uint32_t i = f == &f0 ? index : index + 1;
      EXPECT_TRUE(f->image == Reference(i, genicam::BayerCode(Cfa::kBayerRG, 12), 0, 0, 64, 48, kSettings))
          << "frame " << i;
      EXPECT_TRUE(f->missing.empty()) << f->missing.front();
      EXPECT_EQ(f->values.at("ChunkSimFrameIndex"), i);
      EXPECT_EQ(f->values.at("ChunkFrameID"), static_cast<double>(f->frame_id));
      EXPECT_EQ(f->timestamp_chunk, f->timestamp);
      EXPECT_EQ(f->values.at("ChunkExposureTime"), 4000.0);
      EXPECT_EQ(f->values.at("ChunkGain"), 2.5);
      EXPECT_EQ(f->values.at("ChunkWidth"), 64);
      EXPECT_EQ(f->values.at("ChunkHeight"), 48);
      EXPECT_EQ(f->pixel_format, "BayerRG12");
      EXPECT_EQ(f->values.at("ChunkBlackLevel"), ReadFloat(c, "BlackLevel"));
      EXPECT_EQ(f->values.at("ChunkLineStatusAll"), 0) << "no trigger edge, no strobe";
    }
    index += 10;
  }
  // A chunk switched off is not sent; the payload shrinks by its 16 bytes.
  Set(c, "ChunkSelector", "Gain");
  arv_camera_set_boolean(c.camera(), "ChunkEnable", FALSE, &e);
  ASSERT_EQ(e, nullptr);
  EXPECT_EQ(ReadInt(c, "PayloadSize"), kImage + 8 + 11 * 16);
  ASSERT_TRUE(c.OpenStream());
  Start(c);
  ChunkedFrame f = GrabChunked(c, parser);
  ASSERT_TRUE(f.ok);
  EXPECT_EQ(f.missing, std::vector<std::string>{"ChunkGain"});
  EXPECT_EQ(f.values.count("ChunkExposureTime"), 1u);
  // The payload's layout is frozen while acquiring.
  arv_camera_set_boolean(c.camera(), "ChunkModeActive", FALSE, &e);
  EXPECT_TRUE(g_error_matches(e, ARV_DEVICE_ERROR, ARV_DEVICE_ERROR_PROTOCOL_ERROR_ACCESS_DENIED))
      << (e != nullptr ? e->message : "no error");
  g_clear_error(&e);
  Set(c, "ChunkSelector", "Timestamp");
  arv_camera_set_boolean(c.camera(), "ChunkEnable", FALSE, &e);
  EXPECT_TRUE(g_error_matches(e, ARV_DEVICE_ERROR, ARV_DEVICE_ERROR_PROTOCOL_ERROR_ACCESS_DENIED))
      << (e != nullptr ? e->message : "no error");
  g_clear_error(&e);
  c.CloseStream();
  // Chunk mode off: the image alone, as before.
  arv_camera_set_boolean(c.camera(), "ChunkModeActive", FALSE, &e);
  ASSERT_EQ(e, nullptr);
  EXPECT_EQ(ReadInt(c, "PayloadSize"), kImage);
  SetInt(c, "SimFrameIndex", 3);
  Settle();
  ASSERT_TRUE(c.OpenStream());
  Start(c);
  f = GrabChunked(c, parser);
  c.CloseStream();
  ASSERT_TRUE(f.ok);
  EXPECT_FALSE(f.has_chunks);
  EXPECT_TRUE(f.image == Reference(3, genicam::BayerCode(Cfa::kBayerRG, 12), 0, 0, 64, 48, kSettings));
  g_object_unref(parser);
  EXPECT_EQ(c.failed_buffers(), 0u);
}

// An image whose size is not a whole number of 4-byte words (Mono8, 31 x 23)
// is padded in its chunk, and PayloadSize counts the padding.
TEST_F(GigeE2E, AnOddImageIsPaddedInItsChunk) {
  ASSERT_NO_FATAL_FAILURE(StartWith(SmallMonoDevice()));
  Client& c = *client_;
  GError* e = nullptr;
  arv_camera_set_region(c.camera(), 1, 0, 31, 23, &e);
  ASSERT_EQ(e, nullptr);
  Set(c, "PixelFormat", "Mono8");
  EXPECT_EQ(ReadInt(c, "PayloadSize"), 31 * 23);
  arv_camera_set_boolean(c.camera(), "ChunkModeActive", TRUE, &e);
  ASSERT_EQ(e, nullptr);
  EXPECT_EQ(ReadInt(c, "PayloadSize"), 31 * 23 + 3 + 8 + 12 * 16);
  SetInt(c, "SimFrameIndex", 5);
  Settle();
  ArvChunkParser* parser = arv_camera_create_chunk_parser(c.camera());
  ASSERT_TRUE(c.OpenStream());
  Start(c);
  const ChunkedFrame f = GrabChunked(c, parser);
  c.CloseStream();
  g_object_unref(parser);
  ASSERT_TRUE(f.ok);
  std::vector<uint8_t> want = Reference(5, genicam::kMono8, 1, 0, 31, 23);
  want.resize(want.size() + 3, 0);
  EXPECT_TRUE(f.image == want);
  EXPECT_EQ(f.values.at("ChunkSimFrameIndex"), 5);
  // The frame's own window and format.
  EXPECT_EQ(f.values.at("ChunkOffsetX"), 1);
  EXPECT_EQ(f.values.at("ChunkOffsetY"), 0);
  EXPECT_EQ(f.values.at("ChunkWidth"), 31);
  EXPECT_EQ(f.values.at("ChunkHeight"), 23);
  EXPECT_EQ(f.pixel_format, "Mono8");
}

// Over the network: a window written while streaming is refused as it
// arrives, so every frame keeps the window in use (until 2026-11-27 the fake
// camera's stream could take the refused size before the sync restored it);
// stop, a new window and start sent at once (inside one register sync) take
// the new window.
TEST_F(GigeE2E, TheWindowChangesBetweenAcquisitionsAndNotDuringOne) {
  ASSERT_NO_FATAL_FAILURE(StartWith(SmallDevice()));
  Client& c = *client_;
  ASSERT_TRUE(c.OpenStream());
  Start(c);
  int width = 0;
  EXPECT_FALSE(c.Grab(3000, nullptr, &width).empty());
  EXPECT_EQ(width, 64);
  GError* e = nullptr;
  arv_camera_set_integer(c.camera(), "Width", 32, &e);  // refused: access denied
  EXPECT_TRUE(g_error_matches(e, ARV_DEVICE_ERROR, ARV_DEVICE_ERROR_PROTOCOL_ERROR_ACCESS_DENIED))
      << (e != nullptr ? e->message : "no error");
  g_clear_error(&e);
  EXPECT_EQ(ReadInt(c, "Width"), 64);
  EXPECT_EQ(device_->writes_refused(), 1u);
  for (int i = 0; i < 3; ++i) {
    const std::vector<uint8_t> f = c.Grab(3000, nullptr, &width);
    EXPECT_EQ(f.size(), 64u * 48 * 2);
    EXPECT_EQ(width, 64);
  }
  arv_camera_stop_acquisition(c.camera(), &e);
  ASSERT_EQ(e, nullptr);
  arv_camera_set_region(c.camera(), 8, 4, 32, 24, &e);
  ASSERT_EQ(e, nullptr);
  Start(c);
  EXPECT_EQ(device_->writes_refused(), 1u);
  EXPECT_EQ(ReadInt(c, "Width"), 32);
  // Frames of the first acquisition may still be queued: the next ones have the new window.
  bool arrived = false;
  for (int i = 0; i < 8 && !arrived; ++i) {
    const std::vector<uint8_t> f = c.Grab(3000, nullptr, &width);
    if (width == 32) {
      arrived = true;
      EXPECT_EQ(f.size(), 32u * 24 * 2);
    }
  }
  EXPECT_TRUE(arrived);
  EXPECT_EQ(device_->CheckInvariants(), "");
}

// A write of the window during acquisition is refused for the lock, whatever
// its value: OffsetX = 2 at full width would also leave the sensor, and used
// to say invalid parameter (the window check ran first). The device's stderr
// says which and why.
TEST_F(GigeE2E, AWindowWriteWhileAcquiringIsDeniedForTheLock) {
  ASSERT_NO_FATAL_FAILURE(StartWith(SmallDevice()));
  Client& c = *client_;
  ASSERT_TRUE(c.OpenStream());
  Start(c);
  EXPECT_FALSE(c.Grab(3000).empty());
  testing::internal::CaptureStderr();
  GError* e = nullptr;
  arv_camera_set_integer(c.camera(), "OffsetX", 2, &e);
  const std::string err = testing::internal::GetCapturedStderr();
  EXPECT_TRUE(g_error_matches(e, ARV_DEVICE_ERROR, ARV_DEVICE_ERROR_PROTOCOL_ERROR_ACCESS_DENIED))
      << (e != nullptr ? e->message : "no error");
  g_clear_error(&e);
  EXPECT_NE(err.find("camsim-gige: refused OffsetX = 2: acquisition running"), std::string::npos) << err;
  EXPECT_EQ(err.find("window off the sensor"), std::string::npos) << err;
  EXPECT_EQ(ReadInt(c, "OffsetX"), 0);
}

// GVSP block IDs (and ChunkFrameID) start at 1 on each stream a client
// opens and count on across its acquisitions; they used to be the fake
// camera's counter, from 65400 on, across acquisitions and clients.
TEST_F(GigeE2E, BlockIdsStartAtOneOnEachStream) {
  ASSERT_NO_FATAL_FAILURE(StartWith(SmallDevice()));
  for (int round = 0; round < 2; ++round) {
    if (round == 1) {  // a new client, after the first let go
      client_.reset();
      client_ = std::make_unique<Client>("127.0.0.1");
      ASSERT_TRUE(client_->ok()) << client_->last_error;
      g_client = client_.get();
    }
    Client& c = *client_;
    GError* e = nullptr;
    arv_camera_set_boolean(c.camera(), "ChunkModeActive", TRUE, &e);
    ASSERT_EQ(e, nullptr);
    ArvChunkParser* parser = arv_camera_create_chunk_parser(c.camera());
    ASSERT_TRUE(c.OpenStream());
    Start(c);
    for (uint64_t id = 1; id <= 3; ++id) {
      ChunkedFrame f = GrabChunked(c, parser);
      ASSERT_TRUE(f.ok) << round << " " << id;
      EXPECT_EQ(f.frame_id, id) << "round " << round;
      EXPECT_EQ(f.values.at("ChunkFrameID"), static_cast<double>(id)) << "round " << round;
    }
    arv_camera_stop_acquisition(c.camera(), &e);
    ASSERT_EQ(e, nullptr);
    g_object_unref(parser);
    c.CloseStream();
  }
}

TEST_F(GigeE2E, OutOfRangeWritesAreRefusedAndTheDeviceKeepsServing) {
  ASSERT_NO_FATAL_FAILURE(StartWith(SmallDevice()));
  Client& c = *client_;
  ArvDevice* dev = c.device();
  // Aravis's default range-check policy is off, so these reach the device,
  // which refuses each as it arrives: the client gets GVCP's invalid parameter.
  GError* e = nullptr;
  const auto refused = [&e](const char* what) {
    EXPECT_TRUE(g_error_matches(e, ARV_DEVICE_ERROR, ARV_DEVICE_ERROR_PROTOCOL_ERROR_INVALID_PARAMETER))
        << what << ": " << (e != nullptr ? e->message : "no error");
    g_clear_error(&e);
  };
  arv_camera_set_float(c.camera(), "ExposureTime", 2e8, &e);
  refused("ExposureTime");
  arv_camera_set_float(c.camera(), "Gain", -3.0, &e);
  refused("Gain");
  arv_camera_set_integer(c.camera(), "Width", 1000, &e);
  refused("Width");
  arv_camera_set_integer(c.camera(), "OffsetX", 3, &e);  // off the Bayer increment
  refused("OffsetX");
  arv_device_write_register(dev, reg::kPixelFormat, 0x12345, &e);
  refused("PixelFormat");
  arv_device_write_register(dev, reg::kAcquisitionMode, 9, &e);
  refused("AcquisitionMode");
  uint8_t nan_bytes[8] = {0x7f, 0xf8, 0, 0, 0, 0, 0, 0};  // big-endian quiet NaN
  arv_device_write_memory(dev, reg::kBlackLevel, 8, nan_bytes, &e);
  refused("BlackLevel");
  EXPECT_EQ(device_->writes_refused(), 7u);
  EXPECT_DOUBLE_EQ(ReadFloat(c, "ExposureTime"), 10000.0);
  EXPECT_DOUBLE_EQ(ReadFloat(c, "Gain"), 0.0);
  EXPECT_EQ(ReadInt(c, "Width"), 64);
  EXPECT_EQ(ReadInt(c, "OffsetX"), 0);
  EXPECT_STREQ(arv_camera_get_pixel_format_as_string(c.camera(), nullptr), "BayerRG12");
  EXPECT_STREQ(arv_camera_get_string(c.camera(), "AcquisitionMode", nullptr), "Continuous");
  EXPECT_DOUBLE_EQ(ReadFloat(c, "BlackLevel"), 64.0);
  // An offset that fits alone but not with the width.
  SetInt(c, "Width", 48);
  arv_camera_set_integer(c.camera(), "OffsetX", 32, &e);
  refused("OffsetX 32 with Width 48");
  EXPECT_EQ(ReadInt(c, "Width"), 48);
  EXPECT_EQ(ReadInt(c, "OffsetX"), 0);
  SetInt(c, "Width", 64);
  EXPECT_EQ(device_->writes_refused(), 8u);
  // With Aravis's range checks on, the XML's limits refuse on the client already.
  arv_camera_set_range_check_policy(c.camera(), ARV_RANGE_CHECK_POLICY_ENABLE);
  arv_camera_set_float(c.camera(), "ExposureTime", 2e8, &e);
  EXPECT_NE(e, nullptr);
  g_clear_error(&e);
  arv_camera_set_range_check_policy(c.camera(), ARV_RANGE_CHECK_POLICY_DISABLE);
  // Still serving correct frames; geometry is frozen while acquiring.
  SetInt(c, "SimFrameIndex", 2);
  Settle();
  ASSERT_TRUE(c.OpenStream());
  Start(c);
  const auto f = c.Grab(3000);
  EXPECT_TRUE(f == Reference(2, genicam::BayerCode(Cfa::kBayerRG, 12), 0, 0, 64, 48));
  arv_camera_set_integer(c.camera(), "Width", 32, &e);
  EXPECT_TRUE(g_error_matches(e, ARV_DEVICE_ERROR, ARV_DEVICE_ERROR_PROTOCOL_ERROR_ACCESS_DENIED))
      << (e != nullptr ? e->message : "no error");
  g_clear_error(&e);
  EXPECT_EQ(ReadInt(c, "Width"), 64);
  EXPECT_FALSE(c.Grab(3000).empty());
}

// SFNC: Width's maximum is WidthMax - OffsetX and OffsetX's WidthMax - Width
// (pMax), so a client can order its writes by the limits it reads; the XML
// used to give the sensor's size for both, and a write past it was refused
// by the sync without the client knowing.
TEST_F(GigeE2E, WindowMaximaLeaveRoomForTheOtherFeature) {
  ASSERT_NO_FATAL_FAILURE(StartWith(SmallDevice()));
  Client& c = *client_;
  const auto max_of = [&c](const char* name) {
    gint64 min = 0, max = 0;
    GError* e = nullptr;
    arv_camera_get_integer_bounds(c.camera(), name, &min, &max, &e);
    EXPECT_EQ(e, nullptr) << name;
    g_clear_error(&e);
    return max;
  };
  EXPECT_EQ(max_of("Width"), 64);
  EXPECT_EQ(max_of("OffsetX"), 0);  // the window is the whole sensor
  SetInt(c, "Width", 32);
  Settle();
  EXPECT_EQ(max_of("OffsetX"), 32);
  SetInt(c, "OffsetX", 16);
  SetInt(c, "Height", 16);
  Settle();
  EXPECT_EQ(max_of("Width"), 48);
  EXPECT_EQ(max_of("OffsetY"), 32);
  EXPECT_EQ(max_of("Height"), 48);
  // With Aravis's range checks on, a width past the room left is refused on the client.
  arv_camera_set_range_check_policy(c.camera(), ARV_RANGE_CHECK_POLICY_ENABLE);
  GError* e = nullptr;
  arv_camera_set_integer(c.camera(), "Width", 64, &e);
  EXPECT_NE(e, nullptr);
  g_clear_error(&e);
  arv_camera_set_range_check_policy(c.camera(), ARV_RANGE_CHECK_POLICY_DISABLE);
  EXPECT_EQ(ReadInt(c, "Width"), 32);
}

TEST_F(GigeE2E, SingleAndMultiFrameModesStopByThemselves) {
  ASSERT_NO_FATAL_FAILURE(StartWith(SmallDevice()));
  Client& c = *client_;
  SetFloat(c, "AcquisitionFrameRate", 100.0);
  Set(c, "AcquisitionMode", "MultiFrame");
  SetInt(c, "AcquisitionFrameCount", 3);
  ASSERT_TRUE(c.OpenStream(8));
  Start(c);
  // A stream's first frame may come late on a loaded machine: 3 s for it,
  // then 500 ms for each further one.
  ASSERT_FALSE(c.Grab(3000).empty());
  int frames = 1;
  while (!c.Grab(500).empty()) ++frames;
  EXPECT_EQ(frames, 3);
  c.CloseStream();
  Set(c, "AcquisitionMode", "SingleFrame");
  Settle();
  ASSERT_TRUE(c.OpenStream(8));
  Start(c);
  ASSERT_FALSE(c.Grab(3000).empty());
  frames = 1;
  while (!c.Grab(500).empty()) ++frames;
  EXPECT_EQ(frames, 1);
}

// Frames of the stream whose timestamp is at or after `since_ns` (the
// camera's clock: real time): popped until `expected` have come (up to 3 s,
// so a loaded machine's late frames still count), then for `quiet_ms` more
// (where any extra one would come).
int FramesSince(Client& c, uint64_t since_ns, int expected, int quiet_ms) {
  int n = 0;
  const auto pop = [&] {
    if (!c.Grab(50).empty() && c.last_timestamp_ns() >= since_ns) ++n;
  };
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(3);
  while (n < expected && std::chrono::steady_clock::now() < deadline) pop();
  const auto end = std::chrono::steady_clock::now() + std::chrono::milliseconds(quiet_ms);
  while (std::chrono::steady_clock::now() < end) pop();
  return n;
}

// A client's stop and next start inside one register sync (Aravis sends
// them well under 2 ms apart) start a new acquisition: no free-run frame of
// the old one comes after a switch to trigger mode, and a MultiFrame count
// starts again. (The sync used to be what ended an acquisition, so the old
// one's free-run request gave a frame without a trigger, and the new
// acquisition went on with the old count.)
TEST_F(GigeE2E, AStopAndAStartInOneSyncPeriodStartAfresh) {
  ASSERT_NO_FATAL_FAILURE(StartWith(SmallDevice()));
  Client& c = *client_;
  GError* e = nullptr;
  arv_camera_set_boolean(c.camera(), "AcquisitionFrameRateEnable", FALSE, &e);  // a free-run request always pending
  ASSERT_EQ(e, nullptr);
  Settle();
  ASSERT_TRUE(c.OpenStream(16));
  for (int trial = 0; trial < 4; ++trial) {
    SCOPED_TRACE(trial);
    Set(c, "TriggerMode", "Off");
    Start(c);
    ASSERT_FALSE(c.Grab(3000).empty());
    ASSERT_FALSE(c.Grab(3000).empty());
    arv_camera_stop_acquisition(c.camera(), &e);
    ASSERT_EQ(e, nullptr);
    Set(c, "TriggerMode", "On");
    Set(c, "TriggerSource", "Software");
    const uint64_t t0 = static_cast<uint64_t>(g_get_real_time()) * 1000;
    Start(c);
    EXPECT_EQ(FramesSince(c, t0, 0, 300), 0) << "a frame without a trigger";
    arv_camera_execute_command(c.camera(), "TriggerSoftware", &e);
    ASSERT_EQ(e, nullptr);
    EXPECT_EQ(FramesSince(c, t0, 1, 300), 1);
    arv_camera_stop_acquisition(c.camera(), &e);
    ASSERT_EQ(e, nullptr);
    FramesSince(c, 0, 0, 100);  // drain
  }
  // MultiFrame: a stop and a start after 2 of 5 frames give 5 new ones.
  Set(c, "TriggerMode", "Off");
  arv_camera_set_boolean(c.camera(), "AcquisitionFrameRateEnable", TRUE, &e);
  ASSERT_EQ(e, nullptr);
  SetFloat(c, "AcquisitionFrameRate", 40.0);
  Set(c, "AcquisitionMode", "MultiFrame");
  SetInt(c, "AcquisitionFrameCount", 5);
  Settle();
  for (int trial = 0; trial < 2; ++trial) {
    SCOPED_TRACE(trial);
    Start(c);
    ASSERT_FALSE(c.Grab(3000).empty());
    ASSERT_FALSE(c.Grab(3000).empty());
    arv_camera_stop_acquisition(c.camera(), &e);
    ASSERT_EQ(e, nullptr);
    const uint64_t t0 = static_cast<uint64_t>(g_get_real_time()) * 1000;
    Start(c);
    EXPECT_EQ(FramesSince(c, t0, 5, 300), 5);
    arv_camera_stop_acquisition(c.camera(), &e);
    ASSERT_EQ(e, nullptr);
  }
  EXPECT_EQ(c.failed_buffers(), 0u);
}

// GevSCPSPacketSize is fixed while acquiring (its low 16 bits; a receiver
// places packets by the size its stream started with), and its minimum
// leaves room for the largest frame in the fake camera's 65534 packets.
TEST_F(GigeE2E, ThePacketSizeIsFixedWhileAcquiring) {
  ASSERT_NO_FATAL_FAILURE(StartWith(SmallDevice()));
  Client& c = *client_;
  ASSERT_TRUE(c.OpenStream());
  Start(c);
  ASSERT_FALSE(c.Grab(3000).empty());
  GError* e = nullptr;
  arv_device_write_register(c.device(), reg::kPacketSize, 600, &e);
  EXPECT_TRUE(g_error_matches(e, ARV_DEVICE_ERROR, ARV_DEVICE_ERROR_PROTOCOL_ERROR_ACCESS_DENIED))
      << (e != nullptr ? e->message : "no error");
  g_clear_error(&e);
  EXPECT_EQ(ReadInt(c, "GevSCPSPacketSize"), 1400);
  for (int i = 0; i < 3; ++i) EXPECT_FALSE(c.Grab(3000).empty());
  c.CloseStream();
  SetInt(c, "GevSCPSPacketSize", 600);
  EXPECT_EQ(ReadInt(c, "GevSCPSPacketSize"), 600);
  EXPECT_EQ(c.failed_buffers(), 0u);
  genicam::SensorInfo big;
  big.width = big.height = 8192;
  big.has_isp_rgb = true;  // RGB8: 201 MB
  EXPECT_EQ(genicam::MinPacketSize(big), (8192u * 8192 * 3 + 92 + 65533) / 65534 + 36);
  genicam::SensorInfo too_big = big;
  too_big.width = too_big.height = 16384;  // RGB8: 805 MB, beyond 65534 packets of 9000 bytes and 2^32 bits
  EXPECT_GT(genicam::MinPacketSize(too_big), genicam::kMaxPacketSize);
}

TEST_F(GigeE2E, ExposureAutoOnceMovesTheMeanToTheTarget) {
  ASSERT_NO_FATAL_FAILURE(StartWith(SmallDevice()));
  Client& c = *client_;
  ASSERT_TRUE(c.OpenStream());
  Start(c);
  const double before = MeanLevel12(c.Grab(3000));
  c.CloseStream();
  SetFloat(c, "SimAutoTarget", 0.6 * before);
  Set(c, "ExposureAuto", "Once");
  Settle();
  ASSERT_TRUE(c.OpenStream());
  Start(c);
  for (int i = 0; i < 3; ++i) ASSERT_FALSE(c.Grab(3000).empty());
  c.CloseStream();
  Settle();
  EXPECT_STREQ(arv_camera_get_string(c.camera(), "ExposureAuto", nullptr), "Off") << "Once turns itself off";
  const double exposure = ReadFloat(c, "ExposureTime");
  EXPECT_LT(exposure, 10000.0 * 0.8);
  EXPECT_GT(exposure, 10000.0 * 0.4);
  ASSERT_TRUE(c.OpenStream());
  Start(c);
  const double after = MeanLevel12(c.Grab(3000));
  EXPECT_NEAR(after / before, 0.6, 0.1) << "before " << before << " after " << after;
}

// Continuous: the core's PI controller (core/control/auto_exposure.h) keeps
// adjusting and stays on; a feature left Off is held. A -2 EV target on
// ExposureAuto alone, then +1 EV on GainAuto alone.
TEST_F(GigeE2E, AutoContinuousReachesTheTargetWithTheFeaturesThatAreOn) {
  ASSERT_NO_FATAL_FAILURE(StartWith(SmallDevice()));
  Client& c = *client_;
  SetInt(c, "SimFrameIndex", 1);
  ASSERT_TRUE(c.OpenStream());
  Start(c);
  const double before = MeanLevel12(c.Grab(3000));
  c.CloseStream();
  ASSERT_GT(before, 0.02);
  ASSERT_LT(before, 0.4) << "room for +1 EV below saturation";

  auto run = [&](int frames, std::vector<double>* levels) {
    ASSERT_TRUE(c.OpenStream(8));
    Start(c);
    for (int i = 0; i < frames; ++i) {
      const auto f = c.Grab(3000);
      ASSERT_FALSE(f.empty()) << "frame " << i;
      levels->push_back(MeanLevel12(f));
    }
    c.CloseStream();
    Settle();
  };
  SetFloat(c, "SimAutoTarget", before / 4);
  Set(c, "ExposureAuto", "Continuous");
  Settle();
  std::vector<double> levels;
  ASSERT_NO_FATAL_FAILURE(run(8, &levels));
  EXPECT_STREQ(arv_camera_get_string(c.camera(), "ExposureAuto", nullptr), "Continuous");
  EXPECT_NEAR(std::log2(levels.back() / (before / 4)), 0.0, 1.0 / 6) << "last frame within 1/6 EV";
  EXPECT_NEAR(ReadFloat(c, "ExposureTime") / 10000.0, 0.25, 0.25 * 0.12);
  EXPECT_DOUBLE_EQ(ReadFloat(c, "Gain"), 0.0) << "GainAuto is Off";

  Set(c, "ExposureAuto", "Off");
  const double exposure = ReadFloat(c, "ExposureTime");
  SetFloat(c, "SimAutoTarget", before / 2);
  Set(c, "GainAuto", "Continuous");
  Settle();
  levels.clear();
  ASSERT_NO_FATAL_FAILURE(run(8, &levels));
  EXPECT_NEAR(std::log2(levels.back() / (before / 2)), 0.0, 1.0 / 6);
  EXPECT_NEAR(ReadFloat(c, "Gain"), 6.02, 1.0) << "+1 EV from gain";
  EXPECT_DOUBLE_EQ(ReadFloat(c, "ExposureTime"), exposure) << "ExposureAuto is Off";
}

// SFNC: the auto loop owns ExposureTime (GainAuto: Gain and GainRaw) while
// its Auto feature is Once or Continuous. The XML locks them (pIsLocked over
// the Auto register) and the device refuses a raw write that changes one,
// access denied, logging why; Off (set by the client, or by Once itself
// when it settles) makes them writable again.
TEST_F(GigeE2E, ExposureTimeAndGainAreLockedWhileTheirAutoIsOn) {
  ASSERT_NO_FATAL_FAILURE(StartWith(SmallDevice()));
  Client& c = *client_;
  ArvGc* gc = arv_device_get_genicam(c.device());
  const auto locked = [gc](const char* name) {
    ArvGcNode* node = arv_gc_get_node(gc, name);
    EXPECT_NE(node, nullptr) << name;
    return node != nullptr && arv_gc_feature_node_is_locked(ARV_GC_FEATURE_NODE(node), nullptr);
  };
  // A raw write of a new value: refused with access denied, the reason logged, the value kept.
  const auto refused = [&](const char* name, uint32_t address, const std::vector<uint8_t>& bytes, const char* why) {
    const auto read = [&] { return std::string(name) == "GainRaw" ? double(ReadInt(c, name)) : ReadFloat(c, name); };
    const double before = read();
    testing::internal::CaptureStderr();
    GError* e = nullptr;
    std::vector<uint8_t> b = bytes;
    arv_device_write_memory(c.device(), address, static_cast<guint32>(b.size()), b.data(), &e);
    const std::string err = testing::internal::GetCapturedStderr();
    EXPECT_TRUE(g_error_matches(e, ARV_DEVICE_ERROR, ARV_DEVICE_ERROR_PROTOCOL_ERROR_ACCESS_DENIED))
        << name << ": " << (e != nullptr ? e->message : "no error: written");
    g_clear_error(&e);
    EXPECT_NE(err.find(std::string("camsim-gige: refused ") + name), std::string::npos) << err;
    EXPECT_NE(err.find(why), std::string::npos) << err;
    EXPECT_DOUBLE_EQ(read(), before) << name;
  };
  for (const char* name : {"ExposureTime", "ExposureTimeAbs", "Gain", "GainRaw"}) EXPECT_FALSE(locked(name)) << name;
  SetFloat(c, "ExposureTime", 8000.0);
  SetFloat(c, "Gain", 2.0);
  Set(c, "ExposureAuto", "Continuous");
  Settle();
  EXPECT_TRUE(locked("ExposureTime"));
  EXPECT_TRUE(locked("ExposureTimeAbs"));
  EXPECT_FALSE(locked("Gain")) << "GainAuto is Off";
  ASSERT_NO_FATAL_FAILURE(refused("ExposureTime", reg::kExposureTime, Be64(1234.0),
                                  "locked: ExposureAuto is Continuous (locked while ExposureAuto is not Off or "
                                  "ExposureMode is TriggerWidth)"));
  GError* e = nullptr;
  arv_camera_set_float(c.camera(), "ExposureTime", 1234.0, &e);
  EXPECT_NE(e, nullptr) << "a locked ExposureTime written through GenApi";
  g_clear_error(&e);
  EXPECT_DOUBLE_EQ(ReadFloat(c, "ExposureTime"), 8000.0) << "no frame yet: the loop has not moved it";
  // The value it holds passes (a client writing back what it read).
  std::vector<uint8_t> same = Be64(8000.0);
  arv_device_write_memory(c.device(), reg::kExposureTime, 8, same.data(), &e);
  EXPECT_EQ(e, nullptr) << e->message;
  g_clear_error(&e);
  Set(c, "GainAuto", "Continuous");
  Settle();
  EXPECT_TRUE(locked("Gain"));
  EXPECT_TRUE(locked("GainRaw"));
  ASSERT_NO_FATAL_FAILURE(refused("Gain", reg::kGain, Be64(6.0), "GainAuto is Continuous"));
  ASSERT_NO_FATAL_FAILURE(refused("GainRaw", reg::kGainRaw, Be32(60), "GainAuto is Continuous"));
  EXPECT_EQ(ReadInt(c, "GainRaw"), 20);
  // Off: writable at once (no sync in between).
  Set(c, "ExposureAuto", "Off");
  Set(c, "GainAuto", "Off");
  EXPECT_FALSE(locked("ExposureTime"));
  EXPECT_FALSE(locked("Gain"));
  SetFloat(c, "ExposureTime", 5000.0);
  SetInt(c, "GainRaw", 30);
  Settle();
  EXPECT_DOUBLE_EQ(ReadFloat(c, "ExposureTime"), 5000.0);
  EXPECT_DOUBLE_EQ(ReadFloat(c, "Gain"), 3.0);
  // Once: locked until it has settled and returned to Off by itself.
  ASSERT_TRUE(c.OpenStream());
  Start(c);
  const double level = MeanLevel12(c.Grab(3000));
  c.CloseStream();
  SetFloat(c, "SimAutoTarget", 0.6 * level);
  Set(c, "ExposureAuto", "Once");
  Settle();
  EXPECT_TRUE(locked("ExposureTime"));
  ASSERT_NO_FATAL_FAILURE(refused("ExposureTime", reg::kExposureTime, Be64(1234.0), "ExposureAuto is Once"));
  ASSERT_TRUE(c.OpenStream());
  Start(c);
  for (int i = 0; i < 4; ++i) ASSERT_FALSE(c.Grab(3000).empty());
  c.CloseStream();
  Settle();
  ASSERT_STREQ(arv_camera_get_string(c.camera(), "ExposureAuto", nullptr), "Off") << "Once turns itself off";
  EXPECT_FALSE(locked("ExposureTime"));
  SetFloat(c, "ExposureTime", 1234.0);
  Settle();
  EXPECT_DOUBLE_EQ(ReadFloat(c, "ExposureTime"), 1234.0);
}

// The Auto limits are features an Aravis client reads and writes; each
// bound of a lower limit (upper limit) that is the other's value reads it.
TEST_F(GigeE2E, AutoLimitsAreFeaturesBoundingEachOther) {
  ASSERT_NO_FATAL_FAILURE(StartWith(SmallDevice()));
  Client& c = *client_;
  EXPECT_DOUBLE_EQ(ReadFloat(c, "AutoExposureTimeLowerLimit"), 20.0);
  EXPECT_DOUBLE_EQ(ReadFloat(c, "AutoExposureTimeUpperLimit"), 100000.0);
  EXPECT_DOUBLE_EQ(ReadFloat(c, "AutoGainLowerLimit"), 0.0);
  EXPECT_DOUBLE_EQ(ReadFloat(c, "AutoGainUpperLimit"), 24.0);
  const auto bounds = [&c](const char* name) {
    double min = 0, max = 0;
    GError* e = nullptr;
    arv_camera_get_float_bounds(c.camera(), name, &min, &max, &e);
    EXPECT_EQ(e, nullptr) << name;
    g_clear_error(&e);
    return std::make_pair(min, max);
  };
  EXPECT_EQ(bounds("AutoExposureTimeLowerLimit"), std::make_pair(1.0, 100000.0));
  EXPECT_EQ(bounds("AutoExposureTimeUpperLimit"), std::make_pair(20.0, 1e8));
  EXPECT_EQ(bounds("AutoGainLowerLimit"), std::make_pair(0.0, 24.0));
  EXPECT_EQ(bounds("AutoGainUpperLimit"), std::make_pair(0.0, 48.0));
  SetFloat(c, "AutoExposureTimeUpperLimit", 50000.0);
  SetFloat(c, "AutoGainLowerLimit", 2.5);
  SetFloat(c, "AutoGainUpperLimit", 12.0);
  Settle();
  EXPECT_DOUBLE_EQ(ReadFloat(c, "AutoExposureTimeUpperLimit"), 50000.0);
  EXPECT_DOUBLE_EQ(ReadFloat(c, "AutoGainLowerLimit"), 2.5);
  EXPECT_DOUBLE_EQ(ReadFloat(c, "AutoGainUpperLimit"), 12.0);
  EXPECT_EQ(bounds("AutoExposureTimeLowerLimit"), std::make_pair(1.0, 50000.0));
  EXPECT_EQ(bounds("AutoGainUpperLimit"), std::make_pair(2.5, 48.0));
  // Above the upper limit: refused by the device (Aravis's range checks are
  // off by default) and, with them on, by the client.
  GError* e = nullptr;
  arv_camera_set_float(c.camera(), "AutoExposureTimeLowerLimit", 60000.0, &e);
  EXPECT_TRUE(g_error_matches(e, ARV_DEVICE_ERROR, ARV_DEVICE_ERROR_PROTOCOL_ERROR_INVALID_PARAMETER))
      << (e != nullptr ? e->message : "no error");
  g_clear_error(&e);
  arv_camera_set_range_check_policy(c.camera(), ARV_RANGE_CHECK_POLICY_ENABLE);
  arv_camera_set_float(c.camera(), "AutoGainUpperLimit", 2.0, &e);
  EXPECT_NE(e, nullptr);
  g_clear_error(&e);
  arv_camera_set_range_check_policy(c.camera(), ARV_RANGE_CHECK_POLICY_DISABLE);
  EXPECT_EQ(device_->writes_refused(), 1u);
  EXPECT_DOUBLE_EQ(ReadFloat(c, "AutoExposureTimeLowerLimit"), 20.0);
  EXPECT_DOUBLE_EQ(ReadFloat(c, "AutoGainUpperLimit"), 12.0);
}

TEST_F(GigeE2E, StagesCanBeSwitchedButNotBreakTheFormat) {
  ASSERT_NO_FATAL_FAILURE(StartWith(SmallDevice()));
  Client& c = *client_;
  Set(c, "SimStageSelector", "Stage_sensor");
  EXPECT_TRUE(arv_camera_get_boolean(c.camera(), "SimStageEnable", nullptr));
  GError* e = nullptr;
  arv_camera_set_boolean(c.camera(), "SimStageEnable", false, &e);  // refused as it arrives
  EXPECT_TRUE(g_error_matches(e, ARV_DEVICE_ERROR, ARV_DEVICE_ERROR_PROTOCOL_ERROR_INVALID_PARAMETER))
      << (e != nullptr ? e->message : "no error");
  g_clear_error(&e);
  EXPECT_TRUE(arv_camera_get_boolean(c.camera(), "SimStageEnable", nullptr)) << "raw formats need the sensor";
  Settle();
  EXPECT_TRUE(arv_camera_get_boolean(c.camera(), "SimStageEnable", nullptr));
  Set(c, "SimStageSelector", "Stage_vignetting");
  arv_camera_set_boolean(c.camera(), "SimStageEnable", false, nullptr);
  Settle();
  EXPECT_FALSE(arv_camera_get_boolean(c.camera(), "SimStageEnable", nullptr));
  Set(c, "SimStageSelector", "Stage_sensor");
  Settle();
  EXPECT_TRUE(arv_camera_get_boolean(c.camera(), "SimStageEnable", nullptr));
  SetInt(c, "SimFrameIndex", 1);
  Settle();
  ASSERT_TRUE(c.OpenStream());
  Start(c);
  const auto f = c.Grab(3000);
  const uint32_t code = genicam::BayerCode(Cfa::kBayerRG, 12);
  EXPECT_TRUE(f == Reference(1, code, 0, 0, 64, 48, {"vignetting.mode=\"off\""}) ||
              f == Reference(1, code, 0, 0, 64, 48, {"pipeline.stages=[\"exposure\",\"cfa\",\"sensor\"]"}))
      << "frame without vignetting";
  EXPECT_FALSE(f == Reference(1, code, 0, 0, 64, 48));
}

// Selected features have one register per selector value (GenICam pIndex):
// a value written right after the selector lands on that line or stage,
// moving the selector on at once neither loses it nor moves it elsewhere,
// and reads follow the selector at once. (With one register that the
// device's 2 ms sync rewrote when the selector moved, writes were lost or
// moved; CI caught it once.)
TEST_F(GigeE2E, SelectedRegistersFollowTheSelector) {
  ASSERT_NO_FATAL_FAILURE(StartWith(SmallDevice()));
  Client& c = *client_;
  // Every selected feature's register, for every value of its selector, is
  // where the table says (the XML test cannot read a selector).
  int selected = 0;
  for (const genicam::Feature& f : device_->table()) {
    if (f.selected_by.empty()) continue;
    ++selected;
    ArvGcNode* reg_node = arv_gc_get_node(arv_device_get_genicam(c.device()), (f.name + "Reg").c_str());
    ASSERT_NE(reg_node, nullptr) << f.name;
    const genicam::Feature* selector = genicam::FindFeature(device_->table(), f.selected_by);
    ASSERT_NE(selector, nullptr) << f.selected_by;
    ASSERT_EQ(selector->entries.size(), static_cast<size_t>(f.selections)) << f.name;
    for (const genicam::EnumEntry& e : selector->entries) {
      Set(c, f.selected_by.c_str(), e.name.c_str());
      EXPECT_EQ(arv_gc_register_get_address(ARV_GC_REGISTER(reg_node), nullptr),
                genicam::reg::SelectedAddress(f.address, static_cast<size_t>(e.value), f.length))
          << f.name << " at " << e.name;
    }
  }
  EXPECT_EQ(selected, 7) << "LineMode, LineSource, LineStatus, LineInverter, SimStageEnable, ChunkEnable, BalanceRatio";
  // LineMode at once; LineSource on the input refused, the output's kept.
  Set(c, "LineSelector", "Line1");
  Set(c, "LineSource", "ExposureActive");
  Set(c, "LineSelector", "Line0");
  EXPECT_STREQ(arv_camera_get_string(c.camera(), "LineMode", nullptr), "Input");
  GError* e = nullptr;
  // The XML marks the entry unavailable at Line0 (pIsAvailable), so Aravis
  // refuses it itself; the device refuses the register write as it arrives.
  arv_camera_set_string(c.camera(), "LineSource", "ExposureActive", &e);
  EXPECT_NE(e, nullptr) << "an entry not available at Line0";
  g_clear_error(&e);
  arv_device_write_register(c.device(), genicam::reg::SelectedAddress(reg::kLineSource, 0),
                            genicam::kLineSourceExposureActive, &e);
  EXPECT_TRUE(g_error_matches(e, ARV_DEVICE_ERROR, ARV_DEVICE_ERROR_PROTOCOL_ERROR_INVALID_PARAMETER))
      << (e != nullptr ? e->message : "no error");
  g_clear_error(&e);
  EXPECT_STREQ(arv_camera_get_string(c.camera(), "LineSource", nullptr), "Off") << "Line0 is an input";
  // Clients list only Off there.
  auto available = [&c] {
    guint n = 0;
    const char** v = arv_camera_dup_available_enumerations_as_strings(c.camera(), "LineSource", &n, nullptr);
    std::vector<std::string> names(v, v + n);
    g_free(v);
    return names;
  };
  EXPECT_EQ(available(), std::vector<std::string>{"Off"}) << "at Line0";
  Set(c, "LineSelector", "Line1");
  EXPECT_EQ(available(), (std::vector<std::string>{"Off", "ExposureActive"})) << "at Line1";
  EXPECT_STREQ(arv_camera_get_string(c.camera(), "LineMode", nullptr), "Output");
  EXPECT_STREQ(arv_camera_get_string(c.camera(), "LineSource", nullptr), "ExposureActive");
  for (int round = 0; round < 20; ++round) {
    const bool on = round % 2 == 1;
    Set(c, "SimStageSelector", "Stage_vignetting");
    arv_camera_set_boolean(c.camera(), "SimStageEnable", on, nullptr);
    Set(c, "SimStageSelector", "Stage_exposure");  // away at once: the sync may see only this
    EXPECT_TRUE(arv_camera_get_boolean(c.camera(), "SimStageEnable", nullptr)) << round;
    Settle();
    EXPECT_TRUE(arv_camera_get_boolean(c.camera(), "SimStageEnable", nullptr)) << round;
    Set(c, "SimStageSelector", "Stage_vignetting");
    EXPECT_EQ(arv_camera_get_boolean(c.camera(), "SimStageEnable", nullptr), on) << round;
  }
}

// ---------------------------------------------------------------- SFNC white balance, readout

// Each channel's mean of an RGB8 frame, and its largest sample.
struct ChannelStats {
  double mean[3] = {};
  int max = 0;
};
ChannelStats RgbStats(const std::vector<uint8_t>& f) {
  ChannelStats s;
  const size_t n = f.size() / 3;
  for (size_t i = 0; i < n; ++i)
    for (int ch = 0; ch < 3; ++ch) {
      s.mean[ch] += f[3 * i + ch];
      s.max = std::max<int>(s.max, f[3 * i + ch]);
    }
  for (double& m : s.mean) m /= std::max<size_t>(n, 1);
  return s;
}

// BalanceRatio is the white balance stage's gain of the selected channel:
// doubling Red doubles the red mean of RGB8 frames made after the write
// (linear output: the gamma stage off; a flat grey scene well below
// saturation), and leaves the raw formats' bytes alone. Out-of-range
// ratios are refused as they arrive.
TEST_F(GigeE2E, BalanceRatioScalesItsChannel) {
  DeviceOptions o = SmallDevice();
  o.pattern = "flat";
  ASSERT_NO_FATAL_FAILURE(StartWith(o));
  Client& c = *client_;
  Set(c, "SimStageSelector", "Stage_gamma");
  arv_camera_set_boolean(c.camera(), "SimStageEnable", false, nullptr);
  SetFloat(c, "ExposureTime", 30000.0);
  Set(c, "BalanceRatioSelector", "Red");
  EXPECT_DOUBLE_EQ(ReadFloat(c, "BalanceRatio"), 1.3);  // configs/camera.toml
  Set(c, "BalanceRatioSelector", "Blue");
  EXPECT_DOUBLE_EQ(ReadFloat(c, "BalanceRatio"), 1.1818);
  Set(c, "PixelFormat", "BayerRG12");
  const std::vector<uint8_t> raw_before = GrabIndex(c, 7);
  Set(c, "PixelFormat", "RGB8");
  const ChannelStats before = RgbStats(GrabIndex(c, 7));
  Set(c, "BalanceRatioSelector", "Red");
  SetFloat(c, "BalanceRatio", 2.6);
  Set(c, "BalanceRatioSelector", "Green");  // the Red register keeps its value
  Settle();
  Set(c, "BalanceRatioSelector", "Red");
  EXPECT_DOUBLE_EQ(ReadFloat(c, "BalanceRatio"), 2.6);
  const ChannelStats after = RgbStats(GrabIndex(c, 7));
  EXPECT_LT(after.max, 250) << "away from saturation";
  EXPECT_GT(before.mean[0], 20.0);
  EXPECT_NEAR(after.mean[0] / before.mean[0], 2.0, 0.03) << before.mean[0] << " -> " << after.mean[0];
  EXPECT_NEAR(after.mean[1] / before.mean[1], 1.0, 0.03) << "green";
  EXPECT_NEAR(after.mean[2] / before.mean[2], 1.0, 0.03) << "blue";
  Set(c, "PixelFormat", "BayerRG12");
  EXPECT_TRUE(GrabIndex(c, 7) == raw_before) << "the raw frame is the sensor's, before the white balance";
  for (const double bad : {16.5, -0.25, std::nan("")}) {
    GError* e = nullptr;
    arv_camera_set_float(c.camera(), "BalanceRatio", bad, &e);
    EXPECT_TRUE(g_error_matches(e, ARV_DEVICE_ERROR, ARV_DEVICE_ERROR_PROTOCOL_ERROR_INVALID_PARAMETER))
        << bad << ": " << (e != nullptr ? e->message : "no error");
    g_clear_error(&e);
    EXPECT_DOUBLE_EQ(ReadFloat(c, "BalanceRatio"), 2.6) << bad;
  }
}

// BalanceWhiteAuto Once: gray world on the next frame, then Off (SFNC).
// On the bundled scene, from deliberately wrong ratios, the RGB8 channel
// means end up about equal.
TEST_F(GigeE2E, BalanceWhiteAutoOnceMakesTheMeanGrey) {
  ASSERT_NO_FATAL_FAILURE(StartWith(RunSceneDevice({})));
  Client& c = *client_;
  Set(c, "PixelFormat", "RGB8");
  Set(c, "BalanceRatioSelector", "Red");
  SetFloat(c, "BalanceRatio", 0.5);
  Set(c, "BalanceRatioSelector", "Blue");
  SetFloat(c, "BalanceRatio", 3.0);
  const ChannelStats before = RgbStats(GrabIndex(c, kRunFrame));
  EXPECT_GT(before.mean[2] / before.mean[0], 1.5) << "a blue cast to start from";
  Set(c, "BalanceWhiteAuto", "Once");
  Settle();
  EXPECT_STREQ(arv_camera_get_string(c.camera(), "BalanceWhiteAuto", nullptr), "Once");
  (void)GrabIndex(c, kRunFrame);  // the frame Once measures
  Settle();
  EXPECT_STREQ(arv_camera_get_string(c.camera(), "BalanceWhiteAuto", nullptr), "Off") << "Once turns itself off";
  Set(c, "BalanceRatioSelector", "Green");
  EXPECT_DOUBLE_EQ(ReadFloat(c, "BalanceRatio"), 1.0) << "Green keeps its ratio";
  Set(c, "BalanceRatioSelector", "Red");
  const double red = ReadFloat(c, "BalanceRatio");
  const ChannelStats after = RgbStats(GrabIndex(c, kRunFrame));
  for (int ch = 0; ch < 3; ++ch)
    EXPECT_NEAR(after.mean[ch] / after.mean[1], 1.0, 0.04)
        << "channel " << ch << ": " << after.mean[0] << " " << after.mean[1] << " " << after.mean[2];
  // Off: the ratios stay where Once left them.
  (void)GrabIndex(c, kRunFrame + 1);
  Settle();
  EXPECT_DOUBLE_EQ(ReadFloat(c, "BalanceRatio"), red);
}

// BalanceWhiteAuto Continuous: gray world on every frame; it stays on.
TEST_F(GigeE2E, BalanceWhiteAutoContinuousStaysOn) {
  ASSERT_NO_FATAL_FAILURE(StartWith(RunSceneDevice({})));
  Client& c = *client_;
  Set(c, "PixelFormat", "RGB8");
  Set(c, "BalanceRatioSelector", "Red");
  SetFloat(c, "BalanceRatio", 0.5);
  Set(c, "BalanceWhiteAuto", "Continuous");
  SetInt(c, "SimFrameIndex", kRunFrame);
  Settle();
  ASSERT_TRUE(c.OpenStream());
  Start(c);
  for (int i = 0; i < 2; ++i) ASSERT_FALSE(c.Grab(3000).empty());
  const ChannelStats on = RgbStats(c.Grab(3000));
  c.CloseStream();
  Settle();
  EXPECT_STREQ(arv_camera_get_string(c.camera(), "BalanceWhiteAuto", nullptr), "Continuous");
  EXPECT_GT(ReadFloat(c, "BalanceRatio"), 1.0) << "Red raised from 0.5";
  for (int ch = 0; ch < 3; ++ch)
    EXPECT_NEAR(on.mean[ch] / on.mean[1], 1.0, 0.04)
        << "channel " << ch << ": " << on.mean[0] << " " << on.mean[1] << " " << on.mean[2];
}

// A frame of w x h pixels of `bytes` bytes each, mirrored.
std::vector<uint8_t> Mirrored(const std::vector<uint8_t>& f, int w, int h, int bytes, bool x, bool y) {
  std::vector<uint8_t> out(f.size());
  for (int r = 0; r < h; ++r)
    for (int i = 0; i < w; ++i) {
      const size_t from = (static_cast<size_t>(y ? h - 1 - r : r) * w + (x ? w - 1 - i : i)) * bytes;
      std::memcpy(&out[(static_cast<size_t>(r) * w + i) * bytes], &f[from], static_cast<size_t>(bytes));
    }
  return out;
}

void SetReverse(Client& c, bool x, bool y) {
  GError* e = nullptr;
  arv_camera_set_boolean(c.camera(), "ReverseX", x, &e);
  ASSERT_EQ(e, nullptr) << e->message;
  arv_camera_set_boolean(c.camera(), "ReverseY", y, &e);
  ASSERT_EQ(e, nullptr) << e->message;
  Settle();
}

// ReverseX / ReverseY mirror the readout: each frame is the normal frame
// (same index: same noise) mirrored, byte for byte, in a window off the
// corner. A Bayer format names the phase read out (BayerRG -> BayerGR with
// ReverseX, BayerGB with ReverseY, BayerBG with both): the PixelFormat the
// client reads, the leader's and the formats it may pick. The other
// phase's formats are refused, and the readout is locked while acquiring.
TEST_F(GigeE2E, ReverseXAndYMirrorTheReadout) {
  ASSERT_NO_FATAL_FAILURE(StartWith(SmallDevice()));
  Client& c = *client_;
  SetInt(c, "Width", 60);
  SetInt(c, "OffsetX", 2);
  SetInt(c, "Height", 44);
  SetInt(c, "OffsetY", 4);
  const Cfa phases[4] = {Cfa::kBayerRG, Cfa::kBayerGR, Cfa::kBayerGB, Cfa::kBayerBG};  // by ReverseX + 2 ReverseY
  struct Case {
    const char* format;
    int bits, bytes;  // bits 0: RGB8
  } cases[] = {{"BayerRG12", 12, 2}, {"BayerRG8", 8, 1}, {"RGB8", 0, 3}};
  for (const Case& k : cases) {
    SCOPED_TRACE(k.format);
    ASSERT_NO_FATAL_FAILURE(SetReverse(c, false, false));
    Set(c, "PixelFormat", k.format);
    const std::vector<uint8_t> normal = GrabIndex(c, 5);
    ASSERT_EQ(normal.size(), 60u * 44 * k.bytes);
    for (int readout = 1; readout < 4; ++readout) {
      SCOPED_TRACE(readout);
      const bool x = readout & 1, y = readout & 2;
      ASSERT_NO_FATAL_FAILURE(SetReverse(c, x, y));
      const uint32_t want = k.bits == 0 ? genicam::kRGB8 : genicam::BayerCode(phases[readout], k.bits);
      EXPECT_EQ(static_cast<uint32_t>(arv_camera_get_pixel_format(c.camera(), nullptr)), want);
      uint32_t code = 0;
      const std::vector<uint8_t> f = GrabIndex(c, 5, &code);
      EXPECT_EQ(code, want) << "the leader's format";
      EXPECT_TRUE(f == Mirrored(normal, 60, 44, k.bytes, x, y)) << "the normal frame mirrored";
      EXPECT_FALSE(f == normal);
    }
  }
  ASSERT_NO_FATAL_FAILURE(SetReverse(c, false, false));
  Set(c, "PixelFormat", "BayerRG8");
  ASSERT_NO_FATAL_FAILURE(SetReverse(c, true, false));
  EXPECT_STREQ(arv_camera_get_pixel_format_as_string(c.camera(), nullptr), "BayerGR8");
  guint n = 0;
  const char** formats = arv_camera_dup_available_pixel_formats_as_strings(c.camera(), &n, nullptr);
  EXPECT_EQ(std::vector<std::string>(formats, formats + n),
            (std::vector<std::string>{"BayerGR12", "BayerGR8", "BayerGR16", "BayerGR12p", "BayerGR12Packed", "Mono8",
                                      "RGB8", "BGR8", "YCbCr422_8", "YUV422_8", "YUV422_8_UYVY"}));
  g_free(formats);
  GError* e = nullptr;
  arv_device_write_register(c.device(), reg::kPixelFormat, genicam::BayerCode(Cfa::kBayerRG, 12), &e);
  EXPECT_TRUE(g_error_matches(e, ARV_DEVICE_ERROR, ARV_DEVICE_ERROR_PROTOCOL_ERROR_INVALID_PARAMETER))
      << (e != nullptr ? e->message : "no error: BayerRG12 is not what ReverseX reads out");
  g_clear_error(&e);
  Set(c, "PixelFormat", "BayerGR12");
  ASSERT_TRUE(c.OpenStream());
  Start(c);
  ASSERT_FALSE(c.Grab(3000).empty());
  arv_camera_set_boolean(c.camera(), "ReverseX", false, &e);
  EXPECT_TRUE(g_error_matches(e, ARV_DEVICE_ERROR, ARV_DEVICE_ERROR_PROTOCOL_ERROR_ACCESS_DENIED))
      << (e != nullptr ? e->message : "no error: the readout changed while acquiring");
  g_clear_error(&e);
  c.CloseStream();
  EXPECT_TRUE(arv_camera_get_boolean(c.camera(), "ReverseX", nullptr));
  EXPECT_STREQ(arv_camera_get_pixel_format_as_string(c.camera(), nullptr), "BayerGR12");
  // Packed formats carry the mirrored readout too: they unpack to its codes.
  ASSERT_NO_FATAL_FAILURE(
      CheckPackedFormats(c, "BayerGR12",
                         {{"BayerGR12p", ARV_PIXEL_FORMAT_BAYER_GR_12P, 12, genicam::Packing::kPfnc},
                          {"BayerGR12Packed", ARV_PIXEL_FORMAT_BAYER_GR_12_PACKED, 12, genicam::Packing::kGigeLegacy}},
                         60, 44, 7));
  Set(c, "PixelFormat", "BayerGR12");
  ASSERT_NO_FATAL_FAILURE(SetReverse(c, false, false));
  EXPECT_STREQ(arv_camera_get_pixel_format_as_string(c.camera(), nullptr), "BayerRG12");
}

// A mono sensor's readout mirrors too (an odd window; the format stays).
TEST_F(GigeE2E, ReverseXAndYMirrorMonoFrames) {
  ASSERT_NO_FATAL_FAILURE(StartWith(SmallMonoDevice()));
  Client& c = *client_;
  SetInt(c, "Width", 31);
  SetInt(c, "OffsetX", 1);
  SetInt(c, "Height", 23);
  for (const char* format : {"Mono8", "Mono12"}) {
    SCOPED_TRACE(format);
    ASSERT_NO_FATAL_FAILURE(SetReverse(c, false, false));
    Set(c, "PixelFormat", format);
    const int bytes = std::strcmp(format, "Mono8") == 0 ? 1 : 2;
    const std::vector<uint8_t> normal = GrabIndex(c, 3);
    ASSERT_EQ(normal.size(), 31u * 23 * bytes);
    for (int readout = 1; readout < 4; ++readout) {
      const bool x = readout & 1, y = readout & 2;
      ASSERT_NO_FATAL_FAILURE(SetReverse(c, x, y));
      EXPECT_STREQ(arv_camera_get_pixel_format_as_string(c.camera(), nullptr), format);
      EXPECT_TRUE(GrabIndex(c, 3) == Mirrored(normal, 31, 23, bytes, x, y)) << readout;
    }
  }
}

// BGR8 (PFNC 0x02180015) is RGB8 with R and B swapped, byte for byte: in
// the whole frame and in a window off the corner under ReverseX.
TEST_F(GigeE2E, Bgr8IsRgb8WithRedAndBlueSwapped) {
  ASSERT_NO_FATAL_FAILURE(StartWith(SmallDevice()));
  Client& c = *client_;
  const auto swapped = [](std::vector<uint8_t> f) {
    for (size_t i = 0; i + 2 < f.size(); i += 3) std::swap(f[i], f[i + 2]);
    return f;
  };
  for (const bool reverse_x : {false, true}) {
    SCOPED_TRACE(reverse_x ? "ReverseX, 60x44 at (2, 4)" : "whole sensor");
    if (reverse_x) {
      SetInt(c, "Width", 60);
      SetInt(c, "OffsetX", 2);
      SetInt(c, "Height", 44);
      SetInt(c, "OffsetY", 4);
      ASSERT_NO_FATAL_FAILURE(SetReverse(c, true, false));
    }
    const size_t bytes = reverse_x ? size_t{60} * 44 * 3 : size_t{64} * 48 * 3;
    uint32_t code = 0;
    const std::vector<uint8_t> rgb = GrabAt(c, "RGB8", 6);
    const std::vector<uint8_t> bgr = GrabAt(c, "BGR8", 6, &code);
    EXPECT_EQ(code, genicam::kBGR8) << "the leader's format";
    EXPECT_STREQ(arv_camera_get_pixel_format_as_string(c.camera(), nullptr), "BGR8");
    EXPECT_EQ(ReadInt(c, "PayloadSize"), static_cast<int64_t>(bytes));
    ASSERT_EQ(rgb.size(), bytes);
    ASSERT_EQ(bgr.size(), bytes);
    EXPECT_TRUE(bgr == swapped(rgb)) << "BGR8 is not RGB8 with R and B swapped";
    EXPECT_FALSE(bgr == rgb) << "a frame whose red equals its blue tests nothing";
  }
}

// The 4:2:2 formats, 2 bytes a pixel, are RGB8 (the same frame) in
// full-range BT.601 YCbCr, Cb and Cr those of each pair's even pixel:
// YCbCr422_8 (PFNC 0x0210003B) and YUV422_8 (0x02100032) as Y Cb Y Cr,
// YUV422_8_UYVY (0x0210001F) as Cb Y Cr Y. Each byte equals the test's own
// double-precision conversion, rounded half up and clamped to 0..255: in the
// whole frame, in a window off the corner under ReverseX, and for a test
// pattern (grey: Cb = Cr = 128). A window of odd width is refused.
TEST_F(GigeE2E, Yuv422FormatsAreRgb8InFullRangeBt601) {
  ASSERT_NO_FATAL_FAILURE(StartWith(SmallDevice()));
  Client& c = *client_;
  // Kr = 0.299, Kb = 0.114. The exact values are multiples of 1/1000, 1/1772
  // or 1/1402; the 1e-9 lifts one at exactly k + 0.5 that rounding in double
  // left a hair below.
  const auto quantise = [](double v) { return static_cast<uint8_t>(std::clamp(std::floor(v + 0.5 + 1e-9), 0.0, 255.0)); };
  const auto ycbcr = [&](const uint8_t* p, uint8_t out[3]) {
    const double y = 0.299 * p[0] + 0.587 * p[1] + 0.114 * p[2];
    out[0] = quantise(y);
    out[1] = quantise(128 + (p[2] - y) / (2 * (1 - 0.114)));
    out[2] = quantise(128 + (p[0] - y) / (2 * (1 - 0.299)));
  };
  struct Case {
    const char* name;
    uint32_t code;
    bool uyvy;
    const char* gst;  // Aravis's GStreamer caps for the code
  };
  // (Aravis 0.8.26 has no name and no caps for 0x0210003B.)
  const Case cases[] = {{"YCbCr422_8", 0x0210003bu, false, nullptr},
                        {"YUV422_8", ARV_PIXEL_FORMAT_YUV_422_YUYV_PACKED, false, "video/x-raw, format=(string)YUY2"},
                        {"YUV422_8_UYVY", ARV_PIXEL_FORMAT_YUV_422_PACKED, true, "video/x-raw, format=(string)UYVY"}};
  for (const Case& k : cases) EXPECT_STREQ(arv_pixel_format_to_gst_caps_string(k.code), k.gst) << k.name;
  const auto check = [&](int w, int h, uint32_t index) {
    Set(c, "PixelFormat", "RGB8");
    const std::vector<uint8_t> rgb = GrabAt(c, "RGB8", index);
    ASSERT_EQ(rgb.size(), static_cast<size_t>(w) * h * 3);
    std::vector<uint8_t> yuyv(static_cast<size_t>(w) * h * 2), uyvy(yuyv.size());
    for (size_t p = 0; p < static_cast<size_t>(w) * h; p += 2) {
      uint8_t even[3], odd[3];
      ycbcr(&rgb[3 * p], even);
      ycbcr(&rgb[3 * p + 3], odd);
      const uint8_t a[4] = {even[0], even[1], odd[0], even[2]}, b[4] = {even[1], even[0], even[2], odd[0]};
      std::copy(a, a + 4, yuyv.begin() + static_cast<ptrdiff_t>(2 * p));
      std::copy(b, b + 4, uyvy.begin() + static_cast<ptrdiff_t>(2 * p));
    }
    for (const Case& k : cases) {
      SCOPED_TRACE(k.name);
      uint32_t code = 0;
      const std::vector<uint8_t> f = GrabAt(c, k.name, index, &code);
      EXPECT_EQ(code, k.code) << "the leader's format";
      EXPECT_STREQ(arv_camera_get_pixel_format_as_string(c.camera(), nullptr), k.name);
      EXPECT_EQ(static_cast<uint32_t>(arv_camera_get_pixel_format(c.camera(), nullptr)), k.code);
      EXPECT_EQ(ReadInt(c, "PayloadSize"), static_cast<int64_t>(w) * h * 2);
      ASSERT_EQ(f.size(), static_cast<size_t>(w) * h * 2);
      const std::vector<uint8_t>& want = k.uyvy ? uyvy : yuyv;
      size_t bad = 0, first = 0;
      for (size_t i = 0; i < f.size(); ++i)
        if (f[i] != want[i] && bad++ == 0) first = i;
      EXPECT_EQ(bad, 0u) << "first at byte " << first << ": " << int{f[first]} << ", want " << int{want[first]};
    }
  };
  for (const bool reverse_x : {false, true}) {
    SCOPED_TRACE(reverse_x ? "ReverseX, 60x44 at (2, 4)" : "whole sensor");
    if (reverse_x) {
      SetInt(c, "Width", 60);
      SetInt(c, "OffsetX", 2);
      SetInt(c, "Height", 44);
      SetInt(c, "OffsetY", 4);
      ASSERT_NO_FATAL_FAILURE(SetReverse(c, true, false));
    }
    ASSERT_NO_FATAL_FAILURE(check(reverse_x ? 60 : 64, reverse_x ? 44 : 48, 6));
  }
  // The frame has colour, so Cb and Cr (and their order) were tested.
  const std::vector<uint8_t> f = GrabAt(c, "YCbCr422_8", 6);
  size_t chroma_off = 0, cb_is_cr = 0;
  for (size_t i = 0; i + 3 < f.size(); i += 4) {
    chroma_off += f[i + 1] != 128 || f[i + 3] != 128;
    cb_is_cr += f[i + 1] == f[i + 3];
  }
  EXPECT_GT(chroma_off, f.size() / 8);
  EXPECT_LT(cb_is_cr, f.size() / 8);
  {
    SCOPED_TRACE("TestPattern GreyDiagonalRamp");
    Set(c, "TestPattern", "GreyDiagonalRamp");
    ASSERT_NO_FATAL_FAILURE(check(60, 44, 2));
    const std::vector<uint8_t> grey = GrabAt(c, "YUV422_8", 2);
    for (size_t i = 0; i + 3 < grey.size(); i += 4) {
      ASSERT_EQ(grey[i + 1], 128) << i;
      ASSERT_EQ(grey[i + 3], 128) << i;
    }
    Set(c, "TestPattern", "Off");
  }
  // Odd widths: Width and OffsetX step by 2 on a Bayer sensor, so every row
  // holds whole pixel pairs; a client write of 61 is refused with its reason.
  Set(c, "PixelFormat", "YCbCr422_8");
  Settle();
  EXPECT_EQ(ReadInt(c, "Width"), 60);
  testing::internal::CaptureStderr();
  ASSERT_NO_FATAL_FAILURE(WriteRegRefused(*device_, reg::kWidth, Be32(61)));
  const std::string err = testing::internal::GetCapturedStderr();
  EXPECT_NE(err.find("refused Width = 61: off its increment 2"), std::string::npos) << err;
  Settle();
  EXPECT_EQ(ReadInt(c, "Width"), 60);
}

// DeviceTemperature (SFNC, DeviceTemperatureSelector Sensor) is the sensor's
// configured temperature, sensor.temperature_c (which sets the dark
// current): read-only, a write refused as read-only.
TEST_F(GigeE2E, DeviceTemperatureIsTheSensorsConfiguredTemperature) {
  DeviceOptions o = SmallDevice();
  o.overrides.push_back("sensor.temperature_c=41.5");
  ASSERT_NO_FATAL_FAILURE(StartWith(o));
  Client& c = *client_;
  EXPECT_STREQ(arv_camera_get_string(c.camera(), "DeviceTemperatureSelector", nullptr), "Sensor");
  Set(c, "DeviceTemperatureSelector", "Sensor");
  GError* e = nullptr;
  EXPECT_DOUBLE_EQ(arv_camera_get_float(c.camera(), "DeviceTemperature", &e), 41.5);
  ASSERT_EQ(e, nullptr) << e->message;
  double lo = 0, hi = 0;
  arv_camera_get_float_bounds(c.camera(), "DeviceTemperature", &lo, &hi, nullptr);
  EXPECT_EQ(lo, -100.0);
  EXPECT_EQ(hi, 150.0);
  arv_device_write_memory(c.device(), reg::kDeviceTemperature, 8, Be64(20.0).data(), &e);
  EXPECT_TRUE(g_error_matches(e, ARV_DEVICE_ERROR, ARV_DEVICE_ERROR_PROTOCOL_ERROR_WRITE_PROTECT))
      << (e != nullptr ? e->message : "no error: DeviceTemperature was written");
  g_clear_error(&e);
  Settle();
  EXPECT_DOUBLE_EQ(ReadFloat(c, "DeviceTemperature"), 41.5);
}

// TriggerSoftware is available (the XML's pIsAvailable) only with
// TriggerMode On and TriggerSource Software; elsewhere a raw write is
// refused (access denied) with a line naming why, and gives no frame. In
// trigger mode with the acquisition stopped it is acknowledged and dropped
// (counted, logged): the acquisition started after it waits for a trigger.
TEST_F(GigeE2E, TriggerSoftwareIsAvailableOnlyWhereItTriggers) {
  ASSERT_NO_FATAL_FAILURE(StartWithTriggerLine());  // TriggerSource Line0 is available
  Client& c = *client_;
  ArvGcNode* node = arv_gc_get_node(arv_device_get_genicam(c.device()), "TriggerSoftware");
  ASSERT_NE(node, nullptr);
  const auto available = [&] { return arv_gc_feature_node_is_available(ARV_GC_FEATURE_NODE(node), nullptr); };
  // Refused, with the reason logged; and no frame from it.
  const auto refused = [&](const char* why) {
    testing::internal::CaptureStderr();
    GError* e = nullptr;
    arv_device_write_register(c.device(), reg::kTriggerSoftware, 1, &e);
    const std::string err = testing::internal::GetCapturedStderr();
    EXPECT_TRUE(g_error_matches(e, ARV_DEVICE_ERROR, ARV_DEVICE_ERROR_PROTOCOL_ERROR_ACCESS_DENIED))
        << (e != nullptr ? e->message : "no error: TriggerSoftware taken");
    g_clear_error(&e);
    EXPECT_NE(err.find(std::string("camsim-gige: refused TriggerSoftware = 1: not available: ") + why),
              std::string::npos)
        << err;
  };
  EXPECT_FALSE(available()) << "TriggerMode Off";
  // Free run: a refused trigger leaves the frames as they come.
  SetFloat(c, "AcquisitionFrameRate", 2.0);
  ASSERT_TRUE(c.OpenStream());
  Start(c);
  ASSERT_FALSE(c.Grab(3000).empty());
  ASSERT_NO_FATAL_FAILURE(refused("TriggerMode is Off"));
  GError* e = nullptr;
  arv_camera_stop_acquisition(c.camera(), &e);
  ASSERT_EQ(e, nullptr);
  c.CloseStream();
  TriggerOn("Line0");
  EXPECT_FALSE(available()) << "TriggerSource Line0";
  ASSERT_NO_FATAL_FAILURE(refused("TriggerSource is Line0"));
  Set(c, "TriggerSource", "Software");
  EXPECT_TRUE(available()) << "TriggerMode On, TriggerSource Software";
  Settle();
  EXPECT_EQ(device_->writes_refused(), 2u);
  // Stopped: acknowledged, dropped, counted and logged.
  const uint64_t sent = device_->frames_sent();
  testing::internal::CaptureStderr();
  arv_camera_execute_command(c.camera(), "TriggerSoftware", &e);
  const std::string err = testing::internal::GetCapturedStderr();
  EXPECT_EQ(e, nullptr) << e->message;
  g_clear_error(&e);
  EXPECT_NE(err.find("camsim-gige: dropped TriggerSoftware: the acquisition is stopped"), std::string::npos) << err;
  EXPECT_EQ(device_->triggers_dropped(), 1u);
  ASSERT_TRUE(c.OpenStream());
  Start(c);
  EXPECT_TRUE(c.Grab(400).empty()) << "a frame for the trigger sent while stopped";
  ASSERT_TRUE(SendTriggerSoftware());
  EXPECT_FALSE(c.Grab(3000).empty()) << "no frame for a trigger while acquiring";
  EXPECT_TRUE(c.Grab(400).empty());
  EXPECT_EQ(device_->frames_sent(), sent + 1);
  EXPECT_EQ(device_->writes_refused(), 2u);
}

// Gamma (SFNC: Y' = Y^Gamma) with GammaEnable drives the ISP's gamma stage:
// on, the RGB8 frame is the core's with the power curve of gamma 1 / Gamma
// (`camsim run --set gamma.curve="power" --set gamma.gamma=2` for Gamma
// 0.5), byte for byte; off, the configured sRGB curve. Gamma below 1
// brightens. The raw format does not change; out-of-range values are refused.
TEST_F(GigeE2E, GammaDrivesTheIspsGammaStage) {
  ASSERT_NO_FATAL_FAILURE(StartWith(SmallDevice()));
  Client& c = *client_;
  EXPECT_FALSE(arv_camera_get_boolean(c.camera(), "GammaEnable", nullptr));
  EXPECT_DOUBLE_EQ(ReadFloat(c, "Gamma"), 1.0 / 2.2);  // the core's default power-curve gamma
  const auto mean = [](const std::vector<uint8_t>& f) {
    double sum = 0;
    for (const uint8_t v : f) sum += v;
    return f.empty() ? 0.0 : sum / static_cast<double>(f.size());
  };
  const std::vector<uint8_t> raw_off = GrabAt(c, "BayerRG12", 6);
  const std::vector<uint8_t> off = GrabAt(c, "RGB8", 6);
  ASSERT_EQ(off.size(), size_t{64} * 48 * 3);
  EXPECT_TRUE(off == Reference(6, genicam::kRGB8, 0, 0, 64, 48)) << "GammaEnable off: the configured sRGB curve";
  // Gamma is available only with GammaEnable on (it would do nothing off):
  // the XML says so, and the device refuses a raw write, access denied.
  ArvGcNode* gamma = arv_device_get_feature(c.device(), "Gamma");
  ASSERT_NE(gamma, nullptr);
  EXPECT_FALSE(arv_gc_feature_node_is_available(ARV_GC_FEATURE_NODE(gamma), nullptr));
  const auto gamma_refused = [&] {
    testing::internal::CaptureStderr();
    GError* e = nullptr;
    std::vector<uint8_t> b = Be64(0.5);
    arv_device_write_memory(c.device(), reg::kGamma, 8, b.data(), &e);
    const std::string err = testing::internal::GetCapturedStderr();
    EXPECT_TRUE(g_error_matches(e, ARV_DEVICE_ERROR, ARV_DEVICE_ERROR_PROTOCOL_ERROR_ACCESS_DENIED))
        << (e != nullptr ? e->message : "no error: Gamma taken with GammaEnable off");
    g_clear_error(&e);
    EXPECT_NE(err.find("refused Gamma = 0.5: not available: GammaEnable is false (available while GammaEnable is "
                       "true)"),
              std::string::npos)
        << err;
  };
  ASSERT_NO_FATAL_FAILURE(gamma_refused());
  EXPECT_DOUBLE_EQ(ReadRegDouble(*device_, reg::kGamma), 1.0 / 2.2);
  arv_camera_set_boolean(c.camera(), "GammaEnable", TRUE, nullptr);
  EXPECT_TRUE(arv_gc_feature_node_is_available(ARV_GC_FEATURE_NODE(gamma), nullptr));
  SetFloat(c, "Gamma", 0.5);
  Settle();
  EXPECT_TRUE(arv_camera_get_boolean(c.camera(), "GammaEnable", nullptr));
  const std::vector<uint8_t> bright = GrabIndex(c, 6);
  EXPECT_TRUE(bright == Reference(6, genicam::kRGB8, 0, 0, 64, 48, {"gamma.curve=\"power\"", "gamma.gamma=2"}))
      << "Gamma 0.5 is not the power curve of gamma 2";
  EXPECT_FALSE(bright == off);
  SetFloat(c, "Gamma", 2.0);
  Settle();
  const std::vector<uint8_t> dark = GrabIndex(c, 6);
  EXPECT_TRUE(dark == Reference(6, genicam::kRGB8, 0, 0, 64, 48, {"gamma.curve=\"power\"", "gamma.gamma=0.5"}))
      << "Gamma 2 is not the power curve of gamma 0.5";
  EXPECT_GT(mean(bright), mean(dark) + 20) << "Y' = Y^Gamma: Gamma 0.5 brightens, 2 darkens";
  EXPECT_TRUE(GrabAt(c, "BayerRG12", 6) == raw_off) << "the raw format changed with Gamma";
  GError* e = nullptr;
  for (const double bad : {0.05, 10.5}) {
    arv_camera_set_float(c.camera(), "Gamma", bad, &e);
    EXPECT_TRUE(g_error_matches(e, ARV_DEVICE_ERROR, ARV_DEVICE_ERROR_PROTOCOL_ERROR_INVALID_PARAMETER))
        << bad << ": " << (e != nullptr ? e->message : "no error");
    g_clear_error(&e);
  }
  EXPECT_DOUBLE_EQ(ReadFloat(c, "Gamma"), 2.0);
  arv_camera_set_boolean(c.camera(), "GammaEnable", FALSE, nullptr);
  Settle();
  EXPECT_TRUE(GrabAt(c, "RGB8", 6) == off) << "GammaEnable off again: the configured curve";
  ASSERT_NO_FATAL_FAILURE(gamma_refused());
  EXPECT_DOUBLE_EQ(ReadRegDouble(*device_, reg::kGamma), 2.0);
}

// ---------------------------------------------------------------- user sets

// A user set file's path for this test (none there yet).
std::string UserSetFile(const char* name) {
  const std::string path = testing::TempDir() + "camsim-usersets-" + name + "-" + std::to_string(getpid()) + ".txt";
  std::remove(path.c_str());
  return path;
}
std::string ReadText(const std::string& path) {
  std::ifstream in(path);
  return std::string(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
}
// A raw write of a command register: its status (nullptr: done).
GError* Execute(Client& c, uint32_t address) {
  GError* e = nullptr;
  arv_device_write_register(c.device(), address, 1, &e);
  return e;
}

// UserSetSave keeps the window, format, exposure and gain; UserSetLoad
// brings them back, and the frames are the set's (byte for byte the core's
// frame with the set's exposure and gain in its window). Default loads the
// start-up configuration and cannot be saved; a load while acquiring is
// refused (locked like the payload's features).
TEST_F(GigeE2E, UserSetsSaveAndLoadTheirSettings) {
  ASSERT_NO_FATAL_FAILURE(StartWith(SmallDevice()));
  Client& c = *client_;
  EXPECT_STREQ(arv_camera_get_string(c.camera(), "UserSetSelector", nullptr), "Default");
  EXPECT_STREQ(arv_camera_get_string(c.camera(), "UserSetDefault", nullptr), "Default");
  ArvGc* gc = arv_device_get_genicam(c.device());
  ArvGcNode* save = arv_gc_get_node(gc, "UserSetSave");
  ArvGcNode* load = arv_gc_get_node(gc, "UserSetLoad");
  ASSERT_NE(save, nullptr);
  ASSERT_NE(load, nullptr);
  EXPECT_FALSE(arv_gc_feature_node_is_available(ARV_GC_FEATURE_NODE(save), nullptr)) << "Default is read-only";
  // Default cannot be saved: refused, the reason logged.
  testing::internal::CaptureStderr();
  GError* e = Execute(c, reg::kUserSetSave);
  std::string err = testing::internal::GetCapturedStderr();
  EXPECT_TRUE(g_error_matches(e, ARV_DEVICE_ERROR, ARV_DEVICE_ERROR_PROTOCOL_ERROR_ACCESS_DENIED))
      << (e != nullptr ? e->message : "no error: Default saved");
  g_clear_error(&e);
  EXPECT_NE(err.find("camsim-gige: refused UserSetSave[Default]: not available: UserSetSelector is Default"),
            std::string::npos)
      << err;

  GError* r = nullptr;
  arv_camera_set_region(c.camera(), 8, 6, 32, 24, &r);
  ASSERT_EQ(r, nullptr);
  Set(c, "PixelFormat", "BayerRG8");
  SetFloat(c, "ExposureTime", 5000.0);
  SetFloat(c, "Gain", 3.0);
  Set(c, "UserSetSelector", "UserSet1");
  EXPECT_TRUE(arv_gc_feature_node_is_available(ARV_GC_FEATURE_NODE(save), nullptr));
  arv_camera_execute_command(c.camera(), "UserSetSave", &e);
  ASSERT_EQ(e, nullptr) << e->message;
  // Other settings, then the set again.
  arv_camera_set_region(c.camera(), 0, 0, 64, 48, &r);
  ASSERT_EQ(r, nullptr);
  Set(c, "PixelFormat", "BayerRG12");
  SetFloat(c, "ExposureTime", 20000.0);
  SetFloat(c, "Gain", 0.0);
  Settle();
  arv_camera_execute_command(c.camera(), "UserSetLoad", &e);
  ASSERT_EQ(e, nullptr) << e->message;
  Settle();
  EXPECT_EQ(ReadInt(c, "Width"), 32);
  EXPECT_EQ(ReadInt(c, "Height"), 24);
  EXPECT_EQ(ReadInt(c, "OffsetX"), 8);
  EXPECT_EQ(ReadInt(c, "OffsetY"), 6);
  EXPECT_STREQ(arv_camera_get_pixel_format_as_string(c.camera(), nullptr), "BayerRG8");
  EXPECT_DOUBLE_EQ(ReadFloat(c, "ExposureTime"), 5000.0);
  EXPECT_DOUBLE_EQ(ReadFloat(c, "Gain"), 3.0);
  EXPECT_EQ(ReadInt(c, "GainRaw"), 30);
  EXPECT_EQ(ReadInt(c, "PayloadSize"), 32 * 24);
  const std::vector<uint8_t> f = GrabIndex(c, 3);
  const uint32_t rg8 = genicam::BayerCode(Cfa::kBayerRG, 8);
  EXPECT_TRUE(f == Reference(3, rg8, 8, 6, 32, 24, {"exposure.exposure_time_us=5000.0", "sensor.gain_db=3.0"}))
      << "not the set's frame";
  // Load while acquiring: refused, locked in the XML.
  ASSERT_TRUE(c.OpenStream());
  Start(c);
  ASSERT_FALSE(c.Grab(3000).empty());
  EXPECT_TRUE(arv_gc_feature_node_is_locked(ARV_GC_FEATURE_NODE(load), nullptr));
  Set(c, "UserSetSelector", "Default");
  testing::internal::CaptureStderr();
  e = Execute(c, reg::kUserSetLoad);
  err = testing::internal::GetCapturedStderr();
  EXPECT_TRUE(g_error_matches(e, ARV_DEVICE_ERROR, ARV_DEVICE_ERROR_PROTOCOL_ERROR_ACCESS_DENIED))
      << (e != nullptr ? e->message : "no error: loaded while acquiring");
  g_clear_error(&e);
  EXPECT_NE(err.find("camsim-gige: refused UserSetLoad[Default]: acquisition running"), std::string::npos) << err;
  arv_camera_stop_acquisition(c.camera(), &e);
  ASSERT_EQ(e, nullptr);
  c.CloseStream();
  Settle();
  EXPECT_EQ(ReadInt(c, "Width"), 32) << "a refused load changed the window";
  // Default: the start-up configuration.
  EXPECT_FALSE(arv_gc_feature_node_is_locked(ARV_GC_FEATURE_NODE(load), nullptr));
  arv_camera_execute_command(c.camera(), "UserSetLoad", &e);
  ASSERT_EQ(e, nullptr) << e->message;
  Settle();
  EXPECT_EQ(ReadInt(c, "Width"), 64);
  EXPECT_EQ(ReadInt(c, "OffsetX"), 0);
  EXPECT_STREQ(arv_camera_get_pixel_format_as_string(c.camera(), nullptr), "BayerRG12");
  EXPECT_DOUBLE_EQ(ReadFloat(c, "ExposureTime"), 10000.0);
  EXPECT_DOUBLE_EQ(ReadFloat(c, "Gain"), 0.0);
  EXPECT_EQ(ReadInt(c, "UserSetLoad"), 0) << "a command reads back 0 (done)";
}

// A set holds the trigger's ExposureMode and the lines' inverter and
// debouncer. TriggerWidth locks TriggerMode, TriggerSource and ExposureAuto,
// so a load sets ExposureMode Timed first and the set's value last: a set
// saved under TriggerWidth loads back, and one with TriggerMode Off loads
// while TriggerWidth is on.
TEST_F(GigeE2E, UserSetsHoldTriggerWidthAndTheLines) {
  ASSERT_NO_FATAL_FAILURE(StartWithTriggerLine());
  Client& c = *client_;
  TriggerOn("Line0");
  Set(c, "LineSelector", "Line0");
  arv_camera_set_boolean(c.camera(), "LineInverter", TRUE, nullptr);  // before TriggerWidth, which locks it
  SetFloat(c, "LineDebouncerTime", 1500.0);
  Set(c, "ExposureMode", "TriggerWidth");
  Settle();
  ASSERT_STREQ(arv_camera_get_string(c.camera(), "ExposureMode", nullptr), "TriggerWidth");
  Set(c, "UserSetSelector", "UserSet1");
  GError* e = nullptr;
  arv_camera_execute_command(c.camera(), "UserSetSave", &e);
  ASSERT_EQ(e, nullptr) << e->message;
  // Back to Timed with a Software source and the lines as at start.
  Set(c, "ExposureMode", "Timed");
  Set(c, "TriggerSource", "Software");
  arv_camera_set_boolean(c.camera(), "LineInverter", FALSE, nullptr);
  SetFloat(c, "LineDebouncerTime", 0.0);
  Settle();
  arv_camera_execute_command(c.camera(), "UserSetLoad", &e);
  ASSERT_EQ(e, nullptr) << e->message;
  Settle();
  EXPECT_STREQ(arv_camera_get_string(c.camera(), "ExposureMode", nullptr), "TriggerWidth");
  EXPECT_STREQ(arv_camera_get_string(c.camera(), "TriggerSource", nullptr), "Line0");
  Set(c, "LineSelector", "Line0");
  EXPECT_TRUE(arv_camera_get_boolean(c.camera(), "LineInverter", nullptr));
  EXPECT_DOUBLE_EQ(ReadFloat(c, "LineDebouncerTime"), 1500.0);
  // LineDebouncerTime is Line0's: a write at Line1 is refused, and a load
  // with the selector at Line1 still sets it (and leaves the selector there).
  Set(c, "LineSelector", "Line0");
  SetFloat(c, "LineDebouncerTime", 0.0);
  Set(c, "LineSelector", "Line1");
  arv_device_write_memory(c.device(), reg::kLineDebouncerTime, 8, Be64(9000.0).data(), &e);
  EXPECT_TRUE(g_error_matches(e, ARV_DEVICE_ERROR, ARV_DEVICE_ERROR_PROTOCOL_ERROR_ACCESS_DENIED)) << "at Line1";
  g_clear_error(&e);
  Set(c, "UserSetSelector", "UserSet1");
  arv_camera_execute_command(c.camera(), "UserSetLoad", &e);
  ASSERT_EQ(e, nullptr) << e->message;
  Settle();
  EXPECT_STREQ(arv_camera_get_string(c.camera(), "LineSelector", nullptr), "Line1");
  Set(c, "LineSelector", "Line0");
  EXPECT_DOUBLE_EQ(ReadFloat(c, "LineDebouncerTime"), 1500.0);
  // UserSet2, never saved, holds Default's: Timed, TriggerMode Off.
  Set(c, "UserSetSelector", "UserSet2");
  arv_camera_execute_command(c.camera(), "UserSetLoad", &e);
  ASSERT_EQ(e, nullptr) << e->message;
  Settle();
  EXPECT_STREQ(arv_camera_get_string(c.camera(), "ExposureMode", nullptr), "Timed");
  EXPECT_STREQ(arv_camera_get_string(c.camera(), "TriggerMode", nullptr), "Off");
  Set(c, "LineSelector", "Line0");
  EXPECT_FALSE(arv_camera_get_boolean(c.camera(), "LineInverter", nullptr));
}

// A set with binning, decimation, a window and ReverseX loads back to the
// same readout: the reductions before the window, the window before the
// mirror, the Bayer phase the mirror gives. Frame 4 grabbed after the load
// equals frame 4 grabbed before the save.
TEST_F(GigeE2E, UserSetsHoldBinningDecimationAndTheMirroredWindow) {
  ASSERT_NO_FATAL_FAILURE(StartWith(SmallDevice()));
  Client& c = *client_;
  SetInt(c, "BinningHorizontal", 2);
  SetInt(c, "DecimationVertical", 2);
  GError* e = nullptr;
  arv_camera_set_region(c.camera(), 8, 4, 16, 12, &e);
  ASSERT_EQ(e, nullptr) << e->message;
  arv_camera_set_boolean(c.camera(), "ReverseX", TRUE, &e);
  ASSERT_EQ(e, nullptr) << e->message;
  Set(c, "PixelFormat", "BayerGR12");  // BayerRG's phase under ReverseX
  Settle();
  const std::vector<uint8_t> before = GrabIndex(c, 4);
  ASSERT_EQ(before.size(), 16u * 12 * 2);
  Set(c, "UserSetSelector", "UserSet1");
  arv_camera_execute_command(c.camera(), "UserSetSave", &e);
  ASSERT_EQ(e, nullptr) << e->message;
  Set(c, "UserSetSelector", "Default");
  arv_camera_execute_command(c.camera(), "UserSetLoad", &e);
  ASSERT_EQ(e, nullptr) << e->message;
  Settle();
  ASSERT_EQ(ReadInt(c, "BinningHorizontal"), 1);
  ASSERT_EQ(ReadInt(c, "Width"), 64);
  Set(c, "UserSetSelector", "UserSet1");
  arv_camera_execute_command(c.camera(), "UserSetLoad", &e);
  ASSERT_EQ(e, nullptr) << e->message;
  Settle();
  EXPECT_EQ(ReadInt(c, "BinningHorizontal"), 2);
  EXPECT_EQ(ReadInt(c, "DecimationVertical"), 2);
  EXPECT_EQ(ReadInt(c, "WidthMax"), 32);
  EXPECT_EQ(ReadInt(c, "HeightMax"), 24);
  EXPECT_EQ(ReadInt(c, "OffsetX"), 8);
  EXPECT_EQ(ReadInt(c, "OffsetY"), 4);
  EXPECT_EQ(ReadInt(c, "Width"), 16);
  EXPECT_EQ(ReadInt(c, "Height"), 12);
  EXPECT_TRUE(arv_camera_get_boolean(c.camera(), "ReverseX", nullptr));
  EXPECT_STREQ(arv_camera_get_pixel_format_as_string(c.camera(), nullptr), "BayerGR12");
  EXPECT_TRUE(GrabIndex(c, 4) == before) << "not the saved readout's frame";
}

// A set that changes exposure under ExposureAuto Continuous loads the value
// first and turns the Auto feature on last; a load goes through the
// client's checks, so a set whose window the sensor cannot take is refused
// whole (here a set written into a file for a larger sensor).
TEST_F(GigeE2E, UserSetDefaultFromTheFileSurvivesARestart) {
  DeviceOptions o = SmallDevice();
  o.user_set_file = UserSetFile("restart");
  ASSERT_NO_FATAL_FAILURE(StartWith(o));
  Client* c = client_.get();
  GError* r = nullptr;
  arv_camera_set_region(c->camera(), 4, 2, 40, 30, &r);
  ASSERT_EQ(r, nullptr);
  SetFloat(*c, "ExposureTime", 4000.0);
  Set(*c, "UserSetSelector", "UserSet2");
  GError* e = nullptr;
  arv_camera_execute_command(c->camera(), "UserSetSave", &e);
  ASSERT_EQ(e, nullptr) << e->message;
  Set(*c, "UserSetDefault", "UserSet2");
  const std::string text = ReadText(o.user_set_file);
  EXPECT_NE(text.find("UserSetDefault = UserSet2\n"), std::string::npos) << text;
  EXPECT_NE(text.find("[UserSet2]\nWidth = 40\nHeight = 30\nOffsetX = 4\nOffsetY = 2\n"), std::string::npos) << text;
  EXPECT_NE(text.find("ExposureTime = 4000\n"), std::string::npos) << text;
  EXPECT_EQ(text.find("[UserSet1]"), std::string::npos) << "a set never saved is not written";
  // A second device (a power cycle) on the same file starts with UserSet2.
  client_.reset();
  device_.reset();
  ASSERT_NO_FATAL_FAILURE(StartWith(o));
  c = client_.get();
  EXPECT_STREQ(arv_camera_get_string(c->camera(), "UserSetDefault", nullptr), "UserSet2");
  EXPECT_EQ(ReadInt(*c, "Width"), 40);
  EXPECT_EQ(ReadInt(*c, "OffsetY"), 2);
  EXPECT_DOUBLE_EQ(ReadFloat(*c, "ExposureTime"), 4000.0);
  const uint32_t rg12 = genicam::BayerCode(Cfa::kBayerRG, 12);
  EXPECT_TRUE(GrabIndex(*c, 5) == Reference(5, rg12, 4, 2, 40, 30, {"exposure.exposure_time_us=4000.0"}))
      << "not the set's frame after a restart";
  // Without the file, a new device starts from the configuration.
  client_.reset();
  device_.reset();
  ASSERT_NO_FATAL_FAILURE(StartWith(SmallDevice()));
  EXPECT_EQ(ReadInt(*client_, "Width"), 64);
  std::remove(o.user_set_file.c_str());
}

// The start-up line (camsim-gige's "serving ..., loaded X") names the set
// the start loaded: UserSetDefault's set from --user-set-file, or Default
// and why.
TEST(GigeRegisters, TheStartSaysWhichUserSetItLoaded) {
  DeviceOptions o = OfflineDevice();
  auto d = StartDevice(o);
  ASSERT_NE(d, nullptr);
  EXPECT_EQ(d->start_user_set(), "the Default user set (no --user-set-file)");
  o.user_set_file = UserSetFile("start");
  d = StartDevice(o);
  ASSERT_NE(d, nullptr);
  EXPECT_EQ(d->start_user_set(), "the Default user set (no " + o.user_set_file + " yet)");
  std::ofstream(o.user_set_file) << "[UserSet2]\nWidth = 32\n";
  d = StartDevice(o);
  ASSERT_NE(d, nullptr);
  EXPECT_EQ(d->start_user_set(), "the Default user set (" + o.user_set_file + " names no UserSetDefault)");
  std::ofstream(o.user_set_file) << "UserSetDefault = Default\n[UserSet2]\nWidth = 32\n";
  d = StartDevice(o);
  ASSERT_NE(d, nullptr);
  EXPECT_EQ(d->start_user_set(), "the Default user set (UserSetDefault is Default in " + o.user_set_file + ")");
  std::ofstream(o.user_set_file) << "UserSetDefault = UserSet2\n[UserSet2]\nWidth = 32\n";
  d = StartDevice(o);
  ASSERT_NE(d, nullptr);
  EXPECT_EQ(d->start_user_set(), "user set UserSet2 from " + o.user_set_file + " (its UserSetDefault)");
  EXPECT_EQ(ReadReg32(*d, reg::kWidth), 32u);
  d.reset();
  std::remove(o.user_set_file.c_str());
}

// A scene or a flare environment map whose samples the reader replaced
// (NaN, inf, negative) is named on stderr at the start, as `camsim run`
// names them; camsim-gige replaced them silently.
TEST(GigeRegisters, ReplacedInputSamplesAreWarnedAboutAtTheStart) {
  const std::string dir = testing::TempDir();
  const std::string scene = dir + "camsim-dirty-scene-" + std::to_string(getpid()) + ".exr";
  const std::string env = dir + "camsim-dirty-env-" + std::to_string(getpid()) + ".exr";
  std::vector<float> grey(64 * 48, 0.5f);
  std::vector<float> red = grey;
  red[64 * 2 + 3] = std::nanf("");
  test::WriteExrFixture(scene, test::Box(0, 0, 63, 47), test::Box(0, 0, 63, 47),
                        {{"R", Imf::FLOAT, red}, {"G", Imf::FLOAT, grey}, {"B", Imf::FLOAT, grey}});
  std::vector<float> sky(8 * 4, 1.0f), blue = sky;
  blue[6] = -2.0f;
  test::WriteExrFixture(env, test::Box(0, 0, 7, 3), test::Box(0, 0, 7, 3),
                        {{"R", Imf::FLOAT, sky}, {"G", Imf::FLOAT, sky}, {"B", Imf::FLOAT, blue}});
  DeviceOptions o = OfflineDevice();
  o.pattern.clear();
  o.inputs = {scene};
  o.overrides.push_back("flare.enabled=true");
  o.overrides.push_back("flare.environment_map=\"" + env + "\"");
  testing::internal::CaptureStderr();
  auto d = StartDevice(o);
  const std::string log = testing::internal::GetCapturedStderr();
  ASSERT_NE(d, nullptr) << log;
  EXPECT_NE(log.find("camsim-gige: warning: '" + scene +
                     "': 1 NaN colour sample replaced (first: channel R at x=3, y=2)\n"),
            std::string::npos)
      << log;
  EXPECT_NE(log.find("camsim-gige: warning: flare.environment_map '" + env +
                     "': 1 negative colour sample replaced (first: channel B at x=6, y=0)\n"),
            std::string::npos)
      << log;
  d.reset();
  std::remove(scene.c_str());
  std::remove(env.c_str());
}

// A user set file that is not what the device can load stops the start,
// naming the file, the line and the feature: an unknown feature, a value
// out of its range, a line that is not 'Feature = value', Default as a
// section, and a set the sensor cannot take (its window off the sensor:
// found by loading it through the client's checks).
TEST(GigeRegisters, ABadUserSetFileStopsTheStartNamingIt) {
  DeviceOptions o = OfflineDevice();
  o.user_set_file = UserSetFile("bad");
  const auto start_error = [&](const std::string& text) {
    std::ofstream(o.user_set_file) << text;
    std::string error;
    testing::internal::CaptureStderr();
    auto d = GigeDevice::Start(o, &error);
    testing::internal::GetCapturedStderr();
    EXPECT_EQ(d, nullptr) << "started with:\n" << text;
    return error;
  };
  const std::string at = "--user-set-file " + o.user_set_file + ":";
  EXPECT_EQ(start_error("UserSetDefault = UserSet1\n[UserSet1]\nWidth = 32\nBrightness = 3\n"),
            at + "4: unknown feature 'Brightness' (not one a user set of this device holds)");
  EXPECT_EQ(start_error("[UserSet1]\n# a comment\nExposureTime = 0.5\n"),
            at + "3: ExposureTime = 0.5: out of range 1..1e+08");
  EXPECT_EQ(start_error("[UserSet3]\nPixelFormat = BayerGR12\n"),
            at + "2: PixelFormat = BayerGR12: entry BayerGR12 is not the phase this readout gives (ReverseX 0, "
                 "ReverseY 0)");
  EXPECT_EQ(start_error("[UserSet1]\nWidth 32\n"), at + "2: expected 'Feature = value', not 'Width 32'");
  EXPECT_EQ(start_error("[UserSet1]\nTriggerSource = Line0\n"),
            at + "2: TriggerSource = Line0: entry Line0 is not available: this camera has no trigger line (start it "
                 "with --trigger-line)");
  EXPECT_EQ(start_error("[Default]\nWidth = 32\n"),
            at + "1: [Default] is the start-up configuration, not a user set (UserSet1, UserSet2, UserSet3)");
  EXPECT_EQ(start_error("UserSetDefault = UserSet4\n"),
            at + "1: UserSetDefault = UserSet4: no such set (Default, UserSet1, UserSet2, UserSet3)");
  const std::string off = start_error("[UserSet2]\nWidth = 64\nOffsetX = 8\n");
  EXPECT_NE(off.find("--user-set-file " + o.user_set_file + ": [UserSet2]: OffsetX = 8: window off the sensor"),
            std::string::npos)
      << off;
  // A good file starts, with UserSetDefault's set loaded through the checks.
  std::ofstream(o.user_set_file)
      << "UserSetDefault = UserSet1\n[UserSet1]\nWidth = 32\nOffsetX = 32\nGain = 6\nLineInverter[Line1] = true\n";
  std::string error;
  auto d = GigeDevice::Start(o, &error);
  ASSERT_NE(d, nullptr) << error;
  EXPECT_EQ(ReadReg32(*d, reg::SelectedAddress(reg::kLineInverter, 1)), 1u) << "a Boolean written true";
  EXPECT_EQ(ReadReg32(*d, reg::kWidth), 32u);
  EXPECT_EQ(ReadReg32(*d, reg::kOffsetX), 32u);
  EXPECT_EQ(ReadReg32(*d, reg::kGainRaw), 60u);
  EXPECT_EQ(ReadReg32(*d, reg::kUserSetDefault), 1u);
  d->SyncNow();
  EXPECT_EQ(d->CheckInvariants(), "");
  d.reset();
  std::remove(o.user_set_file.c_str());
  // A directory it cannot write in stops the start (UserSetSave would fail later).
  o.user_set_file = "/camsim-no-such-dir/sets.txt";
  EXPECT_EQ(GigeDevice::Start(o, &error), nullptr);
  EXPECT_EQ(error, "--user-set-file /camsim-no-such-dir/sets.txt: cannot write in its directory /camsim-no-such-dir: "
                   "No such file or directory");
  // A file that can no longer be written: UserSetSave fails (GEV_STATUS_ERROR), saying why.
  const std::string dir = testing::TempDir() + "camsim-usersets-dir-" + std::to_string(getpid());
  ASSERT_EQ(mkdir(dir.c_str(), 0700), 0);
  o.user_set_file = dir + "/sets.txt";
  d = GigeDevice::Start(o, &error);
  ASSERT_NE(d, nullptr) << error << ": no file yet is no error";
  ASSERT_EQ(rmdir(dir.c_str()), 0);
  WriteReg(*d, reg::kUserSetSelector, Be32(1));
  testing::internal::CaptureStderr();
  WriteRegRefused(*d, reg::kUserSetSave, Be32(1));
  const std::string log = testing::internal::GetCapturedStderr();
  EXPECT_NE(log.find("refused UserSetSave[UserSet1]: the user set file: cannot write '" + o.user_set_file + "'"),
            std::string::npos)
      << log;
}


// A --user-set-file saved by a camera started with another configuration
// stops the start, naming the file, the line and the feature: a window
// saved on a 64 x 48 sensor does not fit a 32 x 24 one, and TriggerSource
// Line0 needs a trigger line.
TEST(GigeRegisters, AUserSetFileOfAnotherCameraStopsTheStartNamingTheLine) {
  hal::MemoryLine line("test-trigger");
  DeviceOptions o = OfflineDevice();  // 64 x 48
  o.trigger = &line;
  o.user_set_file = UserSetFile("other");
  {
    auto d = StartDevice(o);
    ASSERT_NE(d, nullptr);
    WriteReg(*d, reg::kWidth, Be32(48));
    WriteReg(*d, reg::kTriggerSource, Be32(genicam::kSourceLine0));
    WriteReg(*d, reg::kUserSetSelector, Be32(1));
    WriteReg(*d, reg::kUserSetSave, Be32(1));
  }
  const std::string text = ReadText(o.user_set_file);
  // The number of the file's line that starts with `start`.
  const auto line_of = [&text](const std::string& start) {
    int n = 1;
    for (size_t at = 0; at < text.size(); at = text.find('\n', at) + 1, ++n) {
      if (text.compare(at, start.size(), start) == 0) return n;
      if (text.find('\n', at) == std::string::npos) break;
    }
    return 0;
  };
  ASSERT_GT(line_of("Width = 48"), 0) << text;
  ASSERT_GT(line_of("TriggerSource = Line0"), 0) << text;
  const auto start_error = [&](const DeviceOptions& other) {
    std::string error;
    testing::internal::CaptureStderr();
    auto d = GigeDevice::Start(other, &error);
    testing::internal::GetCapturedStderr();
    EXPECT_EQ(d, nullptr) << "started with:\n" << text;
    return error;
  };
  const std::string at = "--user-set-file " + o.user_set_file + ":";
  DeviceOptions smaller = o;
  smaller.overrides = SmallDevice(32, 24).overrides;
  const std::string window = start_error(smaller);
  EXPECT_EQ(window.rfind(at + std::to_string(line_of("Width = 48")) + ": Width = 48: ", 0), 0u) << window;
  DeviceOptions no_line = o;
  no_line.trigger = nullptr;
  EXPECT_EQ(start_error(no_line), at + std::to_string(line_of("TriggerSource = Line0")) +
                                      ": TriggerSource = Line0: entry Line0 is not available: this camera has no "
                                      "trigger line (start it with --trigger-line)");
  std::remove(o.user_set_file.c_str());
}

// A set saved with ExposureAuto Continuous loads it (last, after its
// ExposureTime, which the lock would refuse after it), and a set with
// ExposureAuto Off loads its ExposureTime while Continuous is in use
// (ExposureAuto goes Off first).
TEST(GigeRegisters, UserSetsHoldExposureAutoContinuous) {
  auto d = StartDevice(OfflineDevice());
  ASSERT_NE(d, nullptr);
  const auto save = [&](uint32_t set) {
    WriteReg(*d, reg::kUserSetSelector, Be32(set));
    WriteReg(*d, reg::kUserSetSave, Be32(1));
  };
  const auto load = [&](uint32_t set) {
    WriteReg(*d, reg::kUserSetSelector, Be32(set));
    WriteReg(*d, reg::kUserSetLoad, Be32(1));
  };
  WriteReg(*d, reg::kExposureTime, Be64(1500.0));
  save(1);  // Off, 1500 us
  WriteReg(*d, reg::kExposureTime, Be64(2500.0));
  WriteReg(*d, reg::kExposureAuto, Be32(genicam::kAutoContinuous));
  save(2);  // Continuous, 2500 us
  WriteRegRefused(*d, reg::kExposureTime, Be64(900.0));  // locked
  ASSERT_NO_FATAL_FAILURE(load(1));
  EXPECT_EQ(ReadReg32(*d, reg::kExposureAuto), static_cast<uint32_t>(genicam::kAutoOff));
  EXPECT_DOUBLE_EQ(ReadRegDouble(*d, reg::kExposureTime), 1500.0);
  ASSERT_NO_FATAL_FAILURE(load(2));
  EXPECT_EQ(ReadReg32(*d, reg::kExposureAuto), static_cast<uint32_t>(genicam::kAutoContinuous));
  EXPECT_DOUBLE_EQ(ReadRegDouble(*d, reg::kExposureTime), 2500.0);
  WriteRegRefused(*d, reg::kExposureTime, Be64(900.0));  // locked again
  d->SyncNow();
  EXPECT_EQ(d->CheckInvariants(), "");
}

// Gamma is available only with GammaEnable on, so a load writes GammaEnable
// on before the set's Gamma and the set's GammaEnable after: a set saved
// with GammaEnable off loads its Gamma while GammaEnable is off.
TEST(GigeRegisters, UserSetsHoldGammaWithGammaEnableOnOrOff) {
  auto d = StartDevice(OfflineDevice());
  ASSERT_NE(d, nullptr);
  const auto save = [&](uint32_t set) {
    WriteReg(*d, reg::kUserSetSelector, Be32(set));
    WriteReg(*d, reg::kUserSetSave, Be32(1));
  };
  const auto load = [&](uint32_t set) {
    WriteReg(*d, reg::kUserSetSelector, Be32(set));
    WriteReg(*d, reg::kUserSetLoad, Be32(1));
  };
  WriteReg(*d, reg::kGammaEnable, Be32(1));
  WriteReg(*d, reg::kGamma, Be64(0.5));
  save(1);  // on, 0.5
  WriteReg(*d, reg::kGammaEnable, Be32(0));
  save(2);  // off, 0.5
  WriteReg(*d, reg::kGammaEnable, Be32(1));
  WriteReg(*d, reg::kGamma, Be64(2.0));
  WriteReg(*d, reg::kGammaEnable, Be32(0));
  WriteRegRefused(*d, reg::kGamma, Be64(3.0));  // not available
  ASSERT_NO_FATAL_FAILURE(load(2));
  EXPECT_EQ(ReadReg32(*d, reg::kGammaEnable), 0u);
  EXPECT_DOUBLE_EQ(ReadRegDouble(*d, reg::kGamma), 0.5);
  WriteReg(*d, reg::kGammaEnable, Be32(1));
  WriteReg(*d, reg::kGamma, Be64(2.0));
  WriteReg(*d, reg::kGammaEnable, Be32(0));
  ASSERT_NO_FATAL_FAILURE(load(1));
  EXPECT_EQ(ReadReg32(*d, reg::kGammaEnable), 1u);
  EXPECT_DOUBLE_EQ(ReadRegDouble(*d, reg::kGamma), 0.5);
  d->SyncNow();
  EXPECT_EQ(d->CheckInvariants(), "");
}

// ---------------------------------------------------------------- binning and decimation

// A frame of w x h little-endian 16-bit words as values, and back.
std::vector<uint32_t> Words(const std::vector<uint8_t>& f) {
  std::vector<uint32_t> v(f.size() / 2);
  for (size_t i = 0; i < v.size(); ++i) v[i] = f[2 * i] | f[2 * i + 1] << 8;
  return v;
}
std::vector<uint8_t> Bytes16(const std::vector<uint32_t>& v) {
  std::vector<uint8_t> f;
  for (const uint32_t x : v) {
    f.push_back(static_cast<uint8_t>(x & 0xff));
    f.push_back(static_cast<uint8_t>(x >> 8));
  }
  return f;
}

// Decimation from its definition: of the w x h frame's cells (2x2 on a
// Bayer sensor, pixels on mono or RGB), keep those whose cell column is a
// multiple of dx and whose cell row one of dy, in order.
std::vector<uint8_t> DecimatedCells(const std::vector<uint8_t>& f, int w, int h, int bytes, int cell, int dx, int dy) {
  std::vector<uint8_t> out;
  for (int y = 0; y < h; ++y) {
    if ((y / cell) % dy != 0 || (y / cell) / dy >= h / (cell * dy)) continue;  // (whole kept cells only)
    for (int x = 0; x < w; ++x)
      if ((x / cell) % dx == 0 && (x / cell) / dx < w / (cell * dx))
        out.insert(out.end(), f.begin() + (static_cast<ptrdiff_t>(y) * w + x) * bytes,
                   f.begin() + (static_cast<ptrdiff_t>(y) * w + x + 1) * bytes);
  }
  return out;
}

// Binning b x b from its definition, on a Bayer mosaic: split it into its
// four colour planes (plane (p, q) holds pixels (2u + p, 2v + q)), bin each
// plane b x b as a mono image (sum, or the average rounded half up), clamp
// at `full`, and interleave the planes again. cell 1: the frame is mono.
std::vector<uint32_t> Binned(const std::vector<uint32_t>& f, int w, int h, int cell, int b, bool average,
                             uint32_t full) {
  const int ow = w / (cell * b) * cell, oh = h / (cell * b) * cell;
  std::vector<uint32_t> out(static_cast<size_t>(ow) * oh);
  for (int q = 0; q < cell; ++q)
    for (int p = 0; p < cell; ++p) {
      const int pw = w / cell, ph = h / cell;  // the plane
      const auto plane = [&](int u, int v) { return f[static_cast<size_t>(v * cell + q) * w + u * cell + p]; };
      for (int v = 0; v < ph / b; ++v)
        for (int u = 0; u < pw / b; ++u) {
          uint32_t sum = 0;
          for (int l = 0; l < b; ++l)
            for (int k = 0; k < b; ++k) sum += plane(u * b + k, v * b + l);
          const uint32_t n = average ? static_cast<uint32_t>(b * b) : 1;
          out[static_cast<size_t>(v * cell + q) * ow + u * cell + p] = std::min((sum + n / 2) / n, full);
        }
    }
  return out;
}

// A w x h window at (x, y) of a frame of `fw` pixels of `bytes` bytes per row.
std::vector<uint8_t> WindowOf(const std::vector<uint8_t>& f, int fw, int bytes, int x, int y, int w, int h) {
  std::vector<uint8_t> out;
  for (int r = y; r < y + h; ++r)
    out.insert(out.end(), f.begin() + (static_cast<ptrdiff_t>(r) * fw + x) * bytes,
               f.begin() + (static_cast<ptrdiff_t>(r) * fw + x + w) * bytes);
  return out;
}

// DecimationHorizontal / DecimationVertical keep every Nth 2x2 cell of the
// Bayer readout: the frame is, byte for byte, the reference frame's cells
// subsampled (the same phase: the format stays BayerRG12), WidthMax,
// HeightMax and PayloadSize follow, a window too large for the new readout
// is reset to it (offsets 0) and a window that fits stays. RGB8 keeps every
// Nth pixel of the ISP's frame.
TEST_F(GigeE2E, DecimationKeepsEveryNthCfaCell) {
  ASSERT_NO_FATAL_FAILURE(StartWith(SmallDevice()));
  Client& c = *client_;
  const uint32_t code = genicam::BayerCode(Cfa::kBayerRG, 12);
  const std::vector<uint8_t> full = Reference(4, code, 0, 0, 64, 48);
  SetInt(c, "OffsetX", 0);
  SetInt(c, "Width", 60);
  SetInt(c, "OffsetX", 2);
  SetInt(c, "DecimationHorizontal", 2);
  // As the write is answered (the write filter), not only after a sync.
  EXPECT_EQ(ReadInt(c, "WidthMax"), 32);
  EXPECT_EQ(ReadInt(c, "Width"), 32) << "reset to the new readout";
  EXPECT_EQ(ReadInt(c, "OffsetX"), 0);
  SetInt(c, "DecimationVertical", 2);
  EXPECT_EQ(ReadInt(c, "HeightMax"), 24);
  EXPECT_EQ(ReadInt(c, "Height"), 24);
  Settle();
  EXPECT_EQ(ReadInt(c, "PayloadSize"), 32 * 24 * 2);
  uint32_t leader = 0;
  const std::vector<uint8_t> f = GrabIndex(c, 4, &leader);
  EXPECT_EQ(leader, code);
  const std::vector<uint8_t> want = DecimatedCells(full, 64, 48, 2, 2, 2, 2);
  ASSERT_EQ(want.size(), 32u * 24 * 2);
  EXPECT_TRUE(f == want) << "not the reference's every other 2x2 cell";
  // A window of the decimated readout.
  SetInt(c, "Width", 16);
  SetInt(c, "OffsetX", 8);
  SetInt(c, "Height", 12);
  SetInt(c, "OffsetY", 6);
  EXPECT_TRUE(GrabIndex(c, 4) == WindowOf(want, 32, 2, 8, 6, 16, 12));
  // Horizontal 4 only: the window (8 + 16 > 16) is reset on x; y keeps it.
  SetInt(c, "DecimationHorizontal", 4);
  SetInt(c, "DecimationVertical", 1);
  Settle();
  EXPECT_EQ(ReadInt(c, "WidthMax"), 16);
  EXPECT_EQ(ReadInt(c, "HeightMax"), 48);
  EXPECT_EQ(ReadInt(c, "Width"), 16);
  EXPECT_EQ(ReadInt(c, "OffsetX"), 0);
  EXPECT_EQ(ReadInt(c, "Height"), 12);
  EXPECT_EQ(ReadInt(c, "OffsetY"), 6);
  EXPECT_EQ(ReadInt(c, "PayloadSize"), 16 * 12 * 2);
  EXPECT_TRUE(GrabIndex(c, 4) == WindowOf(DecimatedCells(full, 64, 48, 2, 2, 4, 1), 16, 2, 0, 6, 16, 12));
  // RGB8: every other pixel of the ISP's frame.
  SetInt(c, "DecimationHorizontal", 2);
  SetInt(c, "DecimationVertical", 2);
  SetInt(c, "OffsetY", 0);
  SetInt(c, "Height", 24);
  SetInt(c, "Width", 32);
  const std::vector<uint8_t> rgb = GrabAt(c, "RGB8", 4);
  EXPECT_TRUE(rgb == DecimatedCells(Reference(4, genicam::kRGB8, 0, 0, 64, 48), 64, 48, 3, 1, 2, 2));
  // Back to 1: the readout is the sensor again, the window stays.
  SetInt(c, "DecimationHorizontal", 1);
  SetInt(c, "DecimationVertical", 1);
  Settle();
  EXPECT_EQ(ReadInt(c, "WidthMax"), 64);
  EXPECT_EQ(ReadInt(c, "HeightMax"), 48);
  EXPECT_EQ(ReadInt(c, "Width"), 32);
  EXPECT_TRUE(GrabAt(c, "BayerRG12", 4) == WindowOf(full, 64, 2, 0, 0, 32, 24));
  GError* e = nullptr;
  arv_camera_set_integer(c.camera(), "DecimationHorizontal", 5, &e);
  EXPECT_TRUE(g_error_matches(e, ARV_DEVICE_ERROR, ARV_DEVICE_ERROR_PROTOCOL_ERROR_INVALID_PARAMETER))
      << (e != nullptr ? e->message : "no error: 5 is past the maximum 4");
  g_clear_error(&e);
  EXPECT_EQ(device_->CheckInvariants(), "");
}

// BinningHorizontal / BinningVertical 2 combine the same-colour pixels of
// 2 x 2 neighbouring cells (Bayer) or 2 x 2 pixels (mono): Sum clamped at
// full scale (4095 in a 12-bit format), Average rounded half up; each equal
// to the test's own binning of the reference frame's colour planes.
TEST_F(GigeE2E, BinningSumsOrAveragesSameColourPixels) {
  for (const bool mono : {false, true}) {
    SCOPED_TRACE(mono ? "Mono12" : "BayerRG12");
    ASSERT_NO_FATAL_FAILURE(StartWith(mono ? SmallMonoDevice() : SmallDevice()));
    Client& c = *client_;
    const int w = mono ? 32 : 64, h = mono ? 24 : 48, cell = mono ? 1 : 2;
    const uint32_t code = mono ? genicam::kMono12 : genicam::BayerCode(Cfa::kBayerRG, 12);
    Set(c, "PixelFormat", mono ? "Mono12" : "BayerRG12");
    const std::vector<uint32_t> full = Words(Reference(2, code, 0, 0, w, h));
    SetInt(c, "BinningHorizontal", 2);
    SetInt(c, "BinningVertical", 2);
    Settle();
    EXPECT_EQ(ReadInt(c, "WidthMax"), w / 2);
    EXPECT_EQ(ReadInt(c, "HeightMax"), h / 2);
    EXPECT_EQ(ReadInt(c, "PayloadSize"), w / 2 * h / 2 * 2);
    bool saturated = false;
    for (const bool average : {true, false}) {
      SCOPED_TRACE(average ? "Average" : "Sum");
      Set(c, "BinningHorizontalMode", average ? "Average" : "Sum");
      Set(c, "BinningVerticalMode", average ? "Average" : "Sum");
      const std::vector<uint32_t> want = Binned(full, w, h, cell, 2, average, 4095);
      const std::vector<uint8_t> f = GrabIndex(c, 2);
      EXPECT_TRUE(f == Bytes16(want)) << "not the reference binned";
      for (const uint32_t v : want) saturated = saturated || (!average && v == 4095);
    }
    EXPECT_TRUE(saturated || mono) << "no summed pixel reaches full scale: the clamp is not tested";
    EXPECT_EQ(device_->CheckInvariants(), "");
    TearDown();
  }
}

// Binning and decimation together, with different modes and factors per
// axis: same-colour pixels of bx x by cells summed, divided by the factors
// of the Average axes (rounded half up), clamped at full scale; then every
// dx-th / dy-th binned cell kept. Each frame equals the test's own reduction.
std::vector<uint32_t> Reduced(const std::vector<uint32_t>& f, int w, int h, int cell, int bx, int by, bool avg_x,
                              bool avg_y, int dx, int dy, uint32_t full) {
  const int cw = w / cell / (bx * dx), ch = h / cell / (by * dy);  // output cells
  const int ow = cw * cell, oh = ch * cell;
  const uint32_t n = static_cast<uint32_t>((avg_x ? bx : 1) * (avg_y ? by : 1));
  std::vector<uint32_t> out(static_cast<size_t>(ow) * oh);
  for (int v = 0; v < ch; ++v)
    for (int u = 0; u < cw; ++u)
      for (int q = 0; q < cell; ++q)
        for (int p = 0; p < cell; ++p) {
          const int u0 = u * dx * bx, v0 = v * dy * by;  // the first binned cell's first sensor cell
          uint32_t sum = 0;
          for (int l = 0; l < by; ++l)
            for (int k = 0; k < bx; ++k) sum += f[static_cast<size_t>((v0 + l) * cell + q) * w + (u0 + k) * cell + p];
          out[static_cast<size_t>(v * cell + q) * ow + u * cell + p] = std::min((sum + n / 2) / n, full);
        }
  return out;
}
TEST_F(GigeE2E, BinningAndDecimationCombineWithMixedModes) {
  ASSERT_NO_FATAL_FAILURE(StartWith(SmallDevice()));  // 64 x 48 BayerRG
  Client& c = *client_;
  Set(c, "PixelFormat", "BayerRG12");
  const uint32_t code = genicam::BayerCode(Cfa::kBayerRG, 12);
  const std::vector<uint32_t> full = Words(Reference(3, code, 0, 0, 64, 48));
  struct Case {
    int bx, by;
    bool avg_x, avg_y;
    int dx, dy;
  };
  for (const Case& k : {Case{2, 2, false, true, 1, 2}, Case{2, 2, true, false, 2, 1}, Case{3, 1, true, true, 1, 3},
                        Case{1, 2, false, false, 2, 2}}) {
    SCOPED_TRACE(testing::Message() << "binning " << k.bx << "x" << k.by << (k.avg_x ? " Average" : " Sum") << "/"
                                    << (k.avg_y ? "Average" : "Sum") << ", decimation " << k.dx << "x" << k.dy);
    SetInt(c, "DecimationHorizontal", 1);
    SetInt(c, "DecimationVertical", 1);
    SetInt(c, "BinningHorizontal", k.bx);
    SetInt(c, "BinningVertical", k.by);
    Set(c, "BinningHorizontalMode", k.avg_x ? "Average" : "Sum");
    Set(c, "BinningVerticalMode", k.avg_y ? "Average" : "Sum");
    SetInt(c, "DecimationHorizontal", k.dx);
    SetInt(c, "DecimationVertical", k.dy);
    Settle();
    const int ow = 64 / 2 / (k.bx * k.dx) * 2, oh = 48 / 2 / (k.by * k.dy) * 2;
    EXPECT_EQ(ReadInt(c, "WidthMax"), ow);
    EXPECT_EQ(ReadInt(c, "HeightMax"), oh);
    SetInt(c, "OffsetX", 0);
    SetInt(c, "OffsetY", 0);
    SetInt(c, "Width", ow);
    SetInt(c, "Height", oh);
    const std::vector<uint32_t> want = Reduced(full, 64, 48, 2, k.bx, k.by, k.avg_x, k.avg_y, k.dx, k.dy, 4095);
    EXPECT_TRUE(GrabIndex(c, 3) == Bytes16(want)) << "not the reference reduced";
  }
  EXPECT_EQ(device_->CheckInvariants(), "");
}

// Binning and decimation change the payload: refused while acquiring
// (access denied), as the window is, and writable again after the stop.
TEST_F(GigeE2E, BinningAndDecimationAreLockedWhileAcquiring) {
  ASSERT_NO_FATAL_FAILURE(StartWith(SmallDevice()));
  Client& c = *client_;
  ASSERT_TRUE(c.OpenStream());
  Start(c);
  EXPECT_FALSE(c.Grab(3000).empty());
  for (const char* name : {"DecimationHorizontal", "DecimationVertical", "BinningHorizontal", "BinningVertical"}) {
    GError* e = nullptr;
    arv_camera_set_integer(c.camera(), name, 2, &e);
    EXPECT_TRUE(g_error_matches(e, ARV_DEVICE_ERROR, ARV_DEVICE_ERROR_PROTOCOL_ERROR_ACCESS_DENIED))
        << name << ": " << (e != nullptr ? e->message : "no error");
    g_clear_error(&e);
    EXPECT_EQ(ReadInt(c, name), 1) << name;
  }
  for (const char* name : {"BinningHorizontalMode", "BinningVerticalMode"}) {
    GError* e = nullptr;
    arv_camera_set_string(c.camera(), name, "Average", &e);
    EXPECT_TRUE(g_error_matches(e, ARV_DEVICE_ERROR, ARV_DEVICE_ERROR_PROTOCOL_ERROR_ACCESS_DENIED))
        << name << ": " << (e != nullptr ? e->message : "no error");
    g_clear_error(&e);
    EXPECT_STREQ(arv_camera_get_string(c.camera(), name, nullptr), "Sum") << name;
  }
  EXPECT_EQ(ReadInt(c, "WidthMax"), 64);
  c.CloseStream();
  SetInt(c, "DecimationHorizontal", 2);
  Settle();
  EXPECT_EQ(ReadInt(c, "WidthMax"), 32);
}

// A binning or decimation write that leaves the window too large resets it
// on that axis (Width = WidthMax, OffsetX = 0) and says so in one line;
// one whose window still fits, and the other axis, say nothing.
TEST(GigeRegisters, AWindowResetByBinningIsLogged) {
  auto d = StartDevice(OfflineDevice());  // 64 x 48 BayerRG
  ASSERT_NE(d, nullptr);
  WriteReg(*d, reg::kWidth, Be32(48));
  WriteReg(*d, reg::kOffsetX, Be32(16));
  WriteReg(*d, reg::kHeight, Be32(24));
  testing::internal::CaptureStderr();
  WriteReg(*d, reg::kDecimationVertical, Be32(2));  // HeightMax 24: Height 24 still fits
  std::string log = testing::internal::GetCapturedStderr();
  EXPECT_EQ(log, "") << "a window that fits was reported";
  testing::internal::CaptureStderr();
  WriteReg(*d, reg::kBinningHorizontal, Be32(2));
  log = testing::internal::GetCapturedStderr();
  EXPECT_EQ(log, "camsim-gige: reset Width = 32, OffsetX = 0: BinningHorizontal = 2 leaves WidthMax 32, too small "
                 "for the window (Width 48 + OffsetX 16): it is now the whole readout\n");
  EXPECT_EQ(ReadReg32(*d, reg::kWidth), 32u);
  EXPECT_EQ(ReadReg32(*d, reg::kOffsetX), 0u);
  EXPECT_EQ(ReadReg32(*d, reg::kHeight), 24u);
  d->SyncNow();
  EXPECT_EQ(d->CheckInvariants(), "");
}

// Binning x decimation that leaves less than one pixel (mono) or one 2x2
// cell (Bayer) of the sensor on an axis is refused with INVALID_PARAMETER:
// the factor reads back unchanged, WidthMax / HeightMax stay, the refusal
// is logged with why. One that leaves exactly one stays.
TEST_F(GigeE2E, BinningThatLeavesNoCellIsRefused) {
  for (const bool mono : {false, true}) {
    SCOPED_TRACE(mono ? "mono 6 x 4" : "BayerRG 12 x 8");
    DeviceOptions o = SmallDevice(mono ? 6 : 12, mono ? 4 : 8);
    if (mono) o.overrides.push_back("sensor.cfa=\"Mono\"");
    ASSERT_NO_FATAL_FAILURE(StartWith(o));
    Client& c = *client_;
    SetInt(c, "DecimationHorizontal", 2);  // Bayer: 3 cells of 6 across; mono: 3 pixels
    SetInt(c, "DecimationVertical", 2);    // Bayer: 2 cells of 4 down; mono: 2 pixels
    Settle();
    const int64_t width_max = ReadInt(c, "WidthMax"), height_max = ReadInt(c, "HeightMax");
    EXPECT_EQ(width_max, mono ? 3 : 6);
    EXPECT_EQ(height_max, mono ? 2 : 4);
    for (const auto& [name, value] : {std::pair{"BinningHorizontal", 4}, {"BinningVertical", 3}}) {
      GError* e = nullptr;
      testing::internal::CaptureStderr();
      arv_camera_set_integer(c.camera(), name, value, &e);
      const std::string log = testing::internal::GetCapturedStderr();
      EXPECT_TRUE(g_error_matches(e, ARV_DEVICE_ERROR, ARV_DEVICE_ERROR_PROTOCOL_ERROR_INVALID_PARAMETER))
          << name << " " << value << ": " << (e != nullptr ? e->message : "no error");
      g_clear_error(&e);
      const std::string why = std::string("refused ") + name + " = " + std::to_string(value) +
                              ": binning x decimation leaves less than one " + (mono ? "pixel" : "2x2 cell");
      EXPECT_NE(log.find(why), std::string::npos) << log;
      Settle();
      EXPECT_EQ(ReadInt(c, name), 1) << name;
    }
    EXPECT_EQ(ReadInt(c, "WidthMax"), width_max);
    EXPECT_EQ(ReadInt(c, "HeightMax"), height_max);
    SetInt(c, "BinningVertical", 2);  // exactly one cell (pixel) down
    Settle();
    EXPECT_EQ(ReadInt(c, "HeightMax"), mono ? 1 : 2);
    EXPECT_EQ(device_->CheckInvariants(), "");
    TearDown();
  }
}

// ---------------------------------------------------------------- test patterns

// TestPattern's codes from their definition in docs/gige.md, in floating
// point (the device computes them in integers): M = 2^bits - 1, ramp(t, n) =
// floor(t x M / (n - 1) + 1/2); the window (x, y, w, h) of a sw x sh sensor
// in frame `index`, row after row.
std::vector<uint32_t> PatternWindow(const std::string& pattern, int sw, int sh, int bits, uint32_t index, int x, int y,
                                    int w, int h) {
  const double full = std::ldexp(1.0, bits) - 1;
  const auto ramp = [full](int t, int n) { return static_cast<uint32_t>(std::floor(t * full / (n - 1) + 0.5)); };
  std::vector<uint32_t> out;
  for (int r = y; r < y + h; ++r)
    for (int i = x; i < x + w; ++i) {
      if (pattern == "Black") out.push_back(0);
      else if (pattern == "White") out.push_back(static_cast<uint32_t>(full));
      else if (pattern == "GreyHorizontalRamp") out.push_back(ramp(i, sw));
      else if (pattern == "GreyVerticalRamp") out.push_back(ramp(r, sh));
      else if (pattern == "GreyDiagonalRamp") out.push_back(ramp(i + r, sw + sh - 1));
      else if (pattern == "GreyHorizontalRampMoving") out.push_back(ramp(static_cast<int>((i + index) % sw), sw));
      else ADD_FAILURE() << "no pattern " << pattern;
    }
  return out;
}

// A 62 x 44 BayerRG sensor: 4095 / 61 and 4095 / 43 are not whole, so the
// ramps' rounding shows; a 30 x 18 window at (6, 4).
constexpr int kPatternW = 62, kPatternH = 44, kPatternX = 6, kPatternY = 4, kPatternWinW = 30, kPatternWinH = 18;

// TestPattern replaces the ADC's codes of the whole sensor before the
// window: the window shows the pattern's part at its offset, in each
// pattern, exactly (BayerRG12: the codes). With GreyHorizontalRamp: the
// packed formats unpack to those codes, BayerRG8 and Mono8 (from the ISP)
// carry their top 8 bits, RGB8 R = G = B = those; ReverseX mirrors the
// window; DecimationHorizontal keeps every other 2x2 cell of it; Off gives
// the modelled frame (the Reference) again; a user set holds it.
TEST_F(GigeE2E, TestPatternsAreExactCodesOfTheWholeSensorBeforeTheWindow) {
  constexpr int kSw = kPatternW, kSh = kPatternH, kX = kPatternX, kY = kPatternY, kW = kPatternWinW,
                kH = kPatternWinH;
  ASSERT_NO_FATAL_FAILURE(StartWith(SmallDevice(kSw, kSh)));
  Client& c = *client_;
  ASSERT_EQ(device_->sensor().adc_bits, 12) << "configs/camera.toml's ADC; the codes below assume it";
  EXPECT_STREQ(arv_camera_get_string(c.camera(), "TestPattern", nullptr), "Off");
  EXPECT_STREQ(arv_camera_get_string(c.camera(), "TestPatternGeneratorSelector", nullptr), "Sensor");
  GError* e = nullptr;
  arv_camera_set_region(c.camera(), kX, kY, kW, kH, &e);
  ASSERT_EQ(e, nullptr);
  const size_t pixels = static_cast<size_t>(kW) * kH;
  for (const char* p : {"Black", "White", "GreyHorizontalRamp", "GreyVerticalRamp", "GreyDiagonalRamp"}) {
    SCOPED_TRACE(p);
    Set(c, "TestPattern", p);
    uint32_t code = 0;
    EXPECT_TRUE(GrabAt(c, "BayerRG12", 3, &code) == Bytes16(PatternWindow(p, kSw, kSh, 12, 3, kX, kY, kW, kH)));
    EXPECT_EQ(code, genicam::BayerCode(Cfa::kBayerRG, 12));
  }
  Set(c, "TestPattern", "GreyHorizontalRamp");
  const std::vector<uint32_t> codes = PatternWindow("GreyHorizontalRamp", kSw, kSh, 12, 0, kX, kY, kW, kH);
  EXPECT_EQ(codes[1], 470u) << "column 7: 7 x 4095 / 61 = 469.9 rounds up";
  EXPECT_TRUE(UnpackPfnc(GrabAt(c, "BayerRG12p", 3), 12, pixels) == codes);
  EXPECT_TRUE(UnpackGige12Packed(GrabAt(c, "BayerRG12Packed", 3), pixels) == codes);
  std::vector<uint8_t> top8, grey;
  for (const uint32_t v : codes) top8.push_back(static_cast<uint8_t>(v >> 4));
  for (const uint8_t v : top8) grey.insert(grey.end(), 3, v);
  EXPECT_TRUE(GrabAt(c, "BayerRG8", 3) == top8) << "the top 8 of the 12 bits";
  EXPECT_TRUE(GrabAt(c, "Mono8", 3) == top8) << "the luma of R = G = B";
  EXPECT_TRUE(GrabAt(c, "RGB8", 3) == grey) << "R = G = B = the top 8 bits";
  // ReverseX: the window's columns read right to left (as BayerGR12).
  Set(c, "PixelFormat", "BayerRG12");
  ASSERT_NO_FATAL_FAILURE(SetReverse(c, true, false));
  uint32_t code = 0;
  EXPECT_TRUE(GrabIndex(c, 3, &code) == Mirrored(Bytes16(codes), kW, kH, 2, true, false));
  EXPECT_EQ(code, genicam::BayerCode(Cfa::kBayerGR, 12));
  ASSERT_NO_FATAL_FAILURE(SetReverse(c, false, false));
  // Decimation after the pattern: every other 2x2 cell of the whole sensor's ramp.
  arv_camera_set_region(c.camera(), 0, 0, kSw, kSh, &e);
  ASSERT_EQ(e, nullptr);
  SetInt(c, "DecimationHorizontal", 2);
  Settle();
  ASSERT_EQ(ReadInt(c, "Width"), 30);
  const std::vector<uint8_t> whole = Bytes16(PatternWindow("GreyHorizontalRamp", kSw, kSh, 12, 0, 0, 0, kSw, kSh));
  EXPECT_TRUE(GrabAt(c, "BayerRG12", 3) == DecimatedCells(whole, kSw, kSh, 2, 2, 2, 1));
  SetInt(c, "DecimationHorizontal", 1);
  arv_camera_set_region(c.camera(), kX, kY, kW, kH, &e);
  ASSERT_EQ(e, nullptr);
  // A user set holds it.
  Set(c, "UserSetSelector", "UserSet1");
  EXPECT_EQ(Execute(c, reg::kUserSetSave), nullptr);
  Set(c, "TestPattern", "Off");
  EXPECT_EQ(Execute(c, reg::kUserSetLoad), nullptr);
  EXPECT_STREQ(arv_camera_get_string(c.camera(), "TestPattern", nullptr), "GreyHorizontalRamp");
  // Off: the modelled frame.
  Set(c, "TestPattern", "Off");
  const uint32_t rg12 = genicam::BayerCode(Cfa::kBayerRG, 12);
  EXPECT_TRUE(GrabAt(c, "BayerRG12", 3) == Reference(3, rg12, kX, kY, kW, kH));
  EXPECT_EQ(c.failed_buffers(), 0u);
}

// GreyHorizontalRampMoving: frame i is the horizontal ramp at
// (x + i) mod SensorWidth, so frame i + 1 is frame i moved one pixel left
// (its column x is frame i's column x + 1, wrapping round). TestPattern is
// writable while acquiring and applies to a following frame.
TEST_F(GigeE2E, TheMovingRampShiftsAPixelPerFrameAndPatternsChangeWhileAcquiring) {
  constexpr int kSw = kPatternW, kSh = kPatternH;
  ASSERT_NO_FATAL_FAILURE(StartWith(SmallDevice(kSw, kSh)));
  Client& c = *client_;
  Set(c, "TestPattern", "GreyHorizontalRampMoving");
  const std::vector<uint32_t> f5 = Words(GrabAt(c, "BayerRG12", 5)), f6 = Words(GrabIndex(c, 6));
  EXPECT_TRUE(f5 == PatternWindow("GreyHorizontalRampMoving", kSw, kSh, 12, 5, 0, 0, kSw, kSh));
  EXPECT_TRUE(f6 == PatternWindow("GreyHorizontalRampMoving", kSw, kSh, 12, 6, 0, 0, kSw, kSh));
  ASSERT_EQ(f5.size(), static_cast<size_t>(kSw) * kSh);
  ASSERT_EQ(f6.size(), f5.size());
  int shifted = 0;
  for (int r = 0; r < kSh; ++r)
    for (int i = 0; i < kSw; ++i)
      shifted += f6[static_cast<size_t>(r) * kSw + i] == f5[static_cast<size_t>(r) * kSw + (i + 1) % kSw];
  EXPECT_EQ(shifted, kSw * kSh) << "frame 6 is frame 5 one pixel left";
  EXPECT_FALSE(f5 == f6);
  const uint32_t late = 1000003;  // (x + index) mod SensorWidth for a large index
  EXPECT_TRUE(Words(GrabIndex(c, late)) == PatternWindow("GreyHorizontalRampMoving", kSw, kSh, 12, late, 0, 0, kSw, kSh));
  // While acquiring: Black, then White written, without error; a later frame is White.
  Set(c, "TestPattern", "Black");
  Settle();
  ASSERT_TRUE(c.OpenStream());
  Start(c);
  const std::vector<uint32_t> black = Words(c.Grab(3000));
  EXPECT_TRUE(black == std::vector<uint32_t>(f5.size(), 0u));
  Set(c, "TestPattern", "White");
  Settle();
  bool white = false;
  for (int i = 0; i < 8 && !white; ++i) white = Words(c.Grab(3000)) == std::vector<uint32_t>(f5.size(), 4095u);
  c.CloseStream();
  EXPECT_TRUE(white) << "no White frame after the write";
  EXPECT_EQ(c.failed_buffers(), 0u);
}

}  // namespace
}  // namespace camsim::gigetest
