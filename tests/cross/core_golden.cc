// core_golden: bit-exactness of the core on every architecture it is built for.
//
// Self-contained on purpose (the core, the C++ standard library and printf;
// no GoogleTest, no OpenEXR, no TOML), so that it builds wherever camsim_core
// builds: natively, and cross-compiled for aarch64 and armhf, where it runs
// under qemu-user (scripts/cross.sh).
//
// Cases, part 1: the configure-time floating point. The deterministic
// elementary functions (core/base/detmath.h) on 20 000 arguments each (the
// bit patterns of the results are hashed), and the tables built from them
// (Gaussian and Poisson samplers, sRGB and power-law gamma). The core uses
// floating point only at configure time, and these are its longest
// computations; a last-bit difference between CPUs (e.g. a fused
// multiply-add) shows here even when rounding to integers hides it in the
// pixel output.
//
// Cases, part 2: the pipeline configurations of tests/cross/cases.h (the
// demo camera, a mono sensor, bilinear BayerBG with a colour matrix, motion
// blur and rolling shutter, a distorting lens, depth of field and structural
// blur, sensor artefacts, listed defects, flare, dark current
// non-uniformity) x two synthetic scenes
// (the TexturedScene formula and a flat field) x three sizes (67x53, 640x480
// and the tiny 5x3, smaller than the Malvar kernel) x every cut of the
// pipeline after a running stage. Each case's output (uint32 samples, the
// last running stage's) is hashed with FNV-1a 64 over its little-endian bytes,
// the convention of tests/unit/test_golden.cc, and printed as `name hash`.
//
// Each case is run three times: strips of 1 row, of 7 rows (alternating
// between two workers' rings) and the whole frame at once; the three outputs
// must be byte-identical (checked here directly, whatever the hash file says).
//
// The hashes are compared with tests/cross/core_hashes.txt, generated on
// x86-64 by the native release build and committed. Any differing, missing or
// extra case is printed and the exit status is 1.
//
//   core_golden [--update] [HASH_FILE]
//     --update   rewrite HASH_FILE with this run's hashes (only when an output
//                change is intended, and only from the native x86-64 build)
//     HASH_FILE  defaults to the source tree's tests/cross/core_hashes.txt
//   core_golden --workspace
//     only print the demo pipeline's workspace bytes at 640x480 and 1920x1080
#include <bit>
#include <chrono>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <map>
#include <memory>
#include <string>
#include <type_traits>
#include <vector>

#include "core/base/detmath.h"
#include "core/base/random.h"
#include "core/pipeline/pipeline.h"
#include "tests/cross/cases.h"

namespace {

using namespace camsim;

struct Scene {
  int width = 0;
  int height = 0;
  std::vector<uint32_t> plane[3];  // R, G, B radiance, Q16.16
  std::vector<uint32_t> inverse_depth;  // cross::DepthMetres as InverseDepthFromMetres (DoF, motion)

