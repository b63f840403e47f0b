// The hooks in front of Aravis's fake camera (Aravis 0.8.26, Debian 12), by
// ELF symbol interposition: libaravis calls arv_fake_camera_read_memory and
// _write_memory through its PLT (from its GVCP thread, and from
// read_register / write_register), and
// arv_fake_camera_check_and_acknowledge_software_trigger (from its GVCP
// thread), and GLib's g_socket_receive_message,
// g_socket_send_to and g_poll too (its GVCP thread's), so these
// definitions in the executable take their place, and pass what they let
// through to the next definition (dlsym RTLD_NEXT: libaravis's, GLib's).
//
// Range checks: libaravis does its range arithmetic in 32 bits and does not
// check a read past the GenICam XML, so one GVCP packet killed the camera:
// READREG 0x20000 or a WRITEMEM whose length field is below 4 (a copy of
// about 4 GiB), READREG 0xFFFFFFFC or READMEM 0xFFFFFFF0 (a copy from a
// wild pointer), WRITEREG 0xFFFFFFFC (a write 4 GiB past the registers).
// Here each range is checked in 64 bits against the memory map
// (ARV_FAKE_CAMERA_MEMORY_SIZE bytes of registers, then the read-only XML).
// Outside it a read gives zeros and a write changes nothing; both return
// FALSE. A client write longer than GVCP allows (kMaxClientWrite) or not in
// whole registers is refused.
//
// Malformed packets: the fake camera parses each control packet from its
// one receive buffer without looking at the bytes received, so a packet
// shorter than its header or its fields, or than its length field claims,
// would be completed with the previous packet's bytes (a WRITEMEM claiming
// 536 bytes and carrying 4 stored 532 stale ones). The receive hook hides
// such a packet from the fake camera (a first byte other than the command
// key: it ignores the packet) and answers it with INVALID_PARAMETER, unless
// it is shorter than a header (no request id to answer).
//
// Counts: each client write the hooks refuse themselves is counted for the
// local address of the socket its packet came to (WritesRefusedAt). The
// fake camera acknowledges every write it carries out, with or without the
// acknowledge flag, so a write still unanswered when its thread receives or
// polls again is one it dropped (its client is not in control).
//
// Write filter: the device decides on a client's write when it arrives, in
// the order the writes came (GigeDevice::FilterClientWrite), instead of at
// its next register sync. From a camera's creation until its filter is
// set, UnfilteredWritesRefused refuses its clients' writes. The fake
// camera's own write of 0 that acknowledges a software trigger is made
// inside arv_fake_camera_check_and_acknowledge_software_trigger, which the
// hooks run as a device write (DeviceWrites): so the filter can refuse every
// client write to that register, and a client's 0 can no longer pass for
// the acknowledgement and withdraw a frame the device asked for.
//
// Status: the fake camera acknowledges every access it answers as a
// success. The control packet its thread received (g_socket_receive_message)
// is kept until that thread sends the acknowledgement (g_socket_send_to on
// the same socket, the command + 1 and the same request id); when an access
// of that packet was refused, the acknowledgement goes out as GVCP's error
// form instead: the status, and 4 bytes of data (the ack's first 4). A
// write from a client not in control and a command it does not know get no
// acknowledgement from it: the hooks answer those when the thread receives
// again or polls (AnswerUnanswered).
//
// Pacing: the device names the frame this thread sends next, with the link
// rate and GevSCPD (PaceNextFrame), and the send hook lets each of that
// frame's GVSP packets go out only when a link of that rate would have
// carried the ones before it (StreamSend). Control packets pass at once.
//
// Heartbeat: the fake camera renews its controller's heartbeat only on a
// read of the control channel privilege register (from anyone). The hooks
// note who took control (the source address and port of the packet whose
// write set that register from 0, as the fake camera's controller is) and
// count the controller's well-formed command packets (ControllerPackets);
// the device reads the register when the count moved (GigeDevice::
// ProbeHeartbeat).
//
// Packet resend: StreamSend also keeps the packets of the thread's last
// kResendFrames frames, and the receive hook answers a PACKETRESEND with
// the kept packets it asks for (ResendPackets), hidden from the fake camera.

#include <arpa/inet.h>
#include <arv.h>
#include <dlfcn.h>
#include <ifaddrs.h>
#include <net/if.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <time.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <condition_variable>
#include <cstdint>
#include <cstring>
#include <vector>
#include <list>
#include <mutex>

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

using camsim::genicam::GevStatus;

// GVCP header: key or status (2 bytes), command (2), length (2), request id
// (2). An error acknowledgement: the header and 4 bytes of data.
constexpr size_t kGvcpHeader = 8, kGvcpErrorAck = kGvcpHeader + 4;
constexpr uint8_t kGvcpCommandKey = 0x42, kGvcpAckRequired = 0x01,  // byte 0; flags of byte 1
    kGvcpExtendedIds = 0x10;
constexpr uint16_t kReadReg = 0x0080, kWriteReg = 0x0082, kReadMem = 0x0084, kWriteMem = 0x0086,
                   kPacketResend = 0x0040;  // GVCP command codes
uint16_t Get16(const uint8_t* p) { return static_cast<uint16_t>(p[0] << 8 | p[1]); }

// The bytes after the header a command needs (its length field may not say
// less): READREG an address, WRITEREG an address and a value, READMEM an
// address and a count, WRITEMEM an address (then its data).
size_t FixedFields(uint16_t command) {
  switch (command) {
    case kReadReg: return 4;
    case kWriteReg: return 8;
    case kReadMem: return 8;
    case kWriteMem: return 4;
    case kPacketResend: return 12;
    default: return 0;
  }
}

