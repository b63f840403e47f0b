// GVCP packets that come by broadcast. Loopback carries no broadcast, so
// ctest runs this binary through scripts/netns-veth-run.sh: a private network
// namespace with a veth pair, the camera on 10.9.0.1 and the test's sockets
// on 10.9.0.2, both in 10.9.0.0/24.
//
// The rule under test (docs/gige.md): the hooks answer a packet the fake
// camera leaves unanswered (a command it does not know, a write from a client
// not in control), but not one that came by broadcast (a FORCEIP or
// ACTION_CMD meant for other cameras).
#include <gtest/gtest.h>
#include <arpa/inet.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <cstdint>
#include <vector>

#include "genicam/fake_camera_hooks.h"
#include "tests/gige/gige_client.h"

namespace camsim::gigetest {
namespace {

namespace reg = genicam::reg;

constexpr char kCamera[] = "10.9.0.1", kClient[] = "10.9.0.2", kBroadcast[] = "10.9.0.255";
// GVCP: key 0x42, flags (0x01: acknowledge), command, length, request id.
constexpr uint16_t kDiscovery = 0x0002, kDiscoveryAck = 0x0003, kWriteReg = 0x0082, kActionCmd = 0x0100;
constexpr uint16_t kNotImplemented = 0x8001, kAccessDenied = 0x8006;
constexpr int kNoAnswerMs = 300;  // the camera answers in well under a millisecond here

// A GVCP client socket on kClient that may send to the broadcast address.
class Socket {
 public:
  Socket() {
    fd_ = socket(AF_INET, SOCK_DGRAM | SOCK_CLOEXEC, 0);
    const int on = 1;
    setsockopt(fd_, SOL_SOCKET, SO_BROADCAST, &on, sizeof on);
    sockaddr_in a{};
    a.sin_family = AF_INET;
    inet_pton(AF_INET, kClient, &a.sin_addr);
    bound_ = bind(fd_, reinterpret_cast<sockaddr*>(&a), sizeof a) == 0;
  }
  ~Socket() { close(fd_); }
  bool bound() const { return bound_; }
  // Sends a command with the acknowledge flag; the answer's command and
  // status, or false when none came within timeout_ms.
  bool Send(const char* to, uint16_t command, const std::vector<uint8_t>& body, uint16_t* answer_command,
            uint16_t* status, int timeout_ms = 2000) {
    std::vector<uint8_t> p = {0x42, 0x01, uint8_t(command >> 8), uint8_t(command), uint8_t(body.size() >> 8),
                              uint8_t(body.size()), uint8_t(++id_ >> 8), uint8_t(id_)};
    p.insert(p.end(), body.begin(), body.end());
    sockaddr_in a{};
    a.sin_family = AF_INET;
    a.sin_port = htons(genicam::kGvcpPort);
    inet_pton(AF_INET, to, &a.sin_addr);
    if (sendto(fd_, p.data(), p.size(), 0, reinterpret_cast<sockaddr*>(&a), sizeof a) != static_cast<ssize_t>(p.size()))
      return false;
    pollfd f{fd_, POLLIN, 0};
    while (poll(&f, 1, timeout_ms) == 1) {
      uint8_t ack[600];
      const ssize_t n = recv(fd_, ack, sizeof ack, 0);
      if (n < 8 || (ack[6] << 8 | ack[7]) != id_) continue;  // not this request's answer
      *status = static_cast<uint16_t>(ack[0] << 8 | ack[1]);
      *answer_command = static_cast<uint16_t>(ack[2] << 8 | ack[3]);
      return true;
    }
    return false;
  }
  bool WriteReg(const char* to, uint32_t address, uint32_t value, uint16_t* status, int timeout_ms = 2000) {
    uint16_t command = 0;
    return Send(to, kWriteReg, Be(address, value), &command, status, timeout_ms);
  }

 private:
  static std::vector<uint8_t> Be(uint32_t a, uint32_t b) {
    return {uint8_t(a >> 24), uint8_t(a >> 16), uint8_t(a >> 8), uint8_t(a),
            uint8_t(b >> 24), uint8_t(b >> 16), uint8_t(b >> 8), uint8_t(b)};
  }
  int fd_ = -1;
  bool bound_ = false;
  uint16_t id_ = 0;
};

TEST(GigeBroadcast, PacketsForOtherCamerasGetNoAnswerAndAreNotCounted) {
  genicam::DeviceOptions o = SmallDevice();
  o.address = kCamera;
  std::string error;
  auto device = genicam::GigeDevice::Start(o, &error);
  ASSERT_NE(device, nullptr) << error;
  Socket owner, other;
  ASSERT_TRUE(owner.bound() && other.bound()) << "no " << kClient << ": run through scripts/netns-veth-run.sh";
  uint16_t command = 0, status = 0;
  // Broadcast reaches the camera: it answers a discovery.
  ASSERT_TRUE(other.Send(kBroadcast, kDiscovery, {}, &command, &status)) << "no discovery answer by broadcast";
  EXPECT_EQ(command, kDiscoveryAck);
  EXPECT_EQ(status, 0);
  // A command the fake camera does not know: answered when sent to the
  // camera, not when sent to everyone.
  const std::vector<uint8_t> action(12, 0);
  ASSERT_TRUE(other.Send(kCamera, kActionCmd, action, &command, &status));
  EXPECT_EQ(status, kNotImplemented);
  EXPECT_FALSE(other.Send(kBroadcast, kActionCmd, action, &command, &status, kNoAnswerMs))
      << "a broadcast ACTION_CMD was answered with status 0x" << std::hex << status;
  // A write from a client not in control: denied and counted when sent to
  // the camera; by broadcast, neither.
  ASSERT_TRUE(owner.WriteReg(kCamera, reg::kControlChannelPrivilege, 2, &status));
  ASSERT_EQ(status, 0);
  ASSERT_TRUE(owner.WriteReg(kCamera, reg::kHeartbeatTimeout, 30000, &status));  // the owner sends no heartbeat
  EXPECT_FALSE(other.WriteReg(kBroadcast, reg::kWidth, 32, &status, kNoAnswerMs))
      << "a broadcast write was answered with status 0x" << std::hex << status;
  // (Not counted as this camera's: the hooks count by the address a packet
  // came to, here 10.9.0.255.)
  EXPECT_EQ(device->writes_refused(), 0u);
  ASSERT_TRUE(other.WriteReg(kCamera, reg::kWidth, 32, &status));
  EXPECT_EQ(status, kAccessDenied);
  EXPECT_EQ(device->writes_refused(), 1u);
  ASSERT_TRUE(owner.WriteReg(kCamera, reg::kControlChannelPrivilege, 0, &status));
}

}  // namespace
}  // namespace camsim::gigetest
