// camsim-gige: the camera pipeline served as a GigE Vision camera.
#include <arv.h>

#include <cctype>
#include <cerrno>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <thread>
#include <chrono>

#include "genicam/device.h"

namespace {

const char kUsage[] =
    "usage: camsim-gige (--input EXR... | --pattern NAME) [--config FILE] [--set section.key=value]...\n"
    "                   [--address 127.0.0.1] [--serial CS0001] [--trigger-line CHIP:OFFSET|unix:DIR]\n"
    "                   [--strobe-line CHIP:OFFSET|unix:DIR] [--threads N] [--xml-out FILE] [--frames N]\n"
    "                   [--link-mbps 1000] [--user-set-file PATH]\n"
    "  Serves the pipeline's frames as an Aravis fake GigE Vision camera on ADDRESS\n"
    "  (connect by that address). NAME: gradient, checker, flat (size from [sensor]\n"
    "  width/height, else 640x480; depth: a plane from 0.5 m at the left edge to\n"
    "  8 m at the right). --frames N: exit after N frames (0 = run until\n"
    "  SIGINT/SIGTERM). Lines: a GPIO line (libgpiod) or unix:DIR, a loopback trigger\n"
    "  bus shared by a rig of cameras (fire it with camsim-trigger). Receivers at\n"
    "  1080p need a 4 MiB socket buffer: see docs/gige.md. --link-mbps M: the stream's\n"
    "  packets leave no faster than an M Mb/s Ethernet link carries them (default\n"
    "  1000, GigE; 0 = as fast as the host sends), plus GevSCPD after each.\n"
    "  --user-set-file PATH: UserSetSave and UserSetDefault are kept in PATH (created\n"
    "  by the first save) and the start loads UserSetDefault's set from it; without\n"
    "  it user sets last as long as the process.\n";

// The whole of s as a decimal integer in [min, max] (no spaces, no '+').
bool ParseInt(const std::string& s, long min, long max, long* out) {
  if (s.empty() || !(std::isdigit(static_cast<unsigned char>(s[0])) || s[0] == '-')) return false;
  char* end = nullptr;
  errno = 0;
  const long v = std::strtol(s.c_str(), &end, 10);
  if (*end || errno != 0 || v < min || v > max) return false;
  *out = v;
  return true;
}

volatile std::sig_atomic_t g_stop = 0;
void OnSignal(int) { g_stop = 1; }

}  // namespace

int main(int argc, char** argv) {
  camsim::genicam::DeviceOptions o;
  long frames = 0;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    auto value = [&]() -> std::string {
      if (i + 1 >= argc) {
        std::fprintf(stderr, "camsim-gige: %s needs a value\n%s", a.c_str(), kUsage);
        std::exit(1);
      }
      return argv[++i];
    };
    if (a == "--config") o.config_path = value();
    else if (a == "--input") {
      o.inputs.push_back(value());
      while (i + 1 < argc && argv[i + 1][0] != '-') o.inputs.push_back(argv[++i]);
    } else if (a == "--pattern") o.pattern = value();
    else if (a == "--set") o.overrides.push_back(value());
    else if (a == "--address") o.address = value();
    else if (a == "--serial") o.serial = value();
    else if (a == "--trigger-line") o.trigger_line = value();
    else if (a == "--strobe-line") o.strobe_line = value();
    else if (a == "--xml-out") o.xml_path = value();
    else if (a == "--user-set-file") o.user_set_file = value();
    else if (a == "--threads" || a == "--frames" || a == "--link-mbps") {
      const std::string v = value();
      const long min = a == "--threads" ? 1 : 0,
                 max = a == "--threads" ? 64 : a == "--link-mbps" ? camsim::genicam::kMaxLinkMbps : 0x7fffffffL;
      long n = 0;
      if (!ParseInt(v, min, max, &n)) {
        std::fprintf(stderr, "camsim-gige: %s needs an integer %ld..%ld, not '%s'\n", a.c_str(), min, max, v.c_str());
        return 1;
      }
      if (a == "--threads") o.threads = static_cast<int>(n);
      else if (a == "--link-mbps") o.link_mbps = static_cast<int>(n);
      else frames = n;
    } else if (a == "--help" || a == "-h") {
      std::fputs(kUsage, stdout);
      return 0;
    } else {
      std::fprintf(stderr, "camsim-gige: unknown option '%s'\n%s", a.c_str(), kUsage);
      return 1;
    }
  }
  std::string error;
  auto device = camsim::genicam::GigeDevice::Start(o, &error);
  if (!device) {
    std::fprintf(stderr, "camsim-gige: %s\n", error.c_str());
    return 1;
  }
  const auto& s = device->sensor();
  std::fprintf(stderr,
               "camsim-gige: serving %dx%d %s %d-bit as serial %s on %s (GenICam XML %s), loaded %s: frames of %s\n",
               s.width, s.height, camsim::CfaName(s.cfa), s.adc_bits, o.serial.c_str(), o.address.c_str(),
               device->xml_path().c_str(), device->start_user_set().c_str(), device->FrameFormat().c_str());
  std::signal(SIGINT, OnSignal);
  std::signal(SIGTERM, OnSignal);
  while (!g_stop && (frames == 0 || device->frames_sent() < static_cast<uint64_t>(frames)))
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  std::fprintf(stderr, "camsim-gige: %llu frames sent, %llu register writes refused\n",
               static_cast<unsigned long long>(device->frames_sent()),
               static_cast<unsigned long long>(device->writes_refused()));
  return 0;
}
