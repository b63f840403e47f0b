// camsim_gige_fps: frames per second a camsim-gige device delivers to an
// Aravis client over loopback, and how many frames were lost on the way.
//   camsim_gige_fps [--width W] [--height H] [--format BayerRG8|BayerRG12|RGB8|...]
//                   [--frames N] [--threads T] [--packet-size B] [--config FILE] [--prime 0|1]
//                   [--reconfigures N] [--rate FPS] [--exposure-auto Off|Continuous] [--link-mbps M]
// --prime 0 turns off the device's first-frame leader (GigeDevice::PrimeReceiver)
// to show the first frame lost to the default socket buffer.
// --reconfigures N first times N ExposureTime writes, each synced at once
// (GigeDevice::SyncNow: the pipeline planned, checked and rebuilt), and
// prints the median time per write, and of it the time to the write's
// answer (the write filter's checks, the pipeline planned without tables).
// --rate FPS sets AcquisitionFrameRate (default: AcquisitionFrameRateEnable
// off, frames as fast as they are made).
// --link-mbps M: the stream's pacing (camsim-gige's option; 0 = unpaced).
// --exposure-auto Continuous: the device's auto exposure sets ExposureTime
// and Gain after every frame (each step rebuilds the pipeline).
// The device runs in this process (its render threads + Aravis's GVCP/GVSP
// thread) with the demo configuration (every stage on).
#include <arv.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>
#include <vector>

#include "genicam/device.h"

