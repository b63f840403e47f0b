#include "bench/bench_common.h"

#include <cstdlib>
#include <cstring>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "host_tools/config.h"
#include "host_tools/io/exr_scene.h"

namespace camsim::bench {

const host::CoreInput& Scene(int width) {
  static std::map<int, std::unique_ptr<host::CoreInput>> cache;
  auto& slot = cache[width];
  if (!slot) {
    const std::string name = width == 1920 ? "aisle1080_0001.exr" : "aisle_0001.exr";
    io::SceneFrame frame;
    std::string error;
    if (!io::LoadSceneExr(std::string(CAMSIM_SOURCE_DIR "/scenes/") + name, "", &frame, &error)) std::abort();
    slot = std::make_unique<host::CoreInput>();
    host::PrepareInput(frame, frame.width, frame.height, host::SceneFit::kCrop, slot.get());
  }
  return *slot;
}

PipelineConfig Demo(int w, int h) {
  host::RunConfig rc;
  host::Origins origins;
  std::string error;
  if (!host::LoadConfigFile(CAMSIM_SOURCE_DIR "/configs/camera.toml", &rc, &origins, &error) ||
      !host::FinishConfig(&rc, w, h, origins, 1, &error))
    std::abort();
  return rc.core;
}

namespace {
std::vector<PeerPair>& Pairs() {
  static std::vector<PeerPair> pairs;
  return pairs;
}
}  // namespace

void AddPeerPair(const char* camsim, const char* peer, const char* what, const char* error_note, const char* peer2) {
  Pairs().push_back(PeerPair{camsim, peer, what, error_note, peer2});
}

void SetPeerError(const char* what, const char* note) {
  for (PeerPair& p : Pairs())
    if (std::strcmp(p.what, what) == 0) p.error_note = note;
}

const std::vector<PeerPair>& PeerPairs() { return Pairs(); }

}  // namespace camsim::bench
