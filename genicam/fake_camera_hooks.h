// What camsim puts in front of Aravis's fake camera: range checks on its
// memory (arv_fake_camera_read_memory / _write_memory, which its GVCP thread
// and every register access go through), a filter a device sets on the
// writes its clients make (the fake camera's own write that acknowledges a
// software trigger is told apart: arv_fake_camera_check_and_acknowledge_
// software_trigger), and the GVCP status of each refused access in the
// acknowledgement (g_socket_receive_message / g_socket_send_to of its control
// socket, and g_poll for the packets it leaves unanswered), the pacing of
// its stream packets and PACKETRESEND (g_socket_send_to of its stream socket).
// fake_camera_hooks.cc says how.
#pragma once

#include <arv.h>

#include <cstdint>

namespace camsim::genicam {

inline constexpr uint16_t kGvcpPort = 3956;  // GigE Vision's control port

// True when libaravis's own accesses to `camera`'s memory go through the
// hooks (tried with a read and a write of its control privilege register),
// and its socket calls and trigger acknowledgement too (they resolve to the
// hooks). Without them one GVCP
// packet outside the memory map would crash the camera, no filter runs, and
// refused writes are acknowledged: GigeDevice::Init refuses to start then.
bool FakeCameraHooksInForce(ArvFakeCamera* camera);

// GVCP's largest memory access: READMEM and WRITEMEM carry at most 536
// bytes of data (a 576-byte GVCP packet). A longer READMEM is answered with
// INVALID_PARAMETER and not served.
inline constexpr uint32_t kMaxMemoryAccess = 536;

// Client writes reach a filter as GVCP's WRITEMEM allows them: a 4-aligned
// address and length, at most this many bytes, from a packet that holds
// them all; other client writes are refused before.
inline constexpr uint32_t kMaxClientWrite = kMaxMemoryAccess;

// GigE Vision status codes (GVCP acknowledgement header) of refused accesses.
enum class GevStatus : uint16_t {
  kSuccess = 0x0000,
  kNotImplemented = 0x8001,    // a command the fake camera does not know
  kInvalidParameter = 0x8002,  // a malformed packet, an access of 0 or over 536 bytes, a value the register never takes
  kInvalidAddress = 0x8003,    // outside the memory map
  kWriteProtect = 0x8004,      // the GenICam XML
  kBadAlignment = 0x8005,      // not whole registers
  kAccessDenied = 0x8006,      // not now: the window while acquiring, a write from a client not in control
  kError = 0x8FFF,             // the device failed (GEV_STATUS_ERROR): the user set file could not be written
};

// A filter's verdict on a write: whether the bytes (which the filter may
// have set back to the memory's values) are stored, and the status the write
// is acknowledged with. Stored with kSuccess: taken; stored with another
// status: partly refused; not stored with kSuccess: a command the filter
// carried out; not stored with another status: refused. The write function
// returns TRUE for kSuccess.
struct WriteVerdict {
  bool store = true;
  GevStatus status = GevStatus::kSuccess;
};

// Called before each write to a camera's memory, except those made on a
// thread inside a DeviceWrites scope, with a copy of the `size` bytes for
// `address` (big-endian registers) that the filter may change.
using WriteFilter = WriteVerdict (*)(void* owner, uint32_t address, uint32_t size, uint8_t* data);

// Sets the filter of `camera` (nullptr removes it). It waits for a call of
// the old one or a ClientWritesHeld in progress, so the old `owner` may go
// away after; so it must not be called from inside the camera's filter or
// while this thread holds a ClientWritesHeld on the camera.
void SetWriteFilter(ArvFakeCamera* camera, WriteFilter filter, void* owner);

// While one lives, client writes to `camera` wait (its filter's decision
// and the store are made under the same lock), so the device's sync reads
// the registers in one consistent state: not a Width from before a client's
// write and an OffsetX from after the next. Other cameras' writes go on;
// this camera's wait as long as it lives (a sync that rebuilds the pipeline
// holds it for that time, so the GVCP thread answers that much later).
// Taken inside a device's lock, never the other way round (a filter runs
// under it and takes no device lock). Nothing is held without a filter.
class ClientWritesHeld {
 public:
  explicit ClientWritesHeld(ArvFakeCamera* camera);
  ~ClientWritesHeld();
  ClientWritesHeld(const ClientWritesHeld&) = delete;
  ClientWritesHeld& operator=(const ClientWritesHeld&) = delete;