// The header of an error acknowledgement of `command` / `id` (bytes 8..11: data).
void ErrorAckHeader(gchar* ack, GevStatus status, uint16_t command, uint16_t id) {
  const uint16_t fields[4] = {static_cast<uint16_t>(status), static_cast<uint16_t>(command + 1), 4, id};
  for (int i = 0; i < 4; ++i) {
    ack[2 * i] = static_cast<gchar>(fields[i] >> 8);
    ack[2 * i + 1] = static_cast<gchar>(fields[i] & 0xff);
  }
}

using SendToFn = gssize (*)(GSocket*, GSocketAddress*, const gchar*, gsize, GCancellable*, GError**);

// The control packet this thread received and has not acknowledged yet.
struct ControlPacket {
  GSocket* socket = nullptr;  // nullptr: none
  uint16_t command = 0, id = 0;
  bool wants_ack = false;
  GevStatus status = GevStatus::kSuccess;  // the first refusal's
  sockaddr_storage from{};                 // the client's address (native: no reference to hold)
  gsize from_size = 0;
};
thread_local ControlPacket t_packet;
std::atomic<uint64_t> g_resent_packets{0};  // PacketsResent
std::atomic<uint64_t> g_resend_refusals{0};  // ResendRequestsRefused
std::atomic<uint32_t> g_drop_every{0};        // DropStreamPacketsForTest

// Whether a socket is bound to GVCP's port (a fake camera's control or
// discovery socket), and its local IPv4 address (address may be nullptr).
bool GvcpSocketAddress(GSocket* socket, in_addr* address = nullptr) {
  sockaddr_in a{};
  socklen_t n = sizeof a;
  if (getsockname(g_socket_get_fd(socket), reinterpret_cast<sockaddr*>(&a), &n) != 0 || a.sin_family != AF_INET ||
      ntohs(a.sin_port) != camsim::genicam::kGvcpPort)
    return false;
  if (address != nullptr) *address = a.sin_addr;
  return true;
}

// True when `socket` is bound to a broadcast address (the fake camera's
// global or subnet discovery socket), not to an interface's own address
// (its control socket; a /32 address may be its own broadcast address).
bool BroadcastSocket(GSocket* socket) {
  in_addr local{};
  if (!GvcpSocketAddress(socket, &local)) return false;
  if (local.s_addr == htonl(INADDR_BROADCAST)) return true;
  ifaddrs* list = nullptr;
  if (getifaddrs(&list) != 0) return false;
  const auto is = [&local](const sockaddr* a) {
    return a != nullptr && a->sa_family == AF_INET &&
           reinterpret_cast<const sockaddr_in*>(a)->sin_addr.s_addr == local.s_addr;
  };
  bool own = false, broadcast = false;
  for (const ifaddrs* i = list; i != nullptr; i = i->ifa_next) {
    own = own || is(i->ifa_addr);
    broadcast = broadcast || ((i->ifa_flags & IFF_BROADCAST) != 0 && is(i->ifa_broadaddr));
  }
  freeifaddrs(list);
  return broadcast && !own;
}

// Client writes the hooks refused, per local address of the socket their
// packet came to (WritesRefusedAt).
struct RefusedAt {
  in_addr_t address;
  uint64_t writes;
};
std::mutex g_refused_mutex;
std::list<RefusedAt> g_refused;
void CountRefusedWrite(GSocket* socket) {
  in_addr local{};
  if (socket == nullptr || !GvcpSocketAddress(socket, &local)) return;
  std::lock_guard<std::mutex> lock(g_refused_mutex);
  for (RefusedAt& r : g_refused)
    if (r.address == local.s_addr) {
      ++r.writes;
      return;
    }
  g_refused.push_back({local.s_addr, 1});
}

// Each camera's controller, by the local address of its GVCP socket
// (ControllerPackets).
struct Controller {
  in_addr_t local;
  bool set = false;
  sockaddr_in from{};  // the source of the packet that took control
  uint64_t packets = 0;
};
std::mutex g_controllers_mutex;
std::list<Controller> g_controllers;
Controller& ControllerAt(in_addr_t local) {  // under g_controllers_mutex
  for (Controller& c : g_controllers)
    if (c.local == local) return c;
  return g_controllers.emplace_back(Controller{local});
}
bool SameSource(const sockaddr_in& a, const sockaddr_in& b) {
  return a.sin_addr.s_addr == b.sin_addr.s_addr && a.sin_port == b.sin_port;
}
// A well-formed command packet from `from` came to the GVCP socket bound to `local`.
void CountIfFromController(in_addr local, GSocketAddress* from) {
  sockaddr_in a{};
  if (from == nullptr || !g_socket_address_to_native(from, &a, sizeof a, nullptr) || a.sin_family != AF_INET) return;
  std::lock_guard<std::mutex> lock(g_controllers_mutex);
  Controller& c = ControllerAt(local.s_addr);
  if (c.set && SameSource(c.from, a)) ++c.packets;
}

// Sends an error acknowledgement (the header, then 4 bytes of `data`, or
// zeros: a WRITEREG's index 0) of a command the client asked to
// acknowledge, as a camera would: not to a command that came by broadcast
// (a FORCEIP or ACTION_CMD meant for another camera, say), and never to
// PACKETRESEND (GVCP answers it with the resent packets).
void SendErrorAck(GSocket* socket, GSocketAddress* to, bool wants_ack, GevStatus status, uint16_t command,
                  uint16_t id, const uint8_t* data = nullptr) {
  static const SendToFn send = Next<SendToFn>("g_socket_send_to");
  if (send == nullptr || to == nullptr || !wants_ack || command == kPacketResend || BroadcastSocket(socket)) return;
  gchar ack[kGvcpErrorAck] = {};
  ErrorAckHeader(ack, status, command, id);
  if (data != nullptr) std::memcpy(ack + kGvcpHeader, data, kGvcpErrorAck - kGvcpHeader);
  send(socket, to, ack, sizeof ack, nullptr, nullptr);
}