  FrameInput View() const {
    FrameInput in;
    for (int c = 0; c < 3; ++c) in.radiance[c] = MakeImageView<const uint32_t>(plane[c].data(), width, height);
    in.inverse_depth = MakeImageView<const uint32_t>(inverse_depth.data(), width, height);
    return in;
  }
};


// The cases' depth plane (cross::DepthMetres), read by depth of field and by
// motion blur from camera translation.
void AddDepth(Scene* s) {
  s->inverse_depth.resize(static_cast<size_t>(s->width) * s->height);
  for (int y = 0; y < s->height; ++y)
    for (int x = 0; x < s->width; ++x)
      s->inverse_depth[static_cast<size_t>(y) * s->width + x] =
          InverseDepthFromMetres(cross::DepthMetres(s->width, s->height, x, y));
}

Scene Textured(int width, int height) {
  Scene s;
  s.width = width;
  s.height = height;
  for (int c = 0; c < 3; ++c) {
    s.plane[c].resize(static_cast<size_t>(width) * height);
    for (int y = 0; y < height; ++y)
      for (int x = 0; x < width; ++x)
        s.plane[c][static_cast<size_t>(y) * width + x] = cross::TexturedRadiance(width, height, x, y, c);
  }
  AddDepth(&s);
  return s;
}

// A uniform grey field (radiance 0.5: about half the full well): isolates the
// noise, the fixed patterns and the vignetting from the scene's structure.
Scene Flat(int width, int height) {
  Scene s;
  s.width = width;
  s.height = height;
  for (int c = 0; c < 3; ++c) s.plane[c].assign(static_cast<size_t>(width) * height, Q<16, 16>::FromDouble(0.5).raw);
  AddDepth(&s);
  return s;
}

constexpr uint64_t kFnvOffset = 0xcbf29ce484222325ull;

// FNV-1a 64 of `bytes` little-endian bytes of v, whatever the CPU's order.
uint64_t Fnv1aAdd(uint64_t h, uint64_t v, int bytes) {
  for (int i = 0; i < bytes; ++i) {
    h ^= static_cast<uint8_t>(v >> (8 * i));
    h *= 0x100000001b3ull;
  }
  return h;
}

template <typename T>
uint64_t Fnv1a64(const T* samples, size_t count) {
  uint64_t h = kFnvOffset;
  for (size_t i = 0; i < count; ++i)
    h = Fnv1aAdd(h, static_cast<uint64_t>(static_cast<std::make_unsigned_t<T>>(samples[i])), sizeof(T));
  return h;
}

uint64_t Fnv1a64(const std::vector<uint32_t>& samples) { return Fnv1a64(samples.data(), samples.size()); }

// Arguments for the detmath cases: splitmix64 of the index (integers only).
uint64_t SplitMix64(uint64_t i) {
  uint64_t z = i * 0x9E3779B97F4A7C15ull + 0x9E3779B97F4A7C15ull;
  z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
  z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
  return z ^ (z >> 31);
}
// Uniform in [lo, hi): 53 random bits, exact scaling by 2^-53, then one
// multiply and one add (IEEE basic operations; -ffp-contract=off keeps them two).
double Uniform(uint64_t i, double lo, double hi) {
  return lo + (hi - lo) * (static_cast<double>(SplitMix64(i) >> 11) * 0x1p-53);
}
// Any positive finite double, subnormals included: a random bit pattern.
double AnyPositive(uint64_t i) { return std::bit_cast<double>(SplitMix64(i) % 0x7FF0000000000000ull); }

constexpr int kDetmathArgs = 20000;

// Hash of f over kDetmathArgs arguments made by arg(i).
template <typename F, typename A>
uint64_t HashFunction(F f, A arg) {
  uint64_t h = kFnvOffset;
  for (int i = 0; i < kDetmathArgs; ++i) h = Fnv1aAdd(h, std::bit_cast<uint64_t>(f(arg(i))), 8);
  return h;
}

// name -> hash of the configure-time floating point (see the file comment).
std::vector<std::pair<std::string, uint64_t>> ConfigureTimeCases() {
  namespace dm = detmath;
  std::vector<std::pair<std::string, uint64_t>> v;
  v.emplace_back("detmath/Exp", HashFunction(dm::Exp, [](int i) { return Uniform(i, -746.0, 710.0); }));
  v.emplace_back("detmath/Exp2", HashFunction(dm::Exp2, [](int i) { return Uniform(i, -1076.0, 1025.0); }));
  v.emplace_back("detmath/Log", HashFunction(dm::Log, AnyPositive));
  v.emplace_back("detmath/Log.near1", HashFunction(dm::Log, [](int i) { return Uniform(i, 0.5, 2.0); }));
  v.emplace_back("detmath/Log2", HashFunction(dm::Log2, AnyPositive));
  v.emplace_back("detmath/Pow", HashFunction([](double xy) { return dm::Pow(xy, Uniform(~std::bit_cast<uint64_t>(xy), -40.0, 40.0)); },
                                             [](int i) { return Uniform(i, 0.0, 20.0); }));
  v.emplace_back("detmath/Sin", HashFunction(dm::Sin, [](int i) { return Uniform(i, -100.0, 100.0); }));
  v.emplace_back("detmath/Sin.huge", HashFunction(dm::Sin, AnyPositive));
  v.emplace_back("detmath/Cos", HashFunction(dm::Cos, [](int i) { return Uniform(i, -100.0, 100.0); }));
  v.emplace_back("detmath/Atan", HashFunction(dm::Atan, [](int i) { return Uniform(i, -50.0, 50.0); }));
  v.emplace_back("detmath/Atan2", HashFunction([](double y) { return dm::Atan2(y, Uniform(~std::bit_cast<uint64_t>(y), -3.0, 3.0)); },
                                               [](int i) { return Uniform(i, -3.0, 3.0); }));
  v.emplace_back("detmath/InvNormalCdf", HashFunction(dm::InvNormalCdf, [](int i) { return Uniform(i, 0.0, 1.0); }));
  v.emplace_back("detmath/InvNormalCdf.tail", HashFunction(dm::InvNormalCdf, [](int i) { return AnyPositive(i) * 0x1p-1024; }));

  {
    std::vector<int32_t> storage(GaussianTable::kEntries);
    GaussianTable t;
    if (t.Build(Span<int32_t>{storage.data(), storage.size()}).ok())
      v.emplace_back("table/gaussian", Fnv1a64(storage.data(), storage.size()));
  }
  {
    std::vector<uint32_t> storage(PoissonTable::kEntries);
    PoissonTable t;
    if (t.Build(Span<uint32_t>{storage.data(), storage.size()}).ok())
      v.emplace_back("table/poisson", Fnv1a64(storage.data(), storage.size()));
  }
  for (const GammaCurve curve : {GammaCurve::kSrgb, GammaCurve::kPower}) {
    GammaConfig gc;
    gc.curve = curve;
    gc.gamma = 2.2;
    GammaStage g;
    WorkspaceCounter counter;
    g.CountTables(counter);
    std::vector<uint8_t> buffer(counter.bytes());
    Arena arena(Span<uint8_t>{buffer.data(), buffer.size()});
    if (g.Configure(gc, SensorGeometry{}).ok() && g.Init(arena).ok())
      v.emplace_back(curve == GammaCurve::kSrgb ? "table/gamma_srgb" : "table/gamma_power2.2",
                     Fnv1a64(g.table(), GammaStage::kTableSize));
  }
  return v;
}

constexpr int kWorkers = 2;

// One run of the whole frame in strips of `strip_rows`; with `alternate`,
// strip k goes to worker k % kWorkers (sequentially: no threads needed to
// show that each worker's rings are independent).
std::vector<uint32_t> Run(const Pipeline& p, const Scene& scene, uint32_t frame, int strip_rows, bool alternate) {
  const int channels = p.plan().output.channels;
  std::vector<uint32_t> out(static_cast<size_t>(p.width()) * p.height() * channels, 0xDEADBEEFu);
  Tap tap;
  tap.stage = -1;
  tap.format = TapFormat::kU32;
  tap.data = out.data();
  tap.stride = static_cast<ptrdiff_t>(p.width()) * channels;
  // The per-frame pre-passes of flare and smear, when on (as the host runs them).
  std::vector<FlareSource> sources(static_cast<size_t>(p.PrepassFlareSources()));
  FlareFrame flare;
  std::vector<uint32_t> smear(static_cast<size_t>(p.PrepassSmearEntries()));
  const FrameInput in = p.RunPrepasses(scene.View(), Span<FlareSource>{sources.data(), sources.size()}, &flare,
                                       Span<uint32_t>{smear.data(), smear.size()});
  int k = 0;
  for (int y = 0; y < p.height(); y += strip_rows, ++k)
    p.ProcessStrip(in, frame, y, y + strip_rows, alternate ? k % kWorkers : 0, &tap, 1, nullptr, nullptr);
  return out;
}

struct Config {
  const char* name;
  PipelineConfig (*make)(int width, int height);
  uint32_t frame;
};

std::map<std::string, std::string> ReadHashFile(const char* path, bool* found) {
  std::map<std::string, std::string> m;
  *found = false;
  std::FILE* f = std::fopen(path, "r");
  if (f == nullptr) return m;
  *found = true;
  char line[512], name[400], hash[64];
  while (std::fgets(line, sizeof line, f) != nullptr) {
    if (line[0] == '#' || line[0] == '\n') continue;
    if (std::sscanf(line, "%399s %63s", name, hash) == 2) m[name] = hash;
  }
  std::fclose(f);
  return m;
}

// Informational (not compared): the workspace of the demo pipeline.
void PrintWorkspace() {
  for (const auto& size : {std::pair{640, 480}, std::pair{1920, 1080}}) {
    Pipeline p;
    if (p.Configure(cross::DemoConfig(size.first, size.second), 1, false).ok())
      std::printf("# workspace demo %dx%d: tables %zu + per worker %zu = %zu bytes (1 worker)\n", size.first,
                  size.second, p.TableBytes(), p.WorkerBytes(), p.WorkspaceBytes());
  }
}

}  // namespace

