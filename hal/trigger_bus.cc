// Loopback trigger bus backend of hal/gpio.h: UNIX datagram sockets in one
// directory stand for a trigger wire shared by the cameras of a rig.
#include <dirent.h>
#include <fcntl.h>
#include <sys/file.h>
#include <poll.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/time.h>
#include <sys/un.h>
#include <unistd.h>

#include <bitset>
#include <cerrno>
#include <climits>
#include <chrono>
#include <cstring>
#include <utility>

#include "hal/gpio.h"

namespace camsim::hal {
namespace {

std::string Reason() { return std::strerror(errno); }

void Put32(uint8_t* p, uint32_t v) {
  for (int i = 0; i < 4; ++i) p[i] = static_cast<uint8_t>(v >> (8 * i));
}
uint32_t Get32(const uint8_t* p) {
  return static_cast<uint32_t>(p[0]) | static_cast<uint32_t>(p[1]) << 8 | static_cast<uint32_t>(p[2]) << 16 |
         static_cast<uint32_t>(p[3]) << 24;
}
void Put64(uint8_t* p, uint64_t v) {
  Put32(p, static_cast<uint32_t>(v));
  Put32(p + 4, static_cast<uint32_t>(v >> 32));
}
uint64_t Get64(const uint8_t* p) { return static_cast<uint64_t>(Get32(p)) | static_cast<uint64_t>(Get32(p + 4)) << 32; }

// A socket path fits sockaddr_un's sun_path (108 bytes on Linux, with the NUL).
bool MakeAddress(const std::string& path, sockaddr_un* a) {
  if (path.size() + 1 > sizeof a->sun_path) return false;
  std::memset(a, 0, sizeof *a);
  a->sun_family = AF_UNIX;
  std::memcpy(a->sun_path, path.c_str(), path.size() + 1);
  return true;
}

// Socket names of the inputs: line-<pid>-<n>.sock, n the first free number.
// Cameras in other PID namespaces may share the pid.
constexpr char kInputPrefix[] = "line-", kInputSuffix[] = ".sock";
constexpr int kMaxInputNames = 1024;  // names tried before giving up

// A socket file nobody has bound any more (its process was killed) refuses a
// connection; a live one, or a file we cannot judge, is left alone.
bool IsStaleSocket(const sockaddr_un& a) {
  const int probe = socket(AF_UNIX, SOCK_DGRAM | SOCK_CLOEXEC, 0);
  if (probe < 0) return false;
  const bool stale = connect(probe, reinterpret_cast<const sockaddr*>(&a), sizeof a) != 0 && errno == ECONNREFUSED;
  close(probe);
  return stale;
}

// Holds an exclusive flock on the bus directory: claiming a name (probe,
// unlink, bind) and giving it up (unlink) are one step to every member,
// also to cameras in other PID namespaces that share the directory.
class DirectoryLock {
 public:
  explicit DirectoryLock(const std::string& dir) : fd_(open(dir.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC)) {
    if (fd_ >= 0)
      while (flock(fd_, LOCK_EX) != 0 && errno == EINTR) {
      }
  }
  ~DirectoryLock() {
    if (fd_ >= 0) close(fd_);  // releases the lock
  }
  DirectoryLock(const DirectoryLock&) = delete;
  DirectoryLock& operator=(const DirectoryLock&) = delete;

 private:
  int fd_;
};

class BusInput : public InputLine {
 public:
  BusInput(std::string spec, std::string dir, std::string path, int fd)
      : spec_(std::move(spec)), dir_(std::move(dir)), path_(std::move(path)), fd_(fd) {}
  ~BusInput() override {
    // The name goes while the socket still answers: a member probing it
    // meanwhile sees it live, never stale.
    {
      const DirectoryLock lock(dir_);
      unlink(path_.c_str());
    }
    close(fd_);
  }
  int WaitEdge(int timeout_ms, Edge* edge, std::string* error) override {
    // A signal or a datagram that is not a bus edge does not restart the timeout.
    using Clock = std::chrono::steady_clock;
    const Clock::time_point deadline = Clock::now() + std::chrono::milliseconds(timeout_ms);
    for (;;) {
      const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(deadline - Clock::now()).count();
      pollfd p{fd_, POLLIN, 0};
      const int r = poll(&p, 1, left > 0 ? static_cast<int>(left) : 0);
      if (r < 0 && errno == EINTR) continue;
      if (r < 0) {
        *error = "trigger bus '" + spec_ + "': " + Reason();
        return -1;
      }
      if (r == 0) return 0;
      uint8_t buf[64];
      const ssize_t n = recv(fd_, buf, sizeof buf, 0);
      if (n < 0) {
        if (errno == EINTR || errno == EAGAIN) continue;
        *error = "trigger bus '" + spec_ + "': " + Reason();
        return -1;
      }
      TriggerBusMessage m;
      if (!TriggerBusMessage::Decode(buf, static_cast<size_t>(n), &m)) {  // not an edge we read: ignored
        const int version = TriggerBusMessage::VersionOf(buf, static_cast<size_t>(n));
        if (version >= 0 && version != TriggerBusMessage::kVersion && !versions_seen_[version]) {
          versions_seen_[version] = true;
          // (Appended: one wait can ignore several versions before its caller takes the notice.)
          notice_ += (notice_.empty() ? "" : "; ") + std::string("trigger bus '") + spec_ +
                     "': ignored an edge in message version " + std::to_string(version) +
                     " (this camera reads version " + std::to_string(TriggerBusMessage::kVersion) +
                     "; give camsim-trigger and every camera of the rig the same build)";
        }
        continue;
      }
      *edge = m.rising ? Edge::kRising : Edge::kFalling;
      index_ = m.frame_index;
      time_ = m.edge_time_ns > static_cast<uint64_t>(INT64_MAX)
                  ? std::chrono::steady_clock::now()
                  : MonotonicEdgeTime(static_cast<long long>(m.edge_time_ns));
      return 1;
    }
  }
  std::string Name() const override { return spec_; }
  bool LastEdgeIndex(uint32_t* index) const override {
    *index = index_;
    return true;
  }
  bool LastEdgeTime(std::chrono::steady_clock::time_point* time) const override {
    *time = time_;
    return true;
  }
  std::string TakeNotice() override { return std::exchange(notice_, std::string()); }