 private:
  void* held_;  // the camera's filter entry, its lock taken
};

// Client writes the hooks refused themselves (a filter's refusals are its
// device's to count), since the process started, on packets that came to
// the GVCP socket bound to `address` (IPv4, dotted): malformed WRITEREG and
// WRITEMEM packets, writes outside the memory map, to the XML, not in whole
// registers or over kMaxClientWrite bytes, to a camera without a filter
// (UnfilteredWritesRefused), and writes from a client not in control
// (which the fake camera drops). One per packet.
uint64_t WritesRefusedAt(const char* address);

// Well-formed command packets that came to the GVCP socket bound to
// `address` (IPv4, dotted) from the client in control of that camera (the
// source address and port of the packet whose write of the control channel
// privilege register took control, as the fake camera tells its controller),
// since the process started. GigE Vision has each renew the controller's
// heartbeat; the fake camera renews it only on a read of that register, so
// the device reads it when this count moved (GigeDevice::ProbeHeartbeat).
uint64_t ControllerPackets(const char* address);

// How many ClientWritesHeld and client writes hold or wait for `camera`'s
// filter now (0 without a filter): lets a test see a waiter wait.
int FilterUsers(ArvFakeCamera* camera);

// The device's own writes (initial values, reverting a refused value): the
// filter does not see the writes made on this thread while one lives.
class DeviceWrites {
 public:
  DeviceWrites();
  ~DeviceWrites();
  DeviceWrites(const DeviceWrites&) = delete;
  DeviceWrites& operator=(const DeviceWrites&) = delete;
};

// A fake camera serves from its creation, before its device can set its
// filter. While one of these lives, a client write to a camera without a
// filter is refused (access denied, not stored), so none lands unchecked in
// between; a device holds one from before it creates its camera until its
// filter is set. This thread's writes are the device's (DeviceWrites), so
// the camera's own initial values are stored.
class UnfilteredWritesRefused {
 public:
  UnfilteredWritesRefused();
  ~UnfilteredWritesRefused();
  UnfilteredWritesRefused(const UnfilteredWritesRefused&) = delete;
  UnfilteredWritesRefused& operator=(const UnfilteredWritesRefused&) = delete;

 private:
  DeviceWrites own_;
};

// GigE Vision chunk mode for the frame this thread sends next (the fake
// camera sends each frame right after filling it, on the same thread). The
// fake camera sends Width * Height * bits / 8 bytes of image only; the send
// hook puts `tail` (the image's padding and tag and the chunks,
// register_table.h) after those bytes, in the same sequence of packets of
// `packet_data_bytes` each (what a receiver assumes: the
// packet size less the IP, UDP and GVSP headers), and marks the frame's
// leader and trailer as an image with chunks (payload type 0x4001). Frames
// of other block IDs go out as they are.
inline constexpr size_t kMaxChunkTail = 256;  // 3 bytes of padding, the image tag and 12 chunks of 16 bytes: 203
inline constexpr uint16_t kGvspPayloadImageWithChunks = 0x4001;
inline constexpr size_t kGvspHeaderBytes = 8;  // status, block ID, packet format and ID (standard IDs)
inline constexpr size_t kGvspOverheadBytes = 20 + 8 + kGvspHeaderBytes;  // IPv4, UDP and GVSP headers
void SendChunksWithNextFrame(uint16_t block_id, size_t image_bytes, size_t packet_data_bytes, const uint8_t* tail,
                             size_t tail_bytes);

// Pacing of the frame this thread sends next (block `block_id`): its GVSP
// packets leave no faster than a link of `link_bits_per_s` carries them (0:
// no link limit), with `packet_delay_ns` (GevSCPD) after each one. A packet
// of n UDP payload bytes takes WirePacketBytes(n) bytes of the link. The
// send hook sleeps to absolute deadlines on CLOCK_MONOTONIC, only when more
// than kPaceAheadNs ahead, and restarts its schedule when more than
// kPaceBehindNs behind (a thread descheduled does not make up in a burst).
// Control (GVCP) packets are never delayed. Both 0: sent as it comes.
void PaceNextFrame(uint16_t block_id, uint64_t link_bits_per_s, uint64_t packet_delay_ns);
// The hook also keeps the packets of this thread's last kResendFrames
// frames, as sent, and answers a PACKETRESEND (GVCP 0x0040) that reaches
// the thread's control socket by sending the packets it asks for again, to
// the frame's stream destination, paced the same way. PacketsResent counts
// them (all cameras of the process). A request for packets not kept (a
// frame older than these, one not sent yet, packet IDs past its trailer)
// gets a GVSP packet with the status saying so; ResendRequestsRefused counts
// those.
inline constexpr size_t kResendFrames = 4;
uint64_t PacketsResent();
uint64_t ResendRequestsRefused();
// Test hook: leave out every `every`-th payload packet (by packet ID) the
// first time it is sent, as a lossy link would; it is kept for PACKETRESEND.
// 0 (the default): send every packet.
void DropStreamPacketsForTest(uint32_t every);
inline constexpr int64_t kPaceAheadNs = 50'000, kPaceBehindNs = 500'000;
// Ethernet's share of a UDP datagram of `udp_payload` bytes: UDP (8) and
// IPv4 (20) headers, the Ethernet header (14) and FCS (4), padded to
// Ethernet's 64-byte minimum frame, then the preamble with its start
// delimiter (8) and the inter-frame gap (12).
inline constexpr size_t WirePacketBytes(size_t udp_payload) {
  const size_t frame = udp_payload + 8 + 20 + 14 + 4;
  return (frame < 64 ? 64 : frame) + 8 + 12;
}
// The time a frame of `payload_bytes` takes to send paced so: a leader, its
// data packets of GevSCPSPacketSize `packet_size` (IP packet bytes), a
// trailer. The leader's and trailer's sizes are Aravis 0.8.26's fake
// camera's (44 and 16 bytes with the GVSP header).
double FrameSendSeconds(size_t payload_bytes, size_t packet_size, uint64_t link_bits_per_s, uint64_t packet_delay_ns);

}  // namespace camsim::genicam