// The packet this thread received, if the fake camera left it without an
// acknowledgement, is answered: a write from a client not in control (the
// fake camera ignores it) is denied, a command it does not know is not
// implemented. Called when the thread receives again (the fake camera reads
// each of its sockets in turn) and before it polls.
void AnswerUnanswered() {
  if (t_packet.socket == nullptr) return;
  const ControlPacket packet = t_packet;
  t_packet = ControlPacket{};
  const bool write = packet.command == kWriteReg || packet.command == kWriteMem;
  if (write) CountRefusedWrite(packet.socket);
  if (packet.from_size == 0) return;
  GSocketAddress* to = g_socket_address_new_from_native(const_cast<sockaddr_storage*>(&packet.from), packet.from_size);
  SendErrorAck(packet.socket, to, packet.wants_ack, write ? GevStatus::kAccessDenied : GevStatus::kNotImplemented,
               packet.command, packet.id);
  if (to != nullptr) g_object_unref(to);
}

// A refused access: its status goes into the acknowledgement of the control
// packet this thread is answering, if any (the first refusal's).
gboolean Refuse(GevStatus status) {
  if (t_packet.socket != nullptr && t_packet.status == GevStatus::kSuccess) t_packet.status = status;
  return FALSE;
}
// A client write the hooks refuse themselves (a filter's refusals its device counts).
gboolean RefuseClientWrite(GevStatus status) {
  CountRefusedWrite(t_packet.socket);
  return Refuse(status);
}

struct Filter {
  ArvFakeCamera* camera = nullptr;
  camsim::genicam::WriteFilter filter = nullptr;
  void* owner = nullptr;
  std::mutex writes;  // held while the filter decides on a write and it is stored, and by ClientWritesHeld
  int users = 0;         // LockFilter callers holding or waiting for `writes` (under g_filters_mutex)
  bool removed = false;  // SetWriteFilter waits for its users to go (under g_filters_mutex)
};
// Guards the list and each entry's users and removed: held to find, add or
// remove an entry, never while waiting for an entry's `writes`, so one
// camera's filter or sync does not hold up the others'.
std::mutex g_filters_mutex;
std::condition_variable g_filter_released;  // an entry's users went down
std::list<Filter> g_filters;
int g_unfiltered_refused = 0;  // UnfilteredWritesRefused alive (under g_filters_mutex)
bool UnfilteredRefused() {
  std::lock_guard<std::mutex> list(g_filters_mutex);
  return g_unfiltered_refused > 0;
}

// The filter of `camera` with its `writes` lock taken, or nullptr. UnlockFilter releases it.
Filter* LockFilter(ArvFakeCamera* camera) {
  Filter* found = nullptr;
  {
    std::lock_guard<std::mutex> list(g_filters_mutex);
    for (Filter& f : g_filters)
      if (f.camera == camera && !f.removed) {
        ++f.users;
        found = &f;
        break;
      }
  }
  if (found != nullptr) found->writes.lock();
  return found;
}
void UnlockFilter(Filter* f) {
  f->writes.unlock();
  {
    std::lock_guard<std::mutex> list(g_filters_mutex);
    --f->users;
  }
  g_filter_released.notify_all();
}
thread_local int t_device_writes = 0;
thread_local uint64_t t_reads = 0, t_writes = 0;  // calls of the hooks on this thread (FakeCameraHooksInForce)

}  // namespace

extern "C" gboolean arv_fake_camera_read_memory(ArvFakeCamera* camera, guint32 address, guint32 size,
                                                void* buffer) {
  static const ReadFn next = Next<ReadFn>("arv_fake_camera_read_memory");
  ++t_reads;
  if (buffer == nullptr || size == 0) return Refuse(GevStatus::kInvalidParameter);
  const uint64_t end = camera != nullptr ? MapEnd(camera) : 0;
  if (next == nullptr || address >= end) {
    std::memset(buffer, 0, size);
    return Refuse(GevStatus::kInvalidAddress);
  }
  // A block that runs past the end (a client reading the XML in blocks whose
  // length is a multiple of 4): what is inside, then zeros, as libaravis does
  // when its 32-bit sums do not wrap.
  const guint32 inside = uint64_t{address} + size > end ? static_cast<guint32>(end - address) : size;
  std::memset(static_cast<char*>(buffer) + inside, 0, size - inside);
  return next(camera, address, inside, buffer);
}

namespace {
constexpr uint32_t kPrivilege = 0x0a00;  // GigE Vision's control channel privilege register
// Its value, read past the hooks.
uint32_t Privilege(ArvFakeCamera* camera) {
  static const ReadFn read = Next<ReadFn>("arv_fake_camera_read_memory");
  uint8_t v[4] = {};
  if (read != nullptr) read(camera, kPrivilege, sizeof v, v);
  return uint32_t{v[0]} << 24 | uint32_t{v[1]} << 16 | uint32_t{v[2]} << 8 | v[3];
}
// A client write while the fake camera handles the packet in t_packet took
// the privilege register from `before` to `after`: its sender took control
// (from 0), or control ended (to 0: a release, or the fake camera's own
// write at a heartbeat timeout). The fake camera's controller changes so.
void NoteController(uint32_t before, uint32_t after) {
  in_addr local{};
  if ((before == 0) == (after == 0) || t_packet.socket == nullptr || !GvcpSocketAddress(t_packet.socket, &local))
    return;
  std::lock_guard<std::mutex> lock(g_controllers_mutex);
  Controller& c = ControllerAt(local.s_addr);
  c.set = after != 0 && t_packet.from.ss_family == AF_INET;
  if (c.set) std::memcpy(&c.from, &t_packet.from, sizeof c.from);
}
}  // namespace

