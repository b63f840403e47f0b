// The hooks in front of Aravis's fake camera memory (Aravis 0.8.26,
// Debian 12), by ELF symbol interposition: libaravis calls
// arv_fake_camera_read_memory and _write_memory through its PLT (from its
// GVCP thread, and from read_register / write_register), so these
// definitions in the executable take their place, and pass what they let
// through to libaravis's own functions (dlsym RTLD_NEXT).
//
// Range checks: libaravis does its range arithmetic in 32 bits and does not
// check a read past the GenICam XML, so one GVCP packet killed the camera:
// READREG 0x20000 or a WRITEMEM whose length field is below 4 (a copy of
// about 4 GiB), READREG 0xFFFFFFFC or READMEM 0xFFFFFFF0 (a copy from a
// wild pointer), WRITEREG 0xFFFFFFFC (a write 4 GiB past the registers).
// Here each range is checked in 64 bits against the memory map
// (ARV_FAKE_CAMERA_MEMORY_SIZE bytes of registers, then the read-only XML).
// Outside it a read gives zeros and a write changes nothing; both return
// FALSE (the fake camera still acknowledges the packet, where a real camera
// answers GEV_STATUS_INVALID_ADDRESS). libaravis takes a WRITEMEM's length
// from its header, not from the packet received, so a client write longer
// than GVCP allows (kMaxClientWrite) or not in whole registers is refused.
//
// Write filter: the device decides on a client's write when it arrives, in
// the order the writes came (GigeDevice::FilterClientWrite), instead of at
// its next register sync.

#include <arv.h>
#include <dlfcn.h>

#include <cstdint>
#include <cstring>
#include <mutex>
#include <vector>

#include "genicam/fake_camera_hooks.h"

namespace {

using ReadFn = gboolean (*)(ArvFakeCamera*, guint32, guint32, void*);
using WriteFn = gboolean (*)(ArvFakeCamera*, guint32, guint32, const void*);

template <typename Fn>
Fn Next(const char* name) {
  return reinterpret_cast<Fn>(dlsym(RTLD_NEXT, name));
}

// End of the readable map: the registers, then the XML.
uint64_t MapEnd(ArvFakeCamera* camera) {
  size_t xml_size = 0;
  arv_fake_camera_get_genicam_xml(camera, &xml_size);
  return uint64_t{ARV_FAKE_CAMERA_MEMORY_SIZE} + xml_size;
}

struct Filter {
  ArvFakeCamera* camera;
  camsim::genicam::WriteFilter filter;
  void* owner;
};
std::mutex g_filters_mutex;  // held while a filter runs
std::vector<Filter> g_filters;
thread_local int t_device_writes = 0;
thread_local uint64_t t_reads = 0, t_writes = 0;  // calls of the hooks on this thread (FakeCameraHooksInForce)

}  // namespace

extern "C" gboolean arv_fake_camera_read_memory(ArvFakeCamera* camera, guint32 address, guint32 size,
                                                void* buffer) {
  static const ReadFn next = Next<ReadFn>("arv_fake_camera_read_memory");
  ++t_reads;
  if (buffer == nullptr || size == 0) return FALSE;
  const uint64_t end = camera != nullptr ? MapEnd(camera) : 0;
  if (next == nullptr || address >= end) {
    std::memset(buffer, 0, size);
    return FALSE;
  }
  // A block that runs past the end (a client reading the XML in blocks whose
  // length is a multiple of 4): what is inside, then zeros, as libaravis does
  // when its 32-bit sums do not wrap.
  const guint32 inside = uint64_t{address} + size > end ? static_cast<guint32>(end - address) : size;
  std::memset(static_cast<char*>(buffer) + inside, 0, size - inside);
  return next(camera, address, inside, buffer);
}

extern "C" gboolean arv_fake_camera_write_memory(ArvFakeCamera* camera, guint32 address, guint32 size,
                                                 const void* buffer) {
  using camsim::genicam::WriteVerdict;
  static const WriteFn next = Next<WriteFn>("arv_fake_camera_write_memory");
  ++t_writes;
  // Only the registers are writable (the XML after them is read-only).
  if (next == nullptr || camera == nullptr || buffer == nullptr || size == 0 ||
      uint64_t{address} + size > ARV_FAKE_CAMERA_MEMORY_SIZE)
    return FALSE;
  if (t_device_writes > 0) return next(camera, address, size, buffer);
  if (size > camsim::genicam::kMaxClientWrite || size % 4 != 0 || address % 4 != 0) return FALSE;
  uint8_t data[camsim::genicam::kMaxClientWrite];
  std::memcpy(data, buffer, size);
  WriteVerdict verdict = WriteVerdict::kStored;
  {
    std::lock_guard<std::mutex> lock(g_filters_mutex);
    for (const Filter& f : g_filters)
      if (f.camera == camera) {
        verdict = f.filter(f.owner, address, size, data);
        break;
      }
  }
  switch (verdict) {
    case WriteVerdict::kStored: return next(camera, address, size, data);
    case WriteVerdict::kPartlyRefused: next(camera, address, size, data); return FALSE;
    case WriteVerdict::kDone: return TRUE;
    case WriteVerdict::kRefused: break;
  }
  return FALSE;
}

namespace camsim::genicam {

bool FakeCameraHooksInForce(ArvFakeCamera* camera) {
  // (A libaravis that bound these calls inside arvfakecamera.c but not
  // those of its GVCP thread would be refused too: that fails safe.)
  DeviceWrites own;
  const uint64_t reads = t_reads, writes = t_writes;
  arv_fake_camera_set_control_channel_privilege(camera, arv_fake_camera_get_control_channel_privilege(camera));
  return t_reads > reads && t_writes > writes && Next<ReadFn>("arv_fake_camera_read_memory") != nullptr &&
         Next<WriteFn>("arv_fake_camera_write_memory") != nullptr;
}

void SetWriteFilter(ArvFakeCamera* camera, WriteFilter filter, void* owner) {
  std::lock_guard<std::mutex> lock(g_filters_mutex);
  for (size_t i = 0; i < g_filters.size(); ++i)
    if (g_filters[i].camera == camera) {
      g_filters.erase(g_filters.begin() + static_cast<std::ptrdiff_t>(i));
      break;
    }
  if (filter != nullptr) g_filters.push_back({camera, filter, owner});
}

DeviceWrites::DeviceWrites() { ++t_device_writes; }
DeviceWrites::~DeviceWrites() { --t_device_writes; }

}  // namespace camsim::genicam
