// What the benchmark files share: the bundled scenes and the demo camera.
#pragma once

#include <vector>

#include "core/pipeline/pipeline.h"
#include "host_tools/scene_input.h"

namespace camsim::bench {

// The bundled scene at 640x480 (aisle_0001.exr) or 1920x1080 (aisle1080_0001.exr).
const host::CoreInput& Scene(int width);
// The demo camera (configs/camera.toml) at a frame size.
PipelineConfig Demo(int width, int height);

// A pair of benchmarks doing the same job, camsim's and a peer's (OpenCV):
// bench_main.cc prints real-time ratios camsim/peer after the run, with the
// error each has against the double reference when the pair measured it.
struct PeerPair {
  const char* camsim;  // benchmark name, e.g. "BM_Peer_CamsimDemosaic/1920/1080/16"
  const char* peer;
  const char* what;
  const char* error_note;  // filled at run time by the peer benchmarks (static storage)
  const char* peer2;       // nullptr, or another way of the peer's to do the job at the same error
};
// error_note: where the pair's error is, when it is known before the run.
// peer2: the peer's other variant (e.g. OpenCV's other map type for remap);
// bench_main.cc pairs camsim with the faster of peer and peer2, so that the
// peer is at its best.
void AddPeerPair(const char* camsim, const char* peer, const char* what, const char* error_note = "",
                 const char* peer2 = nullptr);
void SetPeerError(const char* what, const char* note);
const std::vector<PeerPair>& PeerPairs();

}  // namespace camsim::bench