extern "C" gboolean arv_fake_camera_write_memory(ArvFakeCamera* camera, guint32 address, guint32 size,
                                                 const void* buffer) {
  static const WriteFn next = Next<WriteFn>("arv_fake_camera_write_memory");
  ++t_writes;
  const bool client = t_device_writes == 0;
  const auto refuse = client ? RefuseClientWrite : Refuse;
  if (next == nullptr || camera == nullptr || buffer == nullptr || size == 0) return refuse(GevStatus::kInvalidParameter);
  if (client && size > camsim::genicam::kMaxClientWrite) return refuse(GevStatus::kInvalidParameter);
  if (client && (size % 4 != 0 || address % 4 != 0)) return refuse(GevStatus::kBadAlignment);
  // Only the registers are writable (the XML after them is read-only).
  if (uint64_t{address} + size > ARV_FAKE_CAMERA_MEMORY_SIZE)
    return refuse(uint64_t{address} + size > MapEnd(camera) ? GevStatus::kInvalidAddress : GevStatus::kWriteProtect);
  if (!client) return next(camera, address, size, buffer);
  uint8_t data[camsim::genicam::kMaxClientWrite];
  std::memcpy(data, buffer, size);
  camsim::genicam::WriteVerdict verdict;
  Filter* f = LockFilter(camera);  // the filter's decision and the store, together
  if (f != nullptr) verdict = f->filter(f->owner, address, size, data);
  else if (UnfilteredRefused()) verdict = {false, GevStatus::kAccessDenied};
  const bool privilege = address <= kPrivilege && kPrivilege + 4 <= uint64_t{address} + size;
  const uint32_t before = privilege ? Privilege(camera) : 0;
  if (verdict.store) next(camera, address, size, data);
  if (privilege) NoteController(before, Privilege(camera));
  if (f != nullptr) UnlockFilter(f);
  if (verdict.status == GevStatus::kSuccess) return TRUE;
  return f != nullptr ? Refuse(verdict.status) : RefuseClientWrite(verdict.status);
}

// The fake camera's acknowledgement of a software trigger (its GVCP thread,
// before it fills a frame): its write of 0 to the trigger register is the
// camera's own, not a client's, so it passes the filter unseen.
extern "C" gboolean arv_fake_camera_check_and_acknowledge_software_trigger(ArvFakeCamera* camera) {
  static const auto next = Next<gboolean (*)(ArvFakeCamera*)>("arv_fake_camera_check_and_acknowledge_software_trigger");
  if (next == nullptr) return FALSE;
  const camsim::genicam::DeviceWrites own;
  return next(camera);
}

namespace {
void ResendPackets(const uint8_t* data, uint16_t length, bool extended);  // below
}  // namespace

// The fake camera's thread receives each control packet into one buffer.
// A malformed one, or a READMEM longer than GVCP allows, is answered here
// and hidden from it.
extern "C" gssize g_socket_receive_message(GSocket* socket, GSocketAddress** address, GInputVector* vectors,
                                           gint num_vectors, GSocketControlMessage*** messages, gint* num_messages,
                                           gint* flags, GCancellable* cancellable, GError** error) {
  using Fn = gssize (*)(GSocket*, GSocketAddress**, GInputVector*, gint, GSocketControlMessage***, gint*, gint*,
                        GCancellable*, GError**);
  static const Fn next = Next<Fn>("g_socket_receive_message");
  AnswerUnanswered();
  if (next == nullptr) {
    g_set_error_literal(error, G_IO_ERROR, G_IO_ERROR_FAILED, "camsim: no g_socket_receive_message");
    return -1;
  }
  const gssize got = next(socket, address, vectors, num_vectors, messages, num_messages, flags, cancellable, error);
  if (got <= 0 || num_vectors != 1 || vectors == nullptr || vectors[0].buffer == nullptr) return got;
  auto* p = static_cast<uint8_t*>(vectors[0].buffer);
  in_addr local{};
  if (p[0] != kGvcpCommandKey || !GvcpSocketAddress(socket, &local)) return got;  // not a command to a camera
  if (got < static_cast<gssize>(kGvcpHeader)) {  // the rest of its header would be the last packet's
    p[0] = 0;
    return got;
  }
  const uint16_t command = Get16(p + 2), id = Get16(p + 6), length = Get16(p + 4);
  GSocketAddress* from = address != nullptr ? *address : nullptr;
  const bool wants_ack = (p[1] & kGvcpAckRequired) != 0;
  if (length < FixedFields(command) || static_cast<size_t>(got) < kGvcpHeader + length) {
    if (command == kWriteReg || command == kWriteMem) CountRefusedWrite(socket);
    SendErrorAck(socket, from, wants_ack, GevStatus::kInvalidParameter, command, id);
    p[0] = 0;
    return got;
  }
  // READMEM: address (4), reserved (2), count (2). GigE Vision limits its
  // data to 536 bytes (a 576-byte GVCP packet; READMEM_CMD's count field),
  // and a device answers a longer one with GEV_STATUS_INVALID_PARAMETER; the
  // fake camera served up to 65535 bytes, in a datagram past UDP's limit.
  if (command == kReadMem && Get16(p + kGvcpHeader + 6) > camsim::genicam::kMaxMemoryAccess) {
    SendErrorAck(socket, from, wants_ack, GevStatus::kInvalidParameter, command, id, p + kGvcpHeader);
    p[0] = 0;
    return got;
  }
  CountIfFromController(local, from);
  // PACKETRESEND is answered with the packets (ResendPackets), not an acknowledgement.
  if (command == kPacketResend) {
    ResendPackets(p + kGvcpHeader, length, (p[1] & kGvcpExtendedIds) != 0);
    p[0] = 0;
    return got;
  }
  t_packet.socket = socket;
  t_packet.command = command;
  t_packet.id = id;
  t_packet.wants_ack = wants_ack;
  if (from != nullptr && g_socket_address_get_native_size(from) <= static_cast<gssize>(sizeof t_packet.from) &&
      g_socket_address_to_native(from, &t_packet.from, sizeof t_packet.from, nullptr))
    t_packet.from_size = static_cast<gsize>(g_socket_address_get_native_size(from));
  return got;
}

