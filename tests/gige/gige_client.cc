#include "tests/gige/gige_client.h"

#include <gtest/gtest.h>

#include <chrono>
#include <cstring>
#include <thread>

namespace camsim::gigetest {

genicam::DeviceOptions SmallDevice(int width, int height) {
  genicam::DeviceOptions o;
  o.config_path = std::string(CAMSIM_SOURCE_DIR) + "/configs/camera.toml";
  o.pattern = "gradient";
  o.overrides = {"sensor.width=" + std::to_string(width), "sensor.height=" + std::to_string(height)};
  o.threads = 1;
  o.xml_path = "";
  return o;
}

std::vector<uint8_t> ReferenceFrame(const genicam::DeviceOptions& opt, uint32_t index, uint32_t format, int x, int y,
                                    int w, int h, const std::vector<std::string>& extra) {
  genicam::DeviceOptions o = opt;
  o.overrides.insert(o.overrides.end(), extra.begin(), extra.end());
  host::RunConfig rc;
  host::Origins origins;
  std::vector<io::SceneFrame> scenes;
  std::string error;
  if (!genicam::LoadDeviceScenes(o, &rc, &origins, &scenes, &error)) return {};
  host::FrameRenderer r(1, 16);
  if (!r.Configure(rc, origins, scenes[0].width, scenes[0].height, nullptr, &error)) return {};
  if (!r.SetScene(scenes[index % scenes.size()], &error)) return {};
  const int sw = r.pipeline().width(), sh = r.pipeline().height();
  std::vector<uint16_t> raw(static_cast<size_t>(sw) * sh);
  std::vector<uint8_t> rgb(static_cast<size_t>(sw) * sh * 3);
  Tap taps[2];
  taps[0].stage = r.SensorIndex();
  taps[0].format = TapFormat::kU16;
  taps[0].data = raw.data();
  taps[0].stride = sw;
  taps[1].stage = r.pipeline().plan().running - 1;
  taps[1].format = TapFormat::kU8;
  taps[1].data = rgb.data();
  taps[1].stride = sw * 3;
  r.Render(index, taps, genicam::FromIsp(format, rc.core.geometry.cfa) ? 2 : 1, nullptr);
  std::vector<uint8_t> out(genicam::FrameBytes(format, w, h));
  genicam::ConvertWindow(format, rc.core.geometry.cfa, rc.core.geometry.adc_bits, raw.data(), rgb.data(), sw, x, y, w,
                         h, out.data());
  return out;
}

Client::Client(const std::string& address) {
  GError* error = nullptr;
  camera_ = arv_camera_new(address.c_str(), &error);
  if (error) {
    last_error = error->message;
    g_clear_error(&error);
    g_clear_object(&camera_);
    return;
  }
  arv_camera_gv_set_stream_options(camera_, ARV_GV_STREAM_OPTION_PACKET_SOCKET_DISABLED);
}

Client::~Client() {
  CloseStream();
  g_clear_object(&camera_);
}

bool Client::OpenStream(int buffers, int socket_buffer_bytes) {
  GError* error = nullptr;
  const guint payload = arv_camera_get_payload(camera_, &error);
  if (!error) stream_ = arv_camera_create_stream(camera_, nullptr, nullptr, &error);
  if (error) {
    last_error = error->message;
    g_clear_error(&error);
    return false;
  }
  // 4 MiB by default: a 1080p frame in flight fits (see docs/gige.md: net.core.rmem_max).
  g_object_set(stream_, "socket-buffer", ARV_GV_STREAM_SOCKET_BUFFER_FIXED, "socket-buffer-size", socket_buffer_bytes,
               nullptr);
  for (int i = 0; i < buffers; ++i) arv_stream_push_buffer(stream_, arv_buffer_new(payload, nullptr));
  return true;
}

std::vector<uint8_t> Client::Grab(int timeout_ms, uint64_t* frame_id, int* width, uint32_t* format) {
  ArvBuffer* b = arv_stream_timeout_pop_buffer(stream_, static_cast<guint64>(timeout_ms) * 1000);
  if (!b) return {};
  const uint64_t popped_ns = static_cast<uint64_t>(g_get_real_time()) * 1000;
  std::vector<uint8_t> out;
  if (arv_buffer_get_status(b) == ARV_BUFFER_STATUS_SUCCESS) {
    size_t size = 0;
    const void* data = arv_buffer_get_data(b, &size);
    out.assign(static_cast<const uint8_t*>(data), static_cast<const uint8_t*>(data) + size);
    if (frame_id) *frame_id = arv_buffer_get_frame_id(b);
    if (width) *width = arv_buffer_get_image_width(b);
    if (format) *format = arv_buffer_get_image_pixel_format(b);
    last_timestamp_ns_ = arv_buffer_get_timestamp(b);
    last_first_packet_ns_ = arv_buffer_get_system_timestamp(b);
    last_popped_ns_ = popped_ns;
  } else {
    ++failed_;
  }
  arv_stream_push_buffer(stream_, b);
  return out;
}

void Client::CloseStream() {
  if (!stream_) return;
  if (camera_) arv_camera_stop_acquisition(camera_, nullptr);
  g_clear_object(&stream_);
}

void Settle(Client& c) {
  const int64_t start = arv_camera_get_integer(c.camera(), "SimSyncCount", nullptr);
  for (int i = 0; i < 2000; ++i) {
    if (arv_camera_get_integer(c.camera(), "SimSyncCount", nullptr) >= start + 2) return;
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  // Read-backs after this would test a state the device may not have reached.
  ADD_FAILURE() << "the device did not sync twice within 10 s (SimSyncCount stayed below " << start + 2 << ")";
}

}  // namespace camsim::gigetest