int main(int argc, char** argv) {
  camsim::genicam::DeviceOptions o;
  o.config_path = std::string(CAMSIM_SOURCE_DIR) + "/configs/camera.toml";
  o.pattern = "gradient";
  int width = 1920, height = 1080, frames = 100, packet = 9000, reconfigures = 0;
  double rate = 0.0;
  std::string format = "BayerRG8", exposure_auto = "Off";
  const auto usage = [](FILE* f) {
    std::fputs("usage: camsim_gige_fps [--width W] [--height H] [--format BayerRG8|BayerRG12|RGB8|...]\n"
               "                       [--frames N] [--threads T] [--packet-size B] [--config FILE] [--prime 0|1]\n"
               "                       [--reconfigures N] [--rate FPS] [--exposure-auto Off|Continuous] [--link-mbps M]\n",
               f);
  };
  // A whole number in [lo, hi], or a clear error naming the option.
  bool bad = false;
  const auto integer = [&](const std::string& a, const std::string& v, int lo, int hi) {
    char* end = nullptr;
    const long n = std::strtol(v.c_str(), &end, 10);
    if (v.empty() || *end != '\0' || n < lo || n > hi) {
      std::fprintf(stderr, "camsim_gige_fps: %s '%s': a whole number in %d .. %d\n", a.c_str(), v.c_str(), lo, hi);
      bad = true;
      return lo;
    }
    return static_cast<int>(n);
  };
  for (int i = 1; i < argc; i += 2) {
    const std::string a = argv[i];
    if (a == "--help" || a == "-h") {
      usage(stdout);
      return 0;
    }
    if (i + 1 >= argc) {
      std::fprintf(stderr, "camsim_gige_fps: %s needs a value\n", a.c_str());
      usage(stderr);
      return 1;
    }
    const std::string v = argv[i + 1];
    if (a == "--width") width = integer(a, v, 2, 16384);
    else if (a == "--height") height = integer(a, v, 2, 16384);
    else if (a == "--format") format = v;
    else if (a == "--frames") frames = integer(a, v, 1, 1000000);
    else if (a == "--threads") o.threads = integer(a, v, 1, 256);
    else if (a == "--packet-size") packet = integer(a, v, 576, 16384);
    else if (a == "--config") o.config_path = v;
    else if (a == "--prime") o.prime_first_frame = integer(a, v, 0, 1) != 0;
    else if (a == "--link-mbps") o.link_mbps = integer(a, v, 0, camsim::genicam::kMaxLinkMbps);
    else if (a == "--reconfigures") reconfigures = integer(a, v, 0, 1000000);
    else if (a == "--rate") {
      char* end = nullptr;
      rate = std::strtod(v.c_str(), &end);
      if (v.empty() || *end != '\0' || !(rate > 0.0 && rate <= 1e6)) {
        std::fprintf(stderr, "camsim_gige_fps: --rate '%s': frames per second, above 0\n", v.c_str());
        bad = true;
      }
    } else if (a == "--exposure-auto") exposure_auto = v;
    else {
      std::fprintf(stderr, "camsim_gige_fps: unknown option %s\n", a.c_str());
      usage(stderr);
      return 1;
    }
  }
  if (bad) return 1;
  o.overrides = {"sensor.width=" + std::to_string(width), "sensor.height=" + std::to_string(height)};
  std::string error;
  auto device = camsim::genicam::GigeDevice::Start(o, &error);
  if (!device) {
    std::fprintf(stderr, "camsim_gige_fps: %s\n", error.c_str());
    return 1;
  }
  if (reconfigures > 0) {
    std::vector<double> ms, answer_ms;  // the write and its sync; the write alone (the filter's checks and plan)
    for (int i = 0; i < reconfigures; ++i) {
      const double us = i % 2 ? 10000.0 : 5000.0;  // alternating, so every write changes the value
      uint64_t bits;
      std::memcpy(&bits, &us, 8);
      uint8_t be[8];
      for (int k = 0; k < 8; ++k) be[k] = static_cast<uint8_t>(bits >> (56 - 8 * k));  // as a client sends it
      const auto t = std::chrono::steady_clock::now();
      device->WriteMemory(camsim::genicam::reg::kExposureTime, be, 8);
      const auto answered = std::chrono::steady_clock::now();
      device->SyncNow();
      ms.push_back(std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t).count());
      answer_ms.push_back(std::chrono::duration<double, std::milli>(answered - t).count());
    }
    std::sort(ms.begin(), ms.end());
    std::sort(answer_ms.begin(), answer_ms.end());
    std::printf("%dx%d, %d thread(s): %.2f ms per ExposureTime write, %.2f ms of it before the write's answer "
                "(medians of %d, the pipeline planned as the write arrives, its tables built by the sync)\n",
                width, height, o.threads, ms[ms.size() / 2], answer_ms[answer_ms.size() / 2], reconfigures);
  }
  GError* e = nullptr;
  ArvCamera* cam = arv_camera_new(o.address.c_str(), &e);
  if (!cam) {
    std::fprintf(stderr, "camsim_gige_fps: %s\n", e ? e->message : "no camera");
    return 1;
  }
  arv_camera_gv_set_stream_options(cam, ARV_GV_STREAM_OPTION_PACKET_SOCKET_DISABLED);
  arv_camera_set_register_cache_policy(cam, ARV_REGISTER_CACHE_POLICY_DISABLE);
  arv_camera_set_pixel_format_from_string(cam, format.c_str(), &e);
  if (!e) arv_camera_set_boolean(cam, "AcquisitionFrameRateEnable", rate > 0, &e);
  if (!e && rate > 0) arv_camera_set_float(cam, "AcquisitionFrameRate", rate, &e);
  if (!e) arv_camera_gv_set_packet_size(cam, packet, &e);
  if (!e) arv_camera_set_string(cam, "ExposureAuto", exposure_auto.c_str(), &e);
  if (e) {
    std::fprintf(stderr, "camsim_gige_fps: %s\n", e->message);
    return 1;
  }
  g_usleep(500000);  // the device's register sync rebuilds the pipeline for the new format
  const guint payload = arv_camera_get_payload(cam, nullptr);
  ArvStream* stream = arv_camera_create_stream(cam, nullptr, nullptr, &e);
  if (!stream) {
    std::fprintf(stderr, "camsim_gige_fps: %s\n", e ? e->message : "no stream");
    return 1;
  }
  g_object_set(stream, "socket-buffer", ARV_GV_STREAM_SOCKET_BUFFER_FIXED, "socket-buffer-size", 4 << 20, nullptr);
  for (int i = 0; i < 8; ++i) arv_stream_push_buffer(stream, arv_buffer_new(payload, nullptr));
  arv_camera_start_acquisition(cam, nullptr);
  // The first good frame starts the clock (whichever buffer it is), the last
  // good frame stops it: fps = frames after the first / the time between. A
  // timeout ends the run; the frames that never came are counted as short.
  int ok = 0, failed = 0;
  bool started = false;
  guint64 gaps = 0, last_id = 0;
  auto t0 = std::chrono::steady_clock::now(), t_last = t0;
  for (int i = 0; i < frames + 1; ++i) {
    ArvBuffer* b = arv_stream_timeout_pop_buffer(stream, 5000000);
    if (!b) {
      std::fprintf(stderr, "camsim_gige_fps: timeout after %d of %d buffers\n", i, frames + 1);
      break;
    }
    if (arv_buffer_get_status(b) == ARV_BUFFER_STATUS_SUCCESS) {
      const guint64 id = arv_buffer_get_frame_id(b);
      const auto now = std::chrono::steady_clock::now();
      if (started) ++ok;
      else t0 = now;
      started = true;
      t_last = now;
      if (last_id && id != last_id + 1) gaps += id - last_id - 1;
      last_id = id;
    } else {
      ++failed;
      std::fprintf(stderr, "camsim_gige_fps: buffer %d failed, status %d\n", i, arv_buffer_get_status(b));
    }
    arv_stream_push_buffer(stream, b);
  }
  const double s = std::chrono::duration<double>(t_last - t0).count();
  const double fps = s > 0 ? ok / s : 0.0;
  const int short_by = frames - ok;  // frames asked for that did not arrive (lost, failed or never sent)
  guint64 completed = 0, stream_failures = 0, underruns = 0;
  arv_stream_get_statistics(stream, &completed, &stream_failures, &underruns);
  // Missing packets: lost in the socket buffer; duplicated: the primed leader (one per stream).
  const guint64 missing = arv_stream_get_info_uint64_by_name(stream, "n_missing_packets");
  const guint64 duplicated = arv_stream_get_info_uint64_by_name(stream, "n_duplicated_packets");
  arv_camera_stop_acquisition(cam, nullptr);
  std::printf("%dx%d %s, %d thread(s), packet %d B, ExposureAuto %s: %d of %d frames in %.2f s = %.2f fps, %.1f MB/s; "
              "failed buffers %d, frame-id gaps %llu, underruns %llu, missing packets %llu, duplicated %llu\n",
              width, height, format.c_str(), o.threads, packet, exposure_auto.c_str(), ok, frames, s, fps,
              fps * (payload / 1e6), failed, static_cast<unsigned long long>(gaps),
              static_cast<unsigned long long>(underruns), static_cast<unsigned long long>(missing),
              static_cast<unsigned long long>(duplicated));
  g_object_unref(stream);
  g_object_unref(cam);
  // Non-zero when any frame asked for is missing: failed, skipped (frame-id
  // gaps) or never arrived (timeout).
  return failed == 0 && gaps == 0 && short_by == 0 ? 0 : 2;
}