namespace {

using camsim::genicam::kGvspHeaderBytes, camsim::genicam::kPaceAheadNs, camsim::genicam::kPaceBehindNs,
    camsim::genicam::WirePacketBytes;

// GVSP (standard IDs): status (2), block ID (2), packet format (1: bit 7
// extended IDs, low 4 bits 1 leader / 2 trailer / 3 payload), packet ID (3).
constexpr uint8_t kGvspLeader = 1, kGvspTrailer = 2, kGvspPayload = 3;
void Put16(uint8_t* p, uint32_t v) {
  p[0] = static_cast<uint8_t>(v >> 8);
  p[1] = static_cast<uint8_t>(v);
}

// The frame this thread sends next (PaceNextFrame): its pacing, and where
// its packets go.
struct StreamFrame {
  bool active = false;  // from PaceNextFrame to its trailer
  uint16_t block_id = 0;
  uint64_t link_bits_per_s = 0, packet_delay_ns = 0;
  GSocket* socket = nullptr;  // its stream socket, once its first packet went out
  int64_t next_ns = 0;        // the earliest its next packet may leave (CLOCK_MONOTONIC)
};
thread_local StreamFrame t_stream;

// The last kResendFrames frames this thread sent, packet by packet, for
// PACKETRESEND; the oldest is reused for the next frame.
struct SentFrame {
  bool used = false;
  uint16_t block_id = 0;
  std::vector<uint8_t> bytes;               // the packets, one after another
  std::vector<std::pair<size_t, size_t>> at;  // by packet ID: offset and size in bytes (size 0: not sent)
};
struct SentFrames {
  SentFrame frames[camsim::genicam::kResendFrames];
  size_t newest = 0;
  GSocket* socket = nullptr;  // the stream socket and destination of the newest frame
  sockaddr_storage to{};
  gsize to_size = 0;
};
thread_local SentFrames t_sent;

int64_t MonotonicNs() {
  timespec t{};
  clock_gettime(CLOCK_MONOTONIC, &t);
  return int64_t{t.tv_sec} * 1'000'000'000 + t.tv_nsec;
}

// Waits for the slot of a packet of `size` UDP payload bytes on a link
// whose schedule is `next_ns` (0: starts now), and books the slot.
void WaitForSlot(int64_t* next_ns, gsize size, uint64_t link_bits_per_s, uint64_t packet_delay_ns) {
  if (link_bits_per_s == 0 && packet_delay_ns == 0) return;
  const int64_t now = MonotonicNs();
  if (*next_ns == 0 || now - *next_ns > kPaceBehindNs) *next_ns = now;  // the first packet, or late
  if (*next_ns - now > kPaceAheadNs) {
    const timespec at{static_cast<time_t>(*next_ns / 1'000'000'000), static_cast<long>(*next_ns % 1'000'000'000)};
    while (clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &at, nullptr) == EINTR) {
    }
  }
  const uint64_t wire_ns =
      link_bits_per_s == 0 ? 0 : WirePacketBytes(size) * 8 * uint64_t{1'000'000'000} / link_bits_per_s;
  *next_ns += static_cast<int64_t>(wire_ns + packet_delay_ns);
}

// Keeps a packet of the frame being sent (t_stream) for PACKETRESEND.
void KeepSent(GSocket* socket, GSocketAddress* address, const gchar* buffer, gsize size) {
  SentFrames& k = t_sent;
  SentFrame& f = k.frames[k.newest];
  if (!f.used || f.block_id != t_stream.block_id) {
    k.newest = (k.newest + 1) % camsim::genicam::kResendFrames;
    SentFrame& n = k.frames[k.newest];
    n.used = true;
    n.block_id = t_stream.block_id;
    n.bytes.clear();
    n.at.clear();
    k.socket = socket;
    k.to_size = 0;
    if (address != nullptr && g_socket_address_get_native_size(address) <= static_cast<gssize>(sizeof k.to) &&
        g_socket_address_to_native(address, &k.to, sizeof k.to, nullptr))
      k.to_size = static_cast<gsize>(g_socket_address_get_native_size(address));
  }
  SentFrame& n = k.frames[k.newest];
  const auto* b = reinterpret_cast<const uint8_t*>(buffer);
  const uint32_t id = uint32_t{b[5]} << 16 | Get16(b + 6);
  if (id >= n.at.size()) n.at.resize(id + 1, {0, 0});
  n.at[id] = {n.bytes.size(), size};
  n.bytes.insert(n.bytes.end(), b, b + size);
}

// Sends one GVSP packet of the frame t_stream names: kept for PACKETRESEND,
// and paced (one packet's wire time and GevSCPD after the one before).
gssize StreamSend(GSocket* socket, GSocketAddress* address, const gchar* buffer, gsize size, GCancellable* cancellable,
                  GError** error) {
  static const SendToFn next = Next<SendToFn>("g_socket_send_to");
  StreamFrame& p = t_stream;
  if (p.socket == nullptr) p.next_ns = 0;  // the frame's first packet
  p.socket = socket;
  KeepSent(socket, address, buffer, size);
  WaitForSlot(&p.next_ns, size, p.link_bits_per_s, p.packet_delay_ns);
  const uint8_t format = static_cast<uint8_t>(buffer[4]) & 0x0f;
  if (format == kGvspTrailer) p.active = false;
  const auto* b = reinterpret_cast<const uint8_t*>(buffer);
  const uint32_t drop = g_drop_every.load(), id = uint32_t{b[5]} << 16 | Get16(b + 6);
  // Lost on the way (test hook).
  if (drop != 0 && format == kGvspPayload && id % drop == 0) return static_cast<gssize>(size);
  return next(socket, address, buffer, size, cancellable, error);
}

// True when `bytes` is a GVSP packet (standard IDs) of the frame t_stream
// names, on its stream socket: never a control packet.
bool StreamPacket(GSocket* socket, const uint8_t* bytes, gsize size) {
  const StreamFrame& p = t_stream;
  if (!p.active || size < kGvspHeaderBytes || Get16(bytes + 2) != p.block_id || (bytes[4] & 0x80) != 0 ||
      (bytes[4] & 0x0f) < kGvspLeader || (bytes[4] & 0x0f) > kGvspPayload)
    return false;
  return p.socket != nullptr ? socket == p.socket : (socket != t_packet.socket && !GvcpSocketAddress(socket));
}

// GVSP packet status of a resend the device cannot answer (GigE Vision 2.0).
constexpr uint16_t kPacketUnavailable = 0x800C,         // beyond the frame's trailer
    kPacketNotYetAvailable = 0x8010,                    // of a frame not sent yet
    kPacketAndPreviousRemovedFromMemory = 0x8011;       // older than the frames kept

// PACKETRESEND (standard IDs): stream channel (2), block ID (2), first and
// last packet ID (4 each, low 24 bits). With the extended-ID flag: 4
// reserved bytes, the packet IDs (4 each, 32 bits), and a 64-bit block ID,
// whose low 16 bits name the frame (the fake camera sends standard IDs).
// The kept packets asked for go out again to the frame's destination,
// paced as the frame was. A request the device cannot answer gets one
// header-only payload packet with the first packet ID asked for and the
// status saying why, so the receiver stops asking (Aravis then gives the
// frame up at once).
void ResendPackets(const uint8_t* data, uint16_t length, bool extended) {
  SentFrames& k = t_sent;
  if (k.socket == nullptr || k.to_size == 0 || length < (extended ? 20 : 12)) return;
  const auto get32 = [](const uint8_t* p) { return uint32_t{Get16(p)} << 16 | Get16(p + 2); };
  const uint16_t block = extended ? Get16(data + 18) : Get16(data + 2);
  const uint32_t mask = extended ? 0xffffffffu : 0x00ffffffu;
  const uint32_t first = get32(data + 4) & mask, last = get32(data + 8) & mask;
  static const SendToFn send = Next<SendToFn>("g_socket_send_to");
  GSocketAddress* to = g_socket_address_new_from_native(&k.to, k.to_size);
  if (to == nullptr) return;
  const auto refuse = [&](uint16_t status) {
    const uint8_t p[kGvspHeaderBytes] = {uint8_t(status >> 8), uint8_t(status),   uint8_t(block >> 8),
                                         uint8_t(block),       kGvspPayload, uint8_t(first >> 16),
                                         uint8_t(first >> 8),  uint8_t(first)};
    ++g_resend_refusals;  // before the packet: a receiver may look at the count once it has it
    send(k.socket, to, reinterpret_cast<const gchar*>(p), sizeof p, nullptr, nullptr);
  };
  const SentFrame* frame = nullptr;
  for (const SentFrame& f : k.frames)
    if (f.used && f.block_id == block) frame = &f;
  if (frame == nullptr) {
    // Block IDs count up and wrap at 2^16 (0 is never used): within half
    // the range after the newest frame's is a frame still to come.
    const uint16_t ahead = static_cast<uint16_t>(block - k.frames[k.newest].block_id);
    refuse(ahead != 0 && ahead < 0x8000 ? kPacketNotYetAvailable : kPacketAndPreviousRemovedFromMemory);
  } else if (first > last) {
    refuse(kPacketUnavailable);
  } else if (first >= frame->at.size()) {
    const bool sending = frame == &k.frames[k.newest] && t_stream.active;
    refuse(sending ? kPacketNotYetAvailable : kPacketUnavailable);
  } else {
    int64_t next_ns = 0;
    for (uint32_t id = first; id <= last && id < frame->at.size(); ++id) {
      const auto [offset, size] = frame->at[id];
      if (size == 0) continue;
      WaitForSlot(&next_ns, size, t_stream.link_bits_per_s, t_stream.packet_delay_ns);
      ++g_resent_packets;
      send(k.socket, to, reinterpret_cast<const gchar*>(frame->bytes.data() + offset), size, nullptr, nullptr);
    }
  }
  g_object_unref(to);
}

// The chunks of the frame this thread sends next (SendChunksWithNextFrame).
struct ChunkedFrame {
  bool active = false;
  uint16_t block_id = 0;
  size_t image_bytes = 0, packet_data_bytes = 0, image_sent = 0;
  uint32_t last_packet_id = 0;  // of the frame's last data packet sent so far
  uint8_t tail[camsim::genicam::kMaxChunkTail];
  size_t tail_bytes = 0;
};
thread_local ChunkedFrame t_chunks;

// One packet of a frame with chunks (t_chunks): the leader and trailer with
// the payload type of an image with chunks, the trailer after the chunks'
// packets, and the chunks after the last image byte. Returns `size` when
// every packet went out (the fake camera only reports failures).
gssize SendChunkedFramePacket(SendToFn next, GSocket* socket, GSocketAddress* address, const uint8_t* packet,
                              gsize size, GCancellable* cancellable, GError** error) {
  using camsim::genicam::kGvspPayloadImageWithChunks;
  ChunkedFrame& c = t_chunks;
  std::vector<uint8_t> out(packet, packet + size);
  const uint8_t format = packet[4] & 0x0f;
  const auto send = [&](const std::vector<uint8_t>& p) {
    return next(socket, address, reinterpret_cast<const gchar*>(p.data()), p.size(), cancellable, error);
  };
  if (format == kGvspLeader || format == kGvspTrailer) {
    // Both carry the payload type at bytes 10..11 (after 2 reserved bytes).
    if (size >= kGvspHeaderBytes + 4) Put16(&out[kGvspHeaderBytes + 2], kGvspPayloadImageWithChunks);
    if (format == kGvspTrailer) {
      const uint32_t id = c.last_packet_id + 1;
      out[5] = static_cast<uint8_t>(id >> 16);
      Put16(&out[6], id & 0xffff);
      c.active = false;
    }
    const gssize sent = send(out);
    return sent == static_cast<gssize>(out.size()) ? static_cast<gssize>(size) : sent;
  }
  c.last_packet_id = uint32_t{packet[5]} << 16 | Get16(packet + 6);
  const size_t data = size - kGvspHeaderBytes;
  const bool last_image_packet = c.image_sent < c.image_bytes && c.image_sent + data >= c.image_bytes;
  c.image_sent += data;
  if (!last_image_packet) return next(socket, address, reinterpret_cast<const gchar*>(packet), size, cancellable, error);
  // The chunks fill this packet up, then packets of their own.
  size_t taken = std::min(c.tail_bytes, c.packet_data_bytes > data ? c.packet_data_bytes - data : 0);
  out.insert(out.end(), c.tail, c.tail + taken);
  gssize sent = send(out);
  if (sent != static_cast<gssize>(out.size())) return sent;
  while (taken < c.tail_bytes) {
    const size_t n = std::min(c.tail_bytes - taken, c.packet_data_bytes);
    const uint32_t id = ++c.last_packet_id;
    std::vector<uint8_t> p(packet, packet + kGvspHeaderBytes);
    p[5] = static_cast<uint8_t>(id >> 16);
    Put16(&p[6], id & 0xffff);
    p.insert(p.end(), c.tail + taken, c.tail + taken + n);
    sent = send(p);
    if (sent != static_cast<gssize>(p.size())) return sent;
    taken += n;
  }
  return static_cast<gssize>(size);
}

}  // namespace