 private:
  std::string spec_, dir_, path_;
  int fd_;
  uint32_t index_ = 0;
  std::chrono::steady_clock::time_point time_{};  // of the last edge returned
  std::bitset<256> versions_seen_;                 // other versions already noticed
  std::string notice_;
};

}  // namespace

void TriggerBusMessage::Encode(uint8_t out[kSize]) const {
  Put32(out, kMagic);
  out[4] = kVersion;
  out[5] = rising ? 1 : 0;
  out[6] = out[7] = 0;
  Put32(out + 8, frame_index);
  Put32(out + 12, sequence);
  Put64(out + 16, edge_time_ns);
}

bool TriggerBusMessage::Decode(const uint8_t* data, size_t size, TriggerBusMessage* out) {
  if (size != kSize || Get32(data) != kMagic || data[4] != kVersion || data[5] > 1) return false;
  out->rising = data[5] == 1;
  out->frame_index = Get32(data + 8);
  out->sequence = Get32(data + 12);
  out->edge_time_ns = Get64(data + 16);
  return true;
}

int TriggerBusMessage::VersionOf(const uint8_t* data, size_t size) {
  return size >= 5 && Get32(data) == kMagic ? data[4] : -1;
}

bool IsBusSpec(const std::string& spec) { return spec.rfind(kBusScheme, 0) == 0; }

bool ParseBusSpec(const std::string& spec, std::string* dir, std::string* error) {
  if (!IsBusSpec(spec) || spec.size() == sizeof kBusScheme - 1) {
    *error = "trigger bus '" + spec + "': expected unix:DIR (a directory for the bus's sockets)";
    return false;
  }
  *dir = spec.substr(sizeof kBusScheme - 1);
  while (dir->size() > 1 && dir->back() == '/') dir->pop_back();
  return true;
}

std::unique_ptr<InputLine> OpenBusInput(const std::string& spec, std::string* error) {
  std::string dir;
  if (!ParseBusSpec(spec, &dir, error)) return nullptr;
  const std::string stem = dir + "/" + kInputPrefix + std::to_string(getpid()) + "-";
  auto name = [&](int n) { return stem + std::to_string(n) + kInputSuffix; };
  sockaddr_un a;
  if (!MakeAddress(name(kMaxInputNames), &a)) {  // checked before the directory is made
    *error = "trigger bus '" + spec + "': socket paths like '" + name(0) + "' can be longer than " +
             std::to_string(sizeof a.sun_path - 1) + " bytes";
    return nullptr;
  }
  // The first member creates the bus directory; its parent must exist.
  if (mkdir(dir.c_str(), 0755) != 0 && errno != EEXIST) {
    *error = "trigger bus '" + spec + "': cannot create directory '" + dir + "': " + Reason();
    return nullptr;
  }
  struct stat st;
  if (stat(dir.c_str(), &st) != 0) {
    *error = "trigger bus '" + spec + "': cannot use '" + dir + "': " + Reason();
    return nullptr;
  }
  if (!S_ISDIR(st.st_mode)) {
    *error = "trigger bus '" + spec + "': '" + dir + "' is not a directory";
    return nullptr;
  }
  const int fd = socket(AF_UNIX, SOCK_DGRAM | SOCK_CLOEXEC, 0);
  if (fd < 0) {
    *error = "trigger bus '" + spec + "': socket: " + Reason();
    return nullptr;
  }
  // A live input's name is skipped, a socket left by a killed process is
  // replaced; under the directory's lock, so two members never both judge
  // one name stale, nor a name being bound or given up.
  const DirectoryLock lock(dir);
  for (int n = 0; n < kMaxInputNames; ++n) {
    const std::string path = name(n);
    MakeAddress(path, &a);
    const sockaddr* addr = reinterpret_cast<const sockaddr*>(&a);
    bool bound = bind(fd, addr, sizeof a) == 0;
    int bind_errno = errno;
    if (!bound && bind_errno == EADDRINUSE && IsStaleSocket(a) && unlink(path.c_str()) == 0) {
      bound = bind(fd, addr, sizeof a) == 0;
      bind_errno = errno;
    }
    if (bound) return std::make_unique<BusInput>(spec, dir, path, fd);
    if (bind_errno != EADDRINUSE) {
      errno = bind_errno;
      *error = "trigger bus '" + spec + "': cannot bind '" + path + "': " + Reason();
      close(fd);
      return nullptr;
    }
  }
  *error = "trigger bus '" + spec + "': " + std::to_string(kMaxInputNames) + " inputs named " + stem +
           "N.sock are in use";
  close(fd);
  return nullptr;
}

BusOutput::~BusOutput() {
  if (fd_ >= 0) close(fd_);
}

bool BusOutput::Set(bool high, std::string* error) { return SetAt(high, MonotonicNowNs(), error); }

bool BusOutput::SetAt(bool high, long long edge_time_ns, std::string* error) {
  if (high == level_) return true;
  // The level changes only once the edge could be sent: after a failure the
  // same Set tries again instead of finding the line already at that level.
  if (fd_ < 0) {
    const int fd = socket(AF_UNIX, SOCK_DGRAM | SOCK_CLOEXEC, 0);
    if (fd < 0) {
      *error = "trigger bus '" + spec_ + "': socket: " + Reason();
      return false;
    }
    // An input queues max_dgram_qlen datagrams (10 by default): beyond that a send waits, up to this long.
    const timeval timeout{0, kSendTimeoutMs * 1000};
    if (setsockopt(fd, SOL_SOCKET, SO_SNDTIMEO, &timeout, sizeof timeout) != 0) {
      *error = "trigger bus '" + spec_ + "': cannot set the send timeout: " + Reason();
      close(fd);
      return false;
    }
    fd_ = fd;
  }
  DIR* d = opendir(dir_.c_str());
  if (!d) {
    *error = "trigger bus '" + spec_ + "': cannot open directory '" + dir_ + "': " + Reason();
    return false;
  }
  level_ = high;
  TriggerBusMessage m;
  m.rising = high;
  m.frame_index = index_;
  m.sequence = ++sequence_;
  m.edge_time_ns = static_cast<uint64_t>(edge_time_ns);
  uint8_t msg[TriggerBusMessage::kSize];
  m.Encode(msg);
  receivers_ = 0;
  const size_t prefix = sizeof kInputPrefix - 1, suffix = sizeof kInputSuffix - 1;
  while (const dirent* e = readdir(d)) {
    const std::string name = e->d_name;
    if (name.size() <= prefix + suffix || name.compare(0, prefix, kInputPrefix) != 0 ||
        name.compare(name.size() - suffix, suffix, kInputSuffix) != 0)
      continue;
    sockaddr_un a;
    if (!MakeAddress(dir_ + "/" + name, &a)) continue;
    // A socket left by a killed process refuses at once (ECONNREFUSED): skipped.
    ssize_t sent;
    do sent = sendto(fd_, msg, sizeof msg, 0, reinterpret_cast<sockaddr*>(&a), sizeof a);
    while (sent < 0 && errno == EINTR);
    if (sent == sizeof msg) ++receivers_;
  }
  closedir(d);
  return true;
}

std::unique_ptr<BusOutput> OpenBusOutput(const std::string& spec, std::string* error) {
  std::string dir;
  if (!ParseBusSpec(spec, &dir, error)) return nullptr;
  struct stat st;
  if (stat(dir.c_str(), &st) != 0 || !S_ISDIR(st.st_mode)) {
    *error = "trigger bus '" + spec + "': no bus directory '" + dir + "' (start a camera on it first)";
    return nullptr;
  }
  return std::make_unique<BusOutput>(spec, dir);
}

namespace {

// "udp:..." and the like: a scheme that is not ours (a gpiochip name has no scheme).
bool UnknownScheme(const std::string& spec, std::string* error) {
  for (const char* s : {"udp:", "tcp:", "unix-stream:", "bus:"})
    if (spec.rfind(s, 0) == 0) {
      *error = "line '" + spec + "': unknown kind '" + std::string(s) +
               "'; a trigger bus is unix:DIR, a GPIO line CHIP:OFFSET";
      return true;
    }
  return false;
}

}  // namespace

std::unique_ptr<InputLine> OpenInputLine(const std::string& spec, const std::string& consumer, std::string* error) {
  if (IsBusSpec(spec)) return OpenBusInput(spec, error);
  if (UnknownScheme(spec, error)) return nullptr;
  return OpenGpiodInput(spec, consumer, error);
}

std::unique_ptr<OutputLine> OpenOutputLine(const std::string& spec, const std::string& consumer,
                                           std::string* error) {
  if (IsBusSpec(spec)) return OpenBusOutput(spec, error);
  if (UnknownScheme(spec, error)) return nullptr;
  return OpenGpiodOutput(spec, consumer, error);
}

}  // namespace camsim::hal
