// Test helpers: a camsim-gige device in this process and an Aravis client
// connected to it by address over loopback.
#pragma once

#include <arv.h>

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "genicam/device.h"

namespace camsim::gigetest {

// Device options for a small sensor on the demo configuration.
genicam::DeviceOptions SmallDevice(int width = 64, int height = 48);

// The frame the device should send for `index` with the given window and
// format, rendered without the network (same renderer and conversion).
std::vector<uint8_t> ReferenceFrame(const genicam::DeviceOptions& o, uint32_t index, uint32_t format, int x, int y,
                                    int w, int h, const std::vector<std::string>& extra_overrides = {});

class Client;
// Waits until the device has checked the writes sent so far through c: two
// more register syncs (SimSyncCount; a pipeline rebuild inside one can take
// tens of ms, more under sanitizers), at most 10 s.
void Settle(Client& c);

class Client {
 public:
  // Connects to address (no packet socket: see README, loopback pitfalls).
  explicit Client(const std::string& address = "127.0.0.1");
  ~Client();
  bool ok() const { return camera_ != nullptr; }
  ArvCamera* camera() { return camera_; }
  ArvDevice* device() { return arv_camera_get_device(camera_); }
  ArvStream* stream() { return stream_; }
  // Creates the stream with n buffers of the current payload and a socket
  // buffer of socket_buffer_bytes (Aravis's FIXED policy; the kernel caps it at net.core.rmem_max).
  bool OpenStream(int buffers = 4, int socket_buffer_bytes = 4 << 20);
  // The next complete frame's bytes (empty on timeout or a failed buffer);
  // *frame_id receives the GVSP block id.
  std::vector<uint8_t> Grab(int timeout_ms, uint64_t* frame_id = nullptr, int* width = nullptr,
                            uint32_t* format = nullptr);
  void CloseStream();
  uint64_t failed_buffers() const { return failed_; }
  // The last grabbed frame's timestamp (ns, the camera's clock: the fake
  // camera's real time).
  uint64_t last_timestamp_ns() const { return last_timestamp_ns_; }
  // The last grabbed frame's first packet's arrival (Aravis's system
  // timestamp) and its pop from the stream (just after its last packet when
  // Grab was waiting), both g_get_real_time in ns.
  uint64_t last_first_packet_ns() const { return last_first_packet_ns_; }
  uint64_t last_popped_ns() const { return last_popped_ns_; }
  std::string last_error;

 private:
  ArvCamera* camera_ = nullptr;
  uint64_t last_timestamp_ns_ = 0, last_first_packet_ns_ = 0, last_popped_ns_ = 0;
  ArvStream* stream_ = nullptr;
  uint64_t failed_ = 0;
};

}  // namespace camsim::gigetest
