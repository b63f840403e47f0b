// Fuzz target: GenICam register writes to the camsim-gige device (issue 8).
//
// Input: a sequence of writes, each
//   byte 0: register choice (< 0xf0: the table's writable registers, index mod
//           count; >= 0xf0: a raw address from the next two bytes, big-endian)
//   byte 1: bit 0 size (0: 4 bytes, 1: 8 bytes), bit 1 sync after this write,
//           bit 2 render a frame after the sync
//   then the value bytes (as a client sends them: big-endian).
// Each input gets a device made for it (16 x 12 demo camera, no network:
// DeviceOptions::serve = false), so an input's result depends on that input
// alone and a saved artifact or seed reproduces it. After every sync, and
// after every render, its invariants must hold (CheckInvariants: registers
// hold their values in use, values in use are valid, the window is on the
// sensor, Gain and GainRaw agree, Line0 has no source, no Auto lower limit
// is above its upper limit); a render must succeed (buffer status SUCCESS)
// and give a non-empty frame. The fake camera fails a
// fill only when the buffer is smaller than the payload its registers give;
// without network the device starts no thread, so nothing changes them
// between RenderNow's sizing and the fill: a failed render is a bug.
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <memory>
#include <string>
#include <vector>

#include "genicam/device.h"

namespace {

// A new device in its initial state (registers, values in use, pipeline,
// frame index, auto-exposure state).
std::unique_ptr<camsim::genicam::GigeDevice> NewDevice() {
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
  const std::unique_ptr<camsim::genicam::GigeDevice> device = NewDevice();
  camsim::genicam::GigeDevice* d = device.get();
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
        if (!d->RenderNow(&frame) || frame.empty()) {
          std::fprintf(stderr, "render failed or gave an empty frame after the invariants held\n");
          std::abort();
        }
        Check(d);
      }
    }
  }
  d->SyncNow();
  Check(d);
  return 0;
}
