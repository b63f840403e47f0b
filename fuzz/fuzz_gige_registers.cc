// Fuzz target: GenICam register writes to the camsim-gige device (issue 8).
//
// Input: a sequence of writes, each
//   byte 0: register choice (< 0xf0: the table's writable registers, index mod
//           count; >= 0xf0: a raw address from the next two bytes, big-endian)
//   byte 1: bit 0 size (0: 4 bytes, 1: 8 bytes), bit 1 sync after this write,
//           bit 2 render a frame after the sync
//   then the value bytes (as a client sends them: big-endian).
// The device runs without network (DeviceOptions::serve = false) on a 16 x 12
// demo camera. After every sync its invariants must hold (CheckInvariants:
// registers hold their values in use, values in use are valid, the window is
// on the sensor, Gain and GainRaw agree, Line0 has no source) and a rendered
// frame has the size the registers announce.
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <memory>
#include <vector>

#include "genicam/device.h"

namespace {

camsim::genicam::GigeDevice* Device() {
  static std::unique_ptr<camsim::genicam::GigeDevice> device = [] {
    camsim::genicam::DeviceOptions o;
    o.config_path = CAMSIM_SOURCE_DIR "/configs/camera.toml";
    o.pattern = "gradient";
    o.overrides = {"sensor.width=16", "sensor.height=12"};
    o.serve = false;
    o.threads = 1;
    std::string error;
    auto d = camsim::genicam::GigeDevice::Start(o, &error);
    if (!d) {
      std::fprintf(stderr, "fuzz_gige_registers: %s\n", error.c_str());
      std::abort();
    }
    return d;
  }();
  return device.get();
}

void Check(camsim::genicam::GigeDevice* d) {
  const std::string broken = d->CheckInvariants();
  if (!broken.empty()) {
    std::fprintf(stderr, "invariant broken: %s\n", broken.c_str());
    std::abort();
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  camsim::genicam::GigeDevice* d = Device();
  std::vector<uint32_t> addresses;
  for (const auto& f : camsim::genicam::FeatureRegisters(d->table()))  // each line's and stage's own
    if (f.writable && f.alias_of.empty() && f.kind != camsim::genicam::Kind::kSwissKnife) addresses.push_back(f.address);
  size_t i = 0;
  while (i + 2 <= size) {
    uint32_t address;
    const uint8_t choice = data[i++];
    if (choice < 0xf0) {
      address = addresses[choice % addresses.size()];
    } else {
      if (i + 2 > size) break;
      address = (static_cast<uint32_t>(data[i]) << 8) | data[i + 1];
      i += 2;
    }
    if (i >= size) break;
    const uint8_t flags = data[i++];
    const uint32_t n = (flags & 1) ? 8 : 4;
    if (i + n > size) break;
    d->WriteMemory(address, data + i, n);
    i += n;
    if (flags & 2) {
      d->SyncNow();
      Check(d);
      if (flags & 4) {
        std::vector<uint8_t> frame;
        if (d->RenderNow(&frame) && frame.empty()) std::abort();
        Check(d);
      }
    }
  }
  d->SyncNow();
  Check(d);
  return 0;
}
