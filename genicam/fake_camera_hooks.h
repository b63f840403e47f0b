// What camsim puts in front of Aravis's fake camera memory
// (arv_fake_camera_read_memory / _write_memory, which its GVCP thread and
// every register access go through): range checks, and a filter a device
// sets on the writes its clients make. fake_camera_hooks.cc says how.
#pragma once

#include <arv.h>

#include <cstdint>

namespace camsim::genicam {

// True when libaravis's own accesses to `camera`'s memory go through the
// hooks (tried with a read and a write of its control privilege register).
// Without them one GVCP packet outside the memory map would crash the
// camera, and no filter runs: GigeDevice::Init refuses to start then.
bool FakeCameraHooksInForce(ArvFakeCamera* camera);

// Client writes reach a filter as GVCP's WRITEMEM allows them: a 4-aligned
// address and length, at most this many bytes; other client writes are
// refused before (a WRITEMEM length field is not checked against the packet).
inline constexpr uint32_t kMaxClientWrite = 536;

// A filter's verdict on a write: store it (kStored), store it with the bytes
// the filter set back to the memory's values (kPartlyRefused), leave the
// memory unchanged as a command the filter carried out (kDone), or refuse it
// (kRefused). The write function returns TRUE for kStored and kDone (over
// GVCP the fake camera acknowledges every write).
enum class WriteVerdict { kStored, kPartlyRefused, kDone, kRefused };

// Called before each write to a camera's memory, except those made on a
// thread inside a DeviceWrites scope, with a copy of the `size` bytes for
// `address` (big-endian registers) that the filter may change.
using WriteFilter = WriteVerdict (*)(void* owner, uint32_t address, uint32_t size, uint8_t* data);

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
