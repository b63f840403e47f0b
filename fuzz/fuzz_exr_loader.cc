// fuzz_exr_loader: the bytes as an OpenEXR file for io::LoadSceneExr (which
// takes a path, so they go to an in-memory file opened by path). Errors are fine;
// a crash, leak, hang or an accepted frame that breaks the documented rules
// (sizes, sanitised samples) is not. An accepted file is also loaded as its
// own separate depth file, which exercises the depth-file path.
#include <sys/mman.h>
#include <unistd.h>

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <limits>
#include <string>

#include "fuzz/fuzz_common.h"
#include <OpenEXR/openexr.h>

#include "host_tools/io/exr_scene.h"

namespace {

// The input lives in an anonymous in-memory file (memfd), opened by path as
// /proc/self/fd/N: nothing is left behind, even when the fuzzer dies.
struct MemFile {
  int fd = -1;
  std::string path;
  MemFile() {
    fd = memfd_create("camsim_fuzz_exr", 0);
    FUZZ_CHECK(fd >= 0, "memfd_create failed");
    path = "/proc/self/fd/" + std::to_string(fd);
  }
  void Set(const uint8_t* data, size_t size) const {
    FUZZ_CHECK(ftruncate(fd, 0) == 0, "ftruncate");
    size_t done = 0;
    while (done < size) {
      const ssize_t n = pwrite(fd, data + done, size - done, static_cast<off_t>(done));
      FUZZ_CHECK(n > 0, "pwrite");
      done += static_cast<size_t>(n);
    }
  }
};

// Not instrumented (coverage, ASan: plain in-bounds reads of a vector): a
// display window of up to 2^25 pixels from a few hundred bytes makes these
// loops long, and they find nothing new anyway.
__attribute__((no_sanitize("coverage", "address"))) void CheckPlane(const camsim::io::FloatPlane& p,
                                                                    const camsim::io::SceneFrame& f,
                                                                    const char* what, bool radiance, bool motion) {
  FUZZ_CHECK(p.width == f.width && p.height == f.height &&
                 p.data.size() == static_cast<size_t>(f.width) * static_cast<size_t>(f.height),
             "%s plane is %d x %d (%zu samples), frame %d x %d", what, p.width, p.height, p.data.size(), f.width,
             f.height);
  const float* v = p.data.data();
  const size_t n = p.data.size();
  size_t bad = 0;
  if (radiance) {
    for (size_t i = 0; i < n; ++i) bad += !(v[i] >= 0.0f && v[i] <= std::numeric_limits<float>::max());
  } else if (motion) {
    for (size_t i = 0; i < n; ++i) bad += !(v[i] >= -std::numeric_limits<float>::max() &&
                                            v[i] <= std::numeric_limits<float>::max());
  } else {
    for (size_t i = 0; i < n; ++i) bad += v[i] != v[i];  // NaN
  }
  FUZZ_CHECK(bad == 0, "%zu %s samples break the sanitising rules (radiance finite and >= 0, motion finite, "
             "depth not NaN)", bad, what);
}

void CheckFrame(const camsim::io::SceneFrame& f) {
  FUZZ_CHECK(f.width >= 1 && f.height >= 1 && f.width <= 16384 && f.height <= 16384, "frame %d x %d", f.width,
             f.height);
  CheckPlane(f.r, f, "r", true, false);
  CheckPlane(f.g, f, "g", true, false);
  CheckPlane(f.b, f, "b", true, false);
  if (f.has_depth) CheckPlane(f.depth, f, "depth", false, false);
  if (f.has_motion) {
    CheckPlane(f.motion_x, f, "motion_x", false, true);
    CheckPlane(f.motion_y, f, "motion_y", false, true);
  }
  FUZZ_CHECK(!f.layout.empty() && !f.source.empty(), "layout or source empty");
}

// The loader accepts display windows up to 2^25 pixels (8K UHD) whatever
// the file's size, so a header of a few hundred bytes can make it allocate
// and fill about 0.5 GB (an 8192 x 4096 window with depth and motion: 1.7 GB
// through `camsim run`). Such inputs only exhaust -rss_limit_mb and the time
// limit without exercising anything new, so they are skipped: when
// OpenEXRCore can read the headers and some part's display window is larger
// than this, the input is not loaded.
constexpr int64_t kMaxFuzzPixels = int64_t{1} << 22;

bool HugeDisplayWindow(const std::string& path) {
  exr_context_t ctx = nullptr;
  exr_context_initializer_t init = EXR_DEFAULT_CONTEXT_INITIALIZER;
  init.flags = EXR_CONTEXT_FLAG_SILENT_HEADER_PARSE;
  bool huge = false;
  int parts = 0;
  if (exr_start_read(&ctx, path.c_str(), &init) == EXR_ERR_SUCCESS && exr_get_count(ctx, &parts) == EXR_ERR_SUCCESS) {
    for (int p = 0; p < parts; ++p) {
      exr_attr_box2i_t d;
      if (exr_get_display_window(ctx, p, &d) != EXR_ERR_SUCCESS) continue;
      const int64_t w = int64_t{d.max.x} - d.min.x + 1, h = int64_t{d.max.y} - d.min.y + 1;
      huge |= w > 0 && h > 0 && w * h > kMaxFuzzPixels;
    }
  }
  if (ctx != nullptr) exr_finish(&ctx);
  return huge;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  static const MemFile file;
  file.Set(data, size);
  const std::string& path = file.path;
  if (HugeDisplayWindow(path)) return 0;

  camsim::io::SceneFrame frame;
  std::string error;
  if (!camsim::io::LoadSceneExr(path, "", &frame, &error)) {
    FUZZ_CHECK(!error.empty(), "LoadSceneExr failed without an error message");
    FUZZ_CHECK(frame.width == 0 && frame.r.data.empty(), "a failed load changed *out");
    return 0;
  }
  CheckFrame(frame);
  frame = {};  // one frame in memory at a time
  camsim::io::SceneFrame with_depth;
  if (camsim::io::LoadSceneExr(path, path, &with_depth, &error)) {
    CheckFrame(with_depth);
    FUZZ_CHECK(with_depth.has_depth, "separate depth file accepted but has_depth is false");
  } else {
    FUZZ_CHECK(!error.empty(), "LoadSceneExr (separate depth) failed without an error message");
  }
  return 0;
}
