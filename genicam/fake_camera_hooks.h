// What camsim puts in front of Aravis's fake camera memory
// (arv_fake_camera_read_memory / _write_memory, which its GVCP thread and
// every register access go through): range checks, and a filter a device
// sets on the writes its clients make. fake_camera_hooks.cc says how.
#pragma once

#include <arv.h>

#include <cstdint>

namespace camsim::genicam {

// True when the hooks stand in for Aravis's functions in this process.
// Without them one GVCP packet outside the memory map would crash the
// camera, and no filter runs: GigeDevice::Start refuses to serve then.
bool FakeCameraHooksInForce();

// Called before each write to a camera's memory, except those made on a
// thread inside a DeviceWrites scope; false leaves the memory unchanged.
// `data` holds `size` bytes for `address` (big-endian registers).
using WriteFilter = bool (*)(void* owner, uint32_t address, uint32_t size, const uint8_t* data);

// Sets the filter of `camera` (nullptr removes it). Removing it waits for a
// call in progress, so `owner` may go away after.
void SetWriteFilter(ArvFakeCamera* camera, WriteFilter filter, void* owner);

// The device's own writes (initial values, reverting a refused value): the
// filter does not see the writes made on this thread while one lives.
class DeviceWrites {
 public:
  DeviceWrites();
  ~DeviceWrites();
  DeviceWrites(const DeviceWrites&) = delete;
  DeviceWrites& operator=(const DeviceWrites&) = delete;
};

}  // namespace camsim::genicam