// The acknowledgement of the packet received: in GVCP's error form when one
// of its accesses was refused.
extern "C" gssize g_socket_send_to(GSocket* socket, GSocketAddress* address, const gchar* buffer, gsize size,
                                   GCancellable* cancellable, GError** error) {
  static const SendToFn next = Next<SendToFn>("g_socket_send_to");
  if (next == nullptr) {
    g_set_error_literal(error, G_IO_ERROR, G_IO_ERROR_FAILED, "camsim: no g_socket_send_to");
    return -1;
  }
  const auto* bytes = reinterpret_cast<const uint8_t*>(buffer);
  // The packets of the frame PaceNextFrame named (and its chunks' extra ones) go out through StreamSend.
  const SendToFn stream_send = StreamPacket(socket, bytes, size) ? StreamSend : next;
  if (t_chunks.active && socket != t_packet.socket && size >= kGvspHeaderBytes && Get16(bytes + 2) == t_chunks.block_id &&
      (bytes[4] & 0x80) == 0 && (bytes[4] & 0x0f) >= kGvspLeader && (bytes[4] & 0x0f) <= kGvspPayload)
    return SendChunkedFramePacket(stream_send, socket, address, bytes, size, cancellable, error);
  if (stream_send != next) return stream_send(socket, address, buffer, size, cancellable, error);
  if (t_packet.socket == nullptr || socket != t_packet.socket) return next(socket, address, buffer, size, cancellable, error);
  const ControlPacket packet = t_packet;
  t_packet = ControlPacket{};
  const auto* ack = reinterpret_cast<const uint8_t*>(buffer);
  if (packet.status == GevStatus::kSuccess || size < kGvcpErrorAck || Get16(ack) != 0 ||
      Get16(ack + 2) != packet.command + 1 || Get16(ack + 6) != packet.id)
    return next(socket, address, buffer, size, cancellable, error);
  gchar refused[kGvcpErrorAck];
  std::memcpy(refused, buffer, sizeof refused);
  ErrorAckHeader(refused, packet.status, packet.command, packet.id);
  // WRITEREG_ACK's data is 2 reserved bytes and an index: the number of
  // registers written on success, the index (from 0) of the write that
  // failed on an error (GigE Vision, WRITEREG_ACK). The fake camera writes
  // one register per WRITEREG and acknowledges index 1; refused, it failed
  // at the first: 0.
  if (packet.command == kWriteReg) std::memset(refused + kGvcpHeader, 0, kGvcpErrorAck - kGvcpHeader);
  const gssize sent = next(socket, address, refused, sizeof refused, cancellable, error);
  return sent == static_cast<gssize>(sizeof refused) ? static_cast<gssize>(size) : sent;
}