int main(int argc, char** argv) {
  bool update = false;
  const char* path = CAMSIM_CORE_HASHES;
  for (int i = 1; i < argc; ++i) {
    if (std::strcmp(argv[i], "--update") == 0) {
      update = true;
    } else if (std::strcmp(argv[i], "--workspace") == 0) {
      PrintWorkspace();
      return 0;
    } else if (argv[i][0] == '-') {
      std::fprintf(stderr, "usage: core_golden [--update] [HASH_FILE] | core_golden --workspace\n");
      return 2;
    } else {
      path = argv[i];
    }
  }
  const auto t0 = std::chrono::steady_clock::now();

  const Config configs[] = {
      {"demo", cross::DemoConfig, 1},
      {"mono", cross::MonoConfig, 2},
      {"bilinear_bg", cross::BilinearBgConfig, 1000003},
      {"motion", cross::MotionConfig, 3},
      {"dof_diffusion", cross::DofDiffusionConfig, 1},
      {"dof_gather", cross::DofGatherConfig, 1},
      {"structural_blur", cross::StructuralBlurConfig, 1},
      {"lens", cross::LensConfig, 5},
      {"lens_unclamped", cross::LensUnclampedConfig, 5},
      {"lens_lanczos4", cross::LensLanczos4Config, 5},
      {"artefacts", cross::ArtefactsConfig, 11},
      {"listed_defects", cross::ListedDefectsConfig, 13},
      {"flare_environment", cross::EnvironmentFlareConfig, 17},
      {"dcnu", cross::DcnuConfig, 19},
  };
  const int sizes[][2] = {{67, 53}, {640, 480}, {5, 3}};

  std::vector<std::pair<std::string, std::string>> got;  // in run order
  int failures = 0;
  for (const auto& [name, hash] : ConfigureTimeCases()) {
    char hex[17];
    std::snprintf(hex, sizeof hex, "%016llx", static_cast<unsigned long long>(hash));
    std::printf("%s %s\n", name.c_str(), hex);
    got.emplace_back(name, hex);
  }
  for (const auto& size : sizes) {
    const int w = size[0], h = size[1];
    const Scene scenes[2] = {Textured(w, h), Flat(w, h)};
    const char* scene_names[2] = {"textured", "flat"};
    for (const Config& cfg : configs) {
      const PipelineConfig full = cfg.make(w, h);
      int leading = 0;  // leading cuts of only left-out stages (the DoF stages when off): not numbered
      std::string previous_running;
      for (int n = 1; n <= full.order_count; ++n) {
        PipelineConfig c = full;
        c.order_count = n;
        auto p = std::make_unique<Pipeline>();
        const Status st = p->Configure(c, kWorkers, false);
        if (!st.ok() && p->plan().running == 0) {  // a cut of only left-out stages
          ++leading;
          continue;
        }
        if (!st.ok()) {
          std::printf("ERROR %s %dx%d cut %d: Configure: %s %s\n", cfg.name, w, h, n, st.field(), st.message());
          ++failures;
          continue;
        }
        // A cut that runs what the previous cut ran gives its output (its last
        // stage is left out). Compared by the running stages and their formats:
        // the planner may move a Bayer CFA, or leave it to a site-only distortion.
        std::string running;
        for (int i = 0; i < p->plan().count; ++i) {
          const PlanEntry& e = p->plan().entries[i];
          if (e.runs) running += std::string(StageName(e.id)) + ":" + std::to_string(e.out.channels) + " ";
        }
        if (running == previous_running) continue;
        previous_running = running;
        std::vector<uint8_t> workspace(p->WorkspaceBytes(), 0xA5);  // not 0: nothing may depend on it
        const Status is = p->Init(Span<uint8_t>{workspace.data(), workspace.size()});
        if (!is.ok()) {
          std::printf("ERROR %s %dx%d cut %d: Init: %s\n", cfg.name, w, h, n, is.message());
          ++failures;
          continue;
        }
        for (int s = 0; s < 2; ++s) {
          char name[160];
          std::snprintf(name, sizeof name, "%s/%s/%dx%d/%d.%s", cfg.name, scene_names[s], w, h, n - leading,
                        StageName(c.order[n - 1]));
          const std::vector<uint32_t> whole = Run(*p, scenes[s], cfg.frame, h, false);
          const std::vector<uint32_t> rows1 = Run(*p, scenes[s], cfg.frame, 1, false);
          const std::vector<uint32_t> rows7 = Run(*p, scenes[s], cfg.frame, 7, true);
          if (rows1 != whole || rows7 != whole) {
            std::printf("STRIP MISMATCH %s: strips of 1 / 7 rows differ from the whole frame (%s / %s)\n", name,
                        rows1 != whole ? "differ" : "same", rows7 != whole ? "differ" : "same");
            ++failures;
          }
          char hex[17];
          std::snprintf(hex, sizeof hex, "%016llx", static_cast<unsigned long long>(Fnv1a64(whole)));
          std::printf("%s %s\n", name, hex);
          got.emplace_back(name, hex);
        }
      }
    }
  }

  // A workspace larger than size_t can count is refused at Configure, not
  // wrapped (16384 x 16384 x 3 channels of fixed pattern: 6 GiB; on armhf
  // its size wrapped to 128 KiB and Init wrote past it).
  {
    PipelineConfig c = cross::DemoConfig(16384, 16384);
    c.order[0] = StageId::kExposure;
    c.order[1] = StageId::kSensor;
    c.order_count = 2;
    c.sensor.fixed_pattern_table = true;
    auto p = std::make_unique<Pipeline>();
    const Status st = p->Configure(c, kWorkers, false);
    const bool ok = sizeof(size_t) < 8 ? st.code() == StatusCode::kResourceExhausted
                                       : st.ok() && p->WorkspaceBytes() >= size_t{24} * 16384 * 16384;
    std::printf("%s workspace of 6 GiB: %s\n", ok ? "#" : "ERROR", st.ok() ? "configured" : st.message());
    if (!ok) ++failures;
  }

  PrintWorkspace();
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  std::printf("# %zu cases in %.1f s (sizeof(void*) = %zu)\n", got.size(), seconds, sizeof(void*));

  if (update) {
    std::FILE* f = std::fopen(path, "w");
    if (f == nullptr) {
      std::printf("ERROR cannot write %s\n", path);
      return 1;
    }
    std::fprintf(f,
                 "# FNV-1a 64 of the little-endian uint32 output of each case; see tests/cross/core_golden.cc.\n"
                 "# Generated on x86-64 by the native release build (core_golden --update);\n"
                 "# aarch64 and armhf (scripts/cross.sh) must print the same.\n");
    for (const auto& [name, hash] : got) std::fprintf(f, "%s %s\n", name.c_str(), hash.c_str());
    std::fclose(f);
    std::printf("# wrote %zu hashes to %s\n", got.size(), path);
    return failures == 0 ? 0 : 1;
  }

  bool found = false;
  std::map<std::string, std::string> expected = ReadHashFile(path, &found);
  if (!found || expected.empty()) {
    std::printf("FAIL: no hashes in %s (generate them with core_golden --update on x86-64)\n", path);
    return 1;
  }
  int differ = 0;
  for (const auto& [name, hash] : got) {
    auto it = expected.find(name);
    if (it == expected.end()) {
      std::printf("NEW      %s %s (not in %s)\n", name.c_str(), hash.c_str(), path);
      ++differ;
    } else {
      if (it->second != hash) {
        std::printf("DIFFERS  %s expected %s got %s\n", name.c_str(), it->second.c_str(), hash.c_str());
        ++differ;
      }
      expected.erase(it);
    }
  }
  for (const auto& [name, hash] : expected) {
    std::printf("MISSING  %s %s (in %s, not run)\n", name.c_str(), hash.c_str(), path);
    ++differ;
  }
  if (differ > 0 || failures > 0) {
    std::printf("FAIL: %d of %zu hashes differ from %s, %d other failures\n", differ, got.size(), path, failures);
    return 1;
  }
  std::printf("OK: all %zu hashes match %s\n", got.size(), path);
  return 0;
}
