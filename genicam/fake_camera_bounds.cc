// Bounds for Aravis's fake camera memory (Aravis 0.8.26, Debian 12).
//
// arv_fake_camera_read_memory and _write_memory do their range arithmetic in
// 32 bits and do not check a read past the GenICam XML: one GVCP packet
// (READREG 0x20000, READMEM 0xFFFFFFF0, WRITEREG 0xFFFFFFFC, or a WRITEMEM
// whose length field is below 4) makes them copy gigabytes and kills the
// camera. The fake camera's GVCP thread calls them through libaravis's PLT,
// so these definitions in the executable take their place (ELF symbol
// interposition). Each checks the range in 64 bits against the memory map
// (ARV_FAKE_CAMERA_MEMORY_SIZE bytes of registers, then the read-only XML)
// and passes what lies inside it to libaravis's own function (dlsym
// RTLD_NEXT). Outside: a read gives zeros and a write changes nothing; both
// return FALSE (the fake camera still acknowledges the packet, as a real
// camera would not: it answers GEV_STATUS_INVALID_ADDRESS).
// FakeCameraBoundsInForce() tells whether the interposition took.

#include <arv.h>
#include <dlfcn.h>

#include <cstdint>
#include <cstring>

#include "genicam/device.h"

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

}  // namespace

extern "C" gboolean arv_fake_camera_read_memory(ArvFakeCamera* camera, guint32 address, guint32 size,
                                                void* buffer) {
  static const ReadFn next = Next<ReadFn>("arv_fake_camera_read_memory");
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
  static const WriteFn next = Next<WriteFn>("arv_fake_camera_write_memory");
  // Only the registers are writable (the XML after them is read-only).
  if (next == nullptr || camera == nullptr || buffer == nullptr || size == 0 ||
      uint64_t{address} + size > ARV_FAKE_CAMERA_MEMORY_SIZE)
    return FALSE;
  return next(camera, address, size, buffer);
}

namespace camsim::genicam {

bool FakeCameraBoundsInForce() {
  const void* read = dlsym(RTLD_DEFAULT, "arv_fake_camera_read_memory");
  const void* write = dlsym(RTLD_DEFAULT, "arv_fake_camera_write_memory");
  return read == reinterpret_cast<const void*>(&arv_fake_camera_read_memory) &&
         write == reinterpret_cast<const void*>(&arv_fake_camera_write_memory) &&
         Next<ReadFn>("arv_fake_camera_read_memory") != nullptr &&
         Next<WriteFn>("arv_fake_camera_write_memory") != nullptr;
}

}  // namespace camsim::genicam