// The fake camera's thread polls its sockets again once it has handled a
// packet.
extern "C" gint g_poll(GPollFD* fds, guint nfds, gint timeout) {
  static const auto next = Next<gint (*)(GPollFD*, guint, gint)>("g_poll");
  AnswerUnanswered();
  if (next == nullptr) return -1;
  return next(fds, nfds, timeout);
}

namespace camsim::genicam {

bool FakeCameraHooksInForce(ArvFakeCamera* camera) {
  // (A libaravis that bound these calls inside arvfakecamera.c but not
  // those of its GVCP thread would be refused too: that fails safe.)
  DeviceWrites own;
  const uint64_t reads = t_reads, writes = t_writes;
  arv_fake_camera_set_control_channel_privilege(camera, arv_fake_camera_get_control_channel_privilege(camera));
  // libaravis calls GLib, and its own trigger acknowledgement, through its
  // PLT, so a call resolves to the first definition in the process, the
  // hooks' when they are exported.
  const bool calls =
      dlsym(RTLD_DEFAULT, "arv_fake_camera_check_and_acknowledge_software_trigger") ==
          reinterpret_cast<void*>(&arv_fake_camera_check_and_acknowledge_software_trigger) &&
      Next<void*>("arv_fake_camera_check_and_acknowledge_software_trigger") != nullptr &&
      dlsym(RTLD_DEFAULT, "g_socket_receive_message") == reinterpret_cast<void*>(&g_socket_receive_message) &&
      dlsym(RTLD_DEFAULT, "g_socket_send_to") == reinterpret_cast<void*>(&g_socket_send_to) &&
      dlsym(RTLD_DEFAULT, "g_poll") == reinterpret_cast<void*>(&g_poll) &&
      Next<void*>("g_socket_receive_message") != nullptr && Next<void*>("g_socket_send_to") != nullptr &&
      Next<void*>("g_poll") != nullptr;
  return t_reads > reads && t_writes > writes && calls && Next<ReadFn>("arv_fake_camera_read_memory") != nullptr &&
         Next<WriteFn>("arv_fake_camera_write_memory") != nullptr;
}

void SendChunksWithNextFrame(uint16_t block_id, size_t image_bytes, size_t packet_data_bytes, const uint8_t* tail,
                             size_t tail_bytes) {
  ChunkedFrame& c = t_chunks;
  c = ChunkedFrame{};
  if (tail_bytes > kMaxChunkTail || packet_data_bytes == 0 || image_bytes == 0) return;  // the device's sizes: not expected
  c.active = true;
  c.block_id = block_id;
  c.image_bytes = image_bytes;
  c.packet_data_bytes = packet_data_bytes;
  std::memcpy(c.tail, tail, tail_bytes);
  c.tail_bytes = tail_bytes;
}

void PaceNextFrame(uint16_t block_id, uint64_t link_bits_per_s, uint64_t packet_delay_ns) {
  t_stream = StreamFrame{};
  t_stream.active = true;
  t_stream.block_id = block_id;
  t_stream.link_bits_per_s = link_bits_per_s;
  t_stream.packet_delay_ns = packet_delay_ns;
}

uint64_t PacketsResent() { return g_resent_packets.load(); }
uint64_t ResendRequestsRefused() { return g_resend_refusals.load(); }

void DropStreamPacketsForTest(uint32_t every) { g_drop_every = every; }

double FrameSendSeconds(size_t payload_bytes, size_t packet_size, uint64_t link_bits_per_s, uint64_t packet_delay_ns) {
  constexpr size_t kLeader = 44, kTrailer = 16;  // UDP payload bytes
  const size_t data = packet_size > kGvspOverheadBytes ? packet_size - kGvspOverheadBytes : 1;
  const size_t full = payload_bytes / data, rest = payload_bytes % data;
  double bytes = static_cast<double>(WirePacketBytes(kLeader) + WirePacketBytes(kTrailer)) +
                 static_cast<double>(full) * static_cast<double>(WirePacketBytes(data + kGvspHeaderBytes));
  size_t packets = 2 + full;
  if (rest != 0) {
    bytes += static_cast<double>(WirePacketBytes(rest + kGvspHeaderBytes));
    ++packets;
  }
  const double wire = link_bits_per_s == 0 ? 0.0 : bytes * 8 / static_cast<double>(link_bits_per_s);
  return wire + static_cast<double>(packets) * static_cast<double>(packet_delay_ns) * 1e-9;
}

void SetWriteFilter(ArvFakeCamera* camera, WriteFilter filter, void* owner) {
  std::unique_lock<std::mutex> list(g_filters_mutex);
  auto entry = g_filters.begin();
  while (entry != g_filters.end() && (entry->camera != camera || entry->removed)) ++entry;
  if (entry == g_filters.end()) {
    if (filter == nullptr) return;
    Filter& added = g_filters.emplace_back();
    added.camera = camera;
    added.filter = filter;
    added.owner = owner;
    return;
  }
  if (filter != nullptr) {
    // Replaced in place, under the camera's write lock: one lock per camera
    // throughout, and the next write sees the new filter.
    ++entry->users;
    list.unlock();
    entry->writes.lock();
    entry->filter = filter;
    entry->owner = owner;
    UnlockFilter(&*entry);
    return;
  }
  // No new write or ClientWritesHeld finds it now; wait for those in progress.
  entry->removed = true;
  g_filter_released.wait(list, [&entry] { return entry->users == 0; });
  g_filters.erase(entry);
}

ClientWritesHeld::ClientWritesHeld(ArvFakeCamera* camera) : held_(LockFilter(camera)) {}
ClientWritesHeld::~ClientWritesHeld() {
  if (held_ != nullptr) UnlockFilter(static_cast<Filter*>(held_));
}

DeviceWrites::DeviceWrites() { ++t_device_writes; }
DeviceWrites::~DeviceWrites() { --t_device_writes; }

int FilterUsers(ArvFakeCamera* camera) {
  std::lock_guard<std::mutex> list(g_filters_mutex);
  for (const Filter& f : g_filters)
    if (f.camera == camera && !f.removed) return f.users;
  return 0;
}

uint64_t WritesRefusedAt(const char* address) {
  in_addr a{};
  if (address == nullptr || inet_pton(AF_INET, address, &a) != 1) return 0;
  std::lock_guard<std::mutex> lock(g_refused_mutex);
  for (const RefusedAt& r : g_refused)
    if (r.address == a.s_addr) return r.writes;
  return 0;
}

uint64_t ControllerPackets(const char* address) {
  in_addr a{};
  if (address == nullptr || inet_pton(AF_INET, address, &a) != 1) return 0;
  std::lock_guard<std::mutex> lock(g_controllers_mutex);
  return ControllerAt(a.s_addr).packets;
}

UnfilteredWritesRefused::UnfilteredWritesRefused() {
  std::lock_guard<std::mutex> list(g_filters_mutex);
  ++g_unfiltered_refused;
}
UnfilteredWritesRefused::~UnfilteredWritesRefused() {
  std::lock_guard<std::mutex> list(g_filters_mutex);
  --g_unfiltered_refused;
}

}  // namespace camsim::genicam
