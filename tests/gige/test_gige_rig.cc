// A rig of camsim-gige cameras on 127.0.0.1, 127.0.0.2 and 127.0.0.3 sharing
// a loopback trigger bus (unix:DIR), each read by its own Aravis client.
// The extra loopback addresses exist only in a private network namespace:
// ctest runs this binary through scripts/netns-run.sh (unshare -rn + ip addr),
// which also keeps its GVCP ports away from the other GigE tests.
#include <gtest/gtest.h>
#include <ifaddrs.h>
#include <netinet/in.h>
#include <arpa/inet.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/un.h>
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <thread>
#include <vector>

#include "hal/gpio.h"
#include "tests/gige/gige_client.h"

namespace camsim::gigetest {
namespace {

using genicam::DeviceOptions;
using genicam::GigeDevice;

constexpr int kCameras = 3;
const char* const kAddresses[kCameras] = {"127.0.0.1", "127.0.0.2", "127.0.0.3"};

void Sleep(int ms) { std::this_thread::sleep_for(std::chrono::milliseconds(ms)); }

bool HasAddress(const char* address) {
  ifaddrs* list = nullptr;
  if (getifaddrs(&list) != 0) return false;
  in_addr want{};
  inet_pton(AF_INET, address, &want);
  bool found = false;
  for (ifaddrs* i = list; i; i = i->ifa_next)
    if (i->ifa_addr && i->ifa_addr->sa_family == AF_INET &&
        reinterpret_cast<sockaddr_in*>(i->ifa_addr)->sin_addr.s_addr == want.s_addr)
      found = true;
  freeifaddrs(list);
  return found;
}

// A fresh bus directory under the test's temp dir (its parent exists; the first camera creates it).
std::string BusDir(const char* name) {
  const std::string dir = testing::TempDir() + name + "-" + std::to_string(getpid());
  rmdir(dir.c_str());
  return dir;
}

void Set(Client& c, const char* feature, const char* value) {
  GError* e = nullptr;
  arv_camera_set_string(c.camera(), feature, value, &e);
  ASSERT_EQ(e, nullptr) << feature << "=" << value << ": " << e->message;
}

// Waits (at most 10 s) until a device's trigger thread has handled `edges` edges.
bool WaitEdges(const GigeDevice& d, uint64_t edges) {
  for (int i = 0; i < 2000 && d.trigger_edges() < edges; ++i) Sleep(5);
  return d.trigger_edges() >= edges;
}

int Fire(const std::string& bus, int count, int first_index) {
  // Interval: a 64x48 frame renders in a few ms; 150 ms leaves room on a loaded CI machine.
  const std::string cmd = std::string(CAMSIM_TRIGGER_BINARY) + " unix:" + bus + " --count " +
                          std::to_string(count) + " --first-index " + std::to_string(first_index) +
                          " --interval-ms 150";
  return std::system(cmd.c_str());
}

class GigeRig : public ::testing::Test {
 protected:
  void SetUp() override {
    for (const char* a : kAddresses) {
      if (!HasAddress(a)) GTEST_FAIL() << a << " is not a local address: run through scripts/netns-run.sh (ctest does)";
    }
  }
  // Starts the cameras on bus `dir`, connects a client to each, TriggerMode On, TriggerSource Line0.
  void StartRig(const std::string& dir) {
    for (int i = 0; i < kCameras; ++i) {
      options_[i] = SmallDevice();
      options_[i].address = kAddresses[i];
      options_[i].serial = "RIG" + std::to_string(i);
      options_[i].trigger_line = "unix:" + dir;
      std::string error;
      devices_[i] = GigeDevice::Start(options_[i], &error);
      ASSERT_NE(devices_[i], nullptr) << kAddresses[i] << ": " << error;
    }
    for (int i = 0; i < kCameras; ++i) {
      clients_[i] = std::make_unique<Client>(kAddresses[i]);
      ASSERT_TRUE(clients_[i]->ok()) << kAddresses[i] << ": " << clients_[i]->last_error;
      EXPECT_STREQ(arv_camera_get_device_serial_number(clients_[i]->camera(), nullptr),
                   options_[i].serial.c_str());
      Set(*clients_[i], "TriggerMode", "On");
      Set(*clients_[i], "TriggerSource", "Line0");
      Settle(*clients_[i]);  // in trigger mode before any acquisition starts
      ASSERT_TRUE(clients_[i]->OpenStream(8)) << clients_[i]->last_error;
    }
  }
  void Start(int i) {
    GError* e = nullptr;
    arv_camera_start_acquisition(clients_[i]->camera(), &e);
    ASSERT_EQ(e, nullptr) << e->message;
  }
  void TearDown() override {
    for (auto& c : clients_) c.reset();
    for (auto& d : devices_) d.reset();  // their bus sockets are removed with them
    if (!bus_.empty()) {
      EXPECT_EQ(rmdir(bus_.c_str()), 0) << "the bus directory is not empty: " << bus_;
    }
  }
  std::string bus_;
  DeviceOptions options_[kCameras];
  std::unique_ptr<GigeDevice> devices_[kCameras];
  std::unique_ptr<Client> clients_[kCameras];
};

TEST_F(GigeRig, PulsesKeepEveryCameraOnTheSameFrameIndex) {
  const std::string bus = bus_ = BusDir("camsim-rig-bus");
  StartRig(bus);
  const uint32_t code = genicam::BayerCode(Cfa::kBayerRG, 12);
  // Cameras 0 and 1 acquire from the start; camera 2, on another frame index
  // of its own (SimFrameIndex 7), starts late and misses the first pulse.
  arv_camera_set_integer(clients_[2]->camera(), "SimFrameIndex", 7, nullptr);
  Start(0);  // acknowledged: the trigger threads read Acquisition themselves
  Start(1);
  constexpr int kFirst = 40, kPulses = 4;
  ASSERT_EQ(Fire(bus, 1, kFirst), 0);
  // Camera 2 must have handled (and ignored) that pulse's two edges before it starts.
  ASSERT_TRUE(WaitEdges(*devices_[2], 2)) << "camera 2 did not see the first pulse";
  Start(2);
  ASSERT_EQ(Fire(bus, kPulses - 1, kFirst + 1), 0);
  for (int i = 0; i < kCameras; ++i) {
    SCOPED_TRACE(kAddresses[i]);
    const int first = i == 2 ? kFirst + 1 : kFirst;
    for (int index = first; index < kFirst + kPulses; ++index) {
      const std::vector<uint8_t> f = clients_[i]->Grab(3000);
      ASSERT_FALSE(f.empty()) << "no frame for the pulse of frame index " << index;
      EXPECT_TRUE(f == ReferenceFrame(options_[i], static_cast<uint32_t>(index), code, 0, 0, 64, 48))
          << "the frame for pulse " << index << " is not the core's frame " << index;
    }
    EXPECT_TRUE(clients_[i]->Grab(300).empty()) << "a frame without a pulse";
    EXPECT_EQ(clients_[i]->failed_buffers(), 0u);
    EXPECT_EQ(devices_[i]->line_error(), "");
  }
  EXPECT_EQ(arv_camera_get_integer(clients_[2]->camera(), "SimFrameIndex", nullptr), kFirst + kPulses)
      << "the next frame index follows the last pulse";
}

TEST_F(GigeRig, MasterStrobeDrivesTheBus) {
  // Camera 0 free-runs at 4 Hz; its strobe (LineSource ExposureActive) is the
  // bus the two others trigger on, so they take the frames the master takes.
  const std::string bus = bus_ = BusDir("camsim-rig-master");
  mkdir(bus.c_str(), 0755);
  options_[0] = SmallDevice();
  options_[0].serial = "MASTER";
  options_[0].strobe_line = "unix:" + bus;
  std::string error;
  devices_[0] = GigeDevice::Start(options_[0], &error);
  ASSERT_NE(devices_[0], nullptr) << error;
  for (int i = 1; i < kCameras; ++i) {
    options_[i] = SmallDevice();
    options_[i].address = kAddresses[i];
    options_[i].serial = "SLAVE" + std::to_string(i);
    options_[i].trigger_line = "unix:" + bus;
    devices_[i] = GigeDevice::Start(options_[i], &error);
    ASSERT_NE(devices_[i], nullptr) << error;
  }
  for (int i = 0; i < kCameras; ++i) {
    clients_[i] = std::make_unique<Client>(kAddresses[i]);
    ASSERT_TRUE(clients_[i]->ok()) << clients_[i]->last_error;
  }
  Client& m = *clients_[0];
  // 4 Hz: 250 ms between pulses, well above a frame's render time even with
  // ASan on two loaded cores, so no pulse waits in a slave's trigger queue.
  arv_camera_set_float(m.camera(), "AcquisitionFrameRate", 4.0, nullptr);
  Set(m, "LineSelector", "Line1");
  Set(m, "LineSource", "ExposureActive");
  arv_camera_set_integer(m.camera(), "SimFrameIndex", 20, nullptr);
  for (int i = 1; i < kCameras; ++i) {
    Set(*clients_[i], "TriggerMode", "On");
    Set(*clients_[i], "TriggerSource", "Line0");
    Settle(*clients_[i]);  // in trigger mode before the acquisition starts
    ASSERT_TRUE(clients_[i]->OpenStream(8));
    Start(i);
    Settle(*clients_[i]);  // the slave's device has taken its AcquisitionStart before the first pulse
  }
  ASSERT_TRUE(m.OpenStream(8));
  Start(0);
  const uint32_t code = genicam::BayerCode(Cfa::kBayerRG, 12);
  // The master's frames 20..23.
  for (int index = 20; index < 24; ++index) {
    const std::vector<uint8_t> f = m.Grab(3000);
    ASSERT_FALSE(f.empty()) << "master frame " << index;
    EXPECT_TRUE(f == ReferenceFrame(options_[0], static_cast<uint32_t>(index), code, 0, 0, 64, 48))
        << "master: not the core's frame " << index;
  }
  // Each slave takes every pulse of the master, from its first: frames 20, 21, 22.
  // (The first pulse of a stream may wait up to 100 ms in the fake camera; a
  // second pulse in that time is queued, not merged: docs/gige.md.)
  for (int i = 1; i < kCameras; ++i) {
    SCOPED_TRACE(kAddresses[i]);
    for (int index = 20; index < 23; ++index) {
      const std::vector<uint8_t> f = clients_[i]->Grab(3000);
      ASSERT_FALSE(f.empty()) << "no slave frame for the master's frame " << index;
      EXPECT_TRUE(f == ReferenceFrame(options_[i], static_cast<uint32_t>(index), code, 0, 0, 64, 48))
          << "the slave's frame is not the master's frame " << index;
    }
    EXPECT_EQ(clients_[i]->failed_buffers(), 0u);
  }
}

TEST(GigeRigAddresses, OneCameraPerAddressAndOnlyLocalAddresses) {
  DeviceOptions o = SmallDevice();
  o.address = "127.0.0.2";
  std::string error;
  auto first = GigeDevice::Start(o, &error);
  ASSERT_NE(first, nullptr) << error;
  o.serial = "OTHER";
  EXPECT_EQ(GigeDevice::Start(o, &error), nullptr) << "a second camera on 127.0.0.2";
  EXPECT_NE(error.find("127.0.0.2"), std::string::npos) << error;
  EXPECT_NE(error.find("in use"), std::string::npos) << error;
  o.address = "127.0.0.9";  // routed to lo, but no interface has it
  EXPECT_EQ(GigeDevice::Start(o, &error), nullptr);
  EXPECT_NE(error.find("127.0.0.9"), std::string::npos) << error;
  EXPECT_NE(error.find("no network interface"), std::string::npos) << error;
  // Found before the fake camera starts, so the error says what to do, not
  // "or another camera" (bind() alone takes any 127/8 address on Linux).
  EXPECT_NE(error.find("ip addr add 127.0.0.9"), std::string::npos) << error;
  EXPECT_EQ(error.find("another camera"), std::string::npos) << error;
  o.address = "camera.local";
  EXPECT_EQ(GigeDevice::Start(o, &error), nullptr);
  EXPECT_NE(error.find("not an IPv4 address"), std::string::npos) << error;
  // Addresses no interface can add to lo get no "ip addr add" advice.
  o.address = "192.0.2.7";  // TEST-NET-1: no host here has it
  EXPECT_EQ(GigeDevice::Start(o, &error), nullptr);
  EXPECT_NE(error.find("no network interface"), std::string::npos) << error;
  EXPECT_EQ(error.find("ip addr add"), std::string::npos) << error;
  for (const char* a : {"0.0.0.0", "255.255.255.255", "239.1.2.3"}) {
    o.address = a;
    EXPECT_EQ(GigeDevice::Start(o, &error), nullptr) << a;
    EXPECT_NE(error.find("a camera serves on one interface's address"), std::string::npos) << error;
    EXPECT_EQ(error.find("ip addr add"), std::string::npos) << error;
  }
}

// camsim-trigger stamps each edge with its scheduled time: a pulse's
// falling edge is exactly --width-us after its rising one, and pulses are
// exactly --interval-ms apart, however late the sender woke (it stamped
// each edge when it got to it: "1 ms" pulses came out 1.7-5 ms wide).
TEST(GigeTrigger, PulsesAreStampedWithTheirScheduledTimes) {
  const std::string dir = BusDir("camsim-schedule");
  ASSERT_EQ(mkdir(dir.c_str(), 0700), 0);
  // A bus input of our own: the raw messages, as a camera receives them.
  const int fd = socket(AF_UNIX, SOCK_DGRAM | SOCK_CLOEXEC, 0);
  ASSERT_GE(fd, 0);
  sockaddr_un a{};
  a.sun_family = AF_UNIX;
  const std::string path = dir + "/line-" + std::to_string(getpid()) + "-0.sock";
  std::strncpy(a.sun_path, path.c_str(), sizeof a.sun_path - 1);
  ASSERT_EQ(bind(fd, reinterpret_cast<sockaddr*>(&a), sizeof a), 0) << std::strerror(errno);
  const std::string cmd = std::string(CAMSIM_TRIGGER_BINARY) + " unix:" + dir +
                          " --count 4 --first-index 7 --interval-ms 20 --width-us 700 > /dev/null";
  ASSERT_EQ(std::system(cmd.c_str()), 0);
  std::vector<hal::TriggerBusMessage> edges;
  uint8_t buf[64];
  for (;;) {
    const ssize_t n = recv(fd, buf, sizeof buf, MSG_DONTWAIT);
    if (n < 0) break;
    hal::TriggerBusMessage m;
    ASSERT_TRUE(hal::TriggerBusMessage::Decode(buf, static_cast<size_t>(n), &m)) << n << " bytes";
    edges.push_back(m);
  }
  close(fd);
  unlink(path.c_str());
  rmdir(dir.c_str());
  ASSERT_EQ(edges.size(), 8u);
  for (size_t k = 0; k < 4; ++k) {
    const hal::TriggerBusMessage &rise = edges[2 * k], &fall = edges[2 * k + 1];
    EXPECT_TRUE(rise.rising);
    EXPECT_FALSE(fall.rising);
    EXPECT_EQ(rise.frame_index, 7 + k);
    EXPECT_EQ(fall.edge_time_ns - rise.edge_time_ns, 700000u) << "pulse " << k;
    if (k > 0) {
      EXPECT_EQ(rise.edge_time_ns - edges[2 * k - 2].edge_time_ns, 20000000u) << "pulse " << k;
    }
  }
}

}  // namespace
}  // namespace camsim::gigetest
