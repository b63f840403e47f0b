// camsim: command-line front end.
//   camsim run --config FILE --input EXR... --out DIR [options]
//   camsim config --default | --check FILE | --preset NAME | --presets
//   camsim emva --preset NAME | --config FILE [--set k=v]... [--size N] [--levels N]
//   camsim emva --dataset EMVA1288_DESCRIPTOR
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <new>
#include <string>
#include <system_error>
#include <utility>
#include <vector>
#include <algorithm>
#include <cmath>

#include "host_tools/io/exr_scene.h"
#include "host_tools/io/image_write.h"

#include "host_tools/config.h"
#include "host_tools/pattern.h"
#include "host_tools/emva_dataset.h"
#include "host_tools/emva_measure.h"
#include "host_tools/presets.h"
#include "host_tools/report/tradeoff.h"
#include "host_tools/run.h"

namespace {

// Each command's usage (`camsim COMMAND --help`); `camsim --help` prints them all.
const char kRunUsage[] =
    "  camsim run --input EXR... --out DIR [--preset NAME] [--config FILE] [--depth EXR] [--threads N]\n"
    "             [--strip-rows N] [--stages a,b,c] [--set section.key=value]... [--report FILE|-]\n"
    "             [--first-frame N] [--dump-stages] [--quiet] [--calibration YAML] [--measure-savings N]\n"
    "      EXR: a file, a directory of .exr files, or a printf pattern (frame_%04d.exr)\n"
    "      --depth: a separate depth file, for a single input frame\n"
    "      --strip-rows: rows per strip (default: one strip per thread; same bytes)\n"
    "      --stages: run only these stages, in the configured order ([pipeline] stages)\n"
    "      --report: the run's JSON report (- : to standard output); a failed run writes its error there\n"
    "      --measure-savings: time each frame N (1..1000) more times with the stages' skipping on and off\n"
    "      --dump-stages: each running stage's output as NAME.K_STAGE.exr: R, G, B (or Y) as float in its\n"
    "        unit, and exactly as uint32 line samples in code.R, code.G, code.B (code.Y)\n";
const char kConfigUsage[] =
    "  camsim config --default          print the annotated default configuration\n"
    "  camsim config --check FILE       parse and validate a configuration\n"
    "  camsim config --preset NAME      print a camera preset (EMVA 1288 data of a real camera)\n"
    "  camsim config --presets          list the camera presets\n";
const char kEmvaUsage[] =
    "  camsim emva [--preset NAME] [--config FILE] [--set section.key=value]... [--size N] [--levels N]\n"
    "  camsim emva --dataset EMVA1288_DESCRIPTOR   (measure a recorded camera's frames)\n"
    "      EMVA 1288 photon-transfer measurement of the emulated sensor, measured vs configured\n"
    "      --size: frame side 16..4096, --levels: exposure levels 20..1000\n";
const char kTradeoffUsage[] =
    "  camsim tradeoff --input EXR --out DIR [--config FILE] [--set section.key=value]... [--frames N]\n"
    "      error against run time for every precision knob of the running stages:\n"
    "      DIR/tradeoff.csv, tradeoff.md and tradeoff.png (--frames: 1..1000)\n";
const char kPreviewUsage[] =
    "  camsim preview --input EXR --out PNG [--scale S]\n"
    "      the ideal (perfect-camera) view of a scene: sRGB of radiance * S (S > 0), clipped\n";

std::string UsageOf(const char* section) { return std::string("usage:\n") + section; }

std::string FullUsage() {
  return std::string("usage:\n") + kRunUsage + kConfigUsage + camsim::host::kPatternUsage + kEmvaUsage +
         kTradeoffUsage + kPreviewUsage;
}

bool ParseInt(const char* s, long lo, long hi, long* out) {
  char* end = nullptr;
  const long v = std::strtol(s, &end, 10);
  if (end == s || *end != '\0' || v < lo || v > hi) return false;
  *out = v;
  return true;
}

// Reads the "--name value" pairs of argv[2..]: take(name, value, &why)
// stores one and returns false for an unknown name or a bad value (why: the
// values allowed; empty for an unknown name). At the first missing or bad
// value it says which, with the command's usage, and returns false.
template <typename Take>
bool ReadOptionPairs(int argc, char** argv, const char* usage, Take take) {
  for (int i = 2; i < argc; i += 2) {
    if (i + 1 >= argc) {
      std::fprintf(stderr, "camsim: %s needs a value\n%s", argv[i], UsageOf(usage).c_str());
      return false;
    }
    std::string why;
    if (!take(std::string(argv[i]), argv[i + 1], &why)) {
      if (why.empty()) why = "unknown option '" + std::string(argv[i]) + "'";
      std::fprintf(stderr, "camsim: bad option '%s %s': %s\n%s", argv[i], argv[i + 1], why.c_str(),
                   UsageOf(usage).c_str());
      return false;
    }
  }
  return true;
}

// Takes a whole number in [lo, hi] into *out, or says the range in *why.
bool TakeInt(const char* v, long lo, long hi, int* out, std::string* why) {
  long n = 0;
  if (!ParseInt(v, lo, hi, &n)) {
    *why = "expected a whole number in [" + std::to_string(lo) + ", " + std::to_string(hi) + "]";
    return false;
  }
  *out = static_cast<int>(n);
  return true;
}

// A bad command line does not stop the parse: the rest may hold --report,
// where RunCommand then writes the error (so an older report cannot pass for
// this run's). The first error counts.
int Run(int argc, char** argv) {
  camsim::host::RunOptions o;
  bool usage = false;
  const auto bad = [&o](const std::string& message) {
    if (o.option_error.empty()) o.option_error = message;
  };
  // A missing value (the last option) fails the run like any bad option:
  // through RunCommand, so that --report (given earlier) records it.
  bool missing = false;
  for (int i = 2; i < argc && !missing; ++i) {
    const std::string a = argv[i];
    auto value = [&](const char* what) -> const char* {
      if (i + 1 >= argc) {
        bad(a + " needs " + what);
        missing = true;
        return "";
      }
      return argv[++i];
    };
    long n = 0;
    if (a == "--config") o.config_path = value("a file");
    else if (a == "--preset") o.preset = value("a name");
    else if (a == "--input") {
      o.inputs.push_back(value("a file"));
      while (i + 1 < argc && argv[i + 1][0] != '-') o.inputs.push_back(argv[++i]);
    } else if (a == "--depth") o.depth_path = value("a file");
    else if (a == "--out") o.out_dir = value("a directory");
    else if (a == "--set") o.overrides.push_back(value("section.key=value"));
    else if (a == "--calibration") {
      // distortion.calibration as a TOML literal string.
      const std::string path = value("an OpenCV or ROS calibration YAML file");
      if (path.find_first_of("'\n") != std::string::npos)
        bad("--calibration: the path must not contain ' or a newline");
      else
        o.calibration_path = path;
    }
    else if (a == "--stages") {
      o.stages = value("a list");
      o.stages_given = true;
    }
    else if (a == "--report") {
      const char* path = value("a file (or - for standard output)");
      if (!missing) o.report_path = path;  // else an earlier --report records the error
    }
    else if (a == "--dump-stages") o.dump_stages = true;
    else if (a == "--quiet") o.quiet = true;
    else if (a == "--threads" || a == "--strip-rows" || a == "--first-frame" || a == "--measure-savings") {
      const char* v = value("a number");
      const long lo = a == "--first-frame" ? 0 : 1;
      const long hi = a == "--threads" ? 64 : (a == "--measure-savings" ? 1000 : 2147483647L);
      if (missing) break;
      if (!ParseInt(v, lo, hi, &n)) {
        bad(a + ": '" + v + "' is not a whole number in [" + std::to_string(lo) + ", " + std::to_string(hi) + "]");
        continue;
      }
      if (a == "--threads") o.threads = static_cast<int>(n);
      else if (a == "--strip-rows") o.strip_rows = static_cast<int>(n);
      else if (a == "--measure-savings") o.savings_rounds = static_cast<int>(n);
      else o.first_frame = static_cast<uint32_t>(n);
    } else {
      bad("unknown option '" + a + "'");
      usage = true;
    }
  }
  if (o.inputs.empty() && !missing) {
    bad("--input is required");
    usage = true;
  }
  const int code = camsim::host::RunCommand(o);
  if (usage) std::fputs(UsageOf(kRunUsage).c_str(), stderr);
  return code;
}

int Config(int argc, char** argv) {
  if (argc == 3 && std::strcmp(argv[2], "--default") == 0) {
    std::fputs(camsim::host::DefaultConfigToml().c_str(), stdout);
    return 0;
  }
  const bool known = argc >= 3 && (std::strcmp(argv[2], "--default") == 0 || std::strcmp(argv[2], "--check") == 0 ||
                                   std::strcmp(argv[2], "--preset") == 0 || std::strcmp(argv[2], "--presets") == 0);
  if (argc == 4 && std::strcmp(argv[2], "--check") == 0) {
    camsim::host::RunConfig rc;
    camsim::host::Origins origins;
    std::string error;
    // Without an input, the size check uses the configured size or a VGA stand-in.
    if (!camsim::host::LoadConfigFile(argv[3], &rc, &origins, &error)) {
      std::fprintf(stderr, "camsim: %s\n", error.c_str());
      return 1;
    }
    const bool stand_in = rc.width == 0 || rc.height == 0;
    const camsim::host::RunConfig given = rc;
    if (!camsim::host::FinishConfig(&rc, rc.width ? rc.width : 640, rc.height ? rc.height : 480, origins, 1, &error)) {
      std::fprintf(stderr, "camsim: %s\n", error.c_str());
      // The stand-in is worth a word only when the error can depend on the
      // size: when the check at other sizes passes or says something else
      // (not for f_number = 200 or adc_bits = 17).
      bool size_matters = false;
      for (const auto& [w, h] : {std::pair<int, int>{320, 240}, std::pair<int, int>{1920, 1080}}) {
        if (!stand_in) break;
        camsim::host::RunConfig other = given;
        std::string other_error;
        size_matters = size_matters ||
                       !(!camsim::host::FinishConfig(&other, given.width ? given.width : w,
                                                     given.height ? given.height : h, origins, 1, &other_error) &&
                         other_error == error);
      }
      if (stand_in && size_matters)
        std::fprintf(stderr,
                     "camsim: (the file sets no sensor.width and sensor.height, so this check used a 640x480 "
                     "stand-in; `camsim run` takes the size of its input)\n");
      return 1;
    }
    std::printf("%s: ok\n", argv[3]);
    return 0;
  }
  if (argc == 4 && std::strcmp(argv[2], "--preset") == 0) {
    const camsim::host::Preset* p = camsim::host::FindPreset(argv[3]);
    if (p == nullptr) {
      std::fprintf(stderr, "camsim: unknown preset '%s' (camsim config --presets lists them)\n", argv[3]);
      return 1;
    }
    std::fputs(p->toml, stdout);
    return 0;
  }
  if (argc == 3 && std::strcmp(argv[2], "--presets") == 0) {
    for (const camsim::host::Preset& p : camsim::host::Presets()) std::printf("%-22s %s\n", p.name, p.summary);
    return 0;
  }
  if (argc < 3) std::fputs("camsim: config needs one of --default, --check FILE, --preset NAME, --presets\n", stderr);
  else if (!known) std::fprintf(stderr, "camsim: config: unknown option '%s'\n", argv[2]);
  else std::fprintf(stderr, "camsim: config %s: wrong number of arguments\n", argv[2]);
  std::fputs(UsageOf(kConfigUsage).c_str(), stderr);
  return 1;
}

int Tradeoff(int argc, char** argv) {
  camsim::host::TradeoffOptions o;
  const bool read = ReadOptionPairs(argc, argv, kTradeoffUsage, [&](const std::string& a, const char* v, std::string* why) {
    if (a == "--input") o.input = v;
    else if (a == "--out") o.out_dir = v;
    else if (a == "--config") o.config_path = v;
    else if (a == "--set") o.overrides.push_back(v);
    else if (a == "--frames") return TakeInt(v, 1, 1000, &o.frames, why);
    else return false;
    return true;
  });
  if (!read) return 1;
  return camsim::host::TradeoffCommand(o);
}

// EMVA 1288 measurement of a configured sensor (a preset, a file, overrides).
int Emva(int argc, char** argv) {
  camsim::host::RunConfig rc;
  camsim::host::Origins origins;
  camsim::host::EmvaOptions options;
  std::string error, title;
  std::vector<std::string> overrides;
  std::string preset, config_path, dataset;
  const bool read = ReadOptionPairs(argc, argv, kEmvaUsage, [&](const std::string& a, const char* v, std::string* why) {
    if (a == "--preset") preset = v;
    else if (a == "--dataset") dataset = v;
    else if (a == "--config") config_path = v;
    else if (a == "--set") overrides.push_back(v);
    else if (a == "--size") return TakeInt(v, 16, 4096, &options.size, why);
    else if (a == "--levels") return TakeInt(v, 20, 1000, &options.levels, why);
    else return false;
    return true;
  });
  if (!read) return 1;
  if (!dataset.empty()) {
    if (!preset.empty() || !config_path.empty() || !overrides.empty()) {
      std::fprintf(stderr, "camsim: --dataset measures recorded frames; it takes no --preset, --config or --set\n");
      return 1;
    }
    camsim::host::EmvaDatasetReport report;
    if (!camsim::host::MeasureEmvaDataset(dataset, &report, &error)) {
      std::fprintf(stderr, "camsim: %s\n", error.c_str());
      return 1;
    }
    std::fputs(camsim::host::FormatEmvaDatasetReport(dataset, report).c_str(), stdout);
    return 0;
  }
  if (!preset.empty() && !camsim::host::ApplyPreset(preset, &rc, &origins, &error)) {
    std::fprintf(stderr, "camsim: %s\n", error.c_str());
    return 1;
  }
  if (!config_path.empty() && !camsim::host::LoadConfigFile(config_path, &rc, &origins, &error)) {
    std::fprintf(stderr, "camsim: %s\n", error.c_str());
    return 1;
  }
  for (const std::string& s : overrides)
    if (!camsim::host::ApplyOverride(s, &rc, &origins, &error)) {
      std::fprintf(stderr, "camsim: %s\n", error.c_str());
      return 1;
    }
  camsim::host::EmvaReport report;
  if (!camsim::host::MeasureEmva(rc, origins, options, &report, &error)) {
    std::fprintf(stderr, "camsim: %s\n", error.c_str());
    return 1;
  }
  title = preset.empty() ? (config_path.empty() ? "default sensor" : config_path) : preset;
  std::fputs(camsim::host::FormatEmvaReport(title, report).c_str(), stdout);
  return 0;
}

// The "before" picture: what a perfect camera would show (no noise, no lens,
// no mosaic): sRGB encoding of radiance * scale, clipped to [0, 1].
int Preview(int argc, char** argv) {
  std::string input, output;
  double scale = 1.0;
  const bool read = ReadOptionPairs(argc, argv, kPreviewUsage, [&](const std::string& a, const char* v, std::string* why) {
    char* end = nullptr;
    if (a == "--input") input = v;
    else if (a == "--out") output = v;
    else if (a == "--scale") scale = std::strtod(v, &end);
    else return false;
    if (end == nullptr || (end != v && *end == '\0' && scale > 0 && std::isfinite(scale))) return true;
    *why = "expected a finite number > 0";
    return false;
  });
  if (!read) return 1;
  if (input.empty() || output.empty()) {
    std::fprintf(stderr, "camsim: preview needs %s\n%s",
                 input.empty() && output.empty() ? "--input EXR and --out PNG"
                 : input.empty()                 ? "--input EXR"
                                                 : "--out PNG",
                 UsageOf(kPreviewUsage).c_str());
    return 1;
  }
  std::error_code same_error;  // equivalent() is false, with an error, when the output does not exist
  if (std::filesystem::equivalent(input, output, same_error)) {
    std::fprintf(stderr, "camsim: preview --out '%s' would overwrite the input '%s'\n", output.c_str(), input.c_str());
    return 1;
  }
  camsim::io::SceneFrame scene;
  std::string error, target;
  if (!camsim::io::WritableTarget(output, &target, &error)) {  // a FIFO or device: refused before the work
    std::fprintf(stderr, "camsim: %s\n", error.c_str());
    return 2;
  }
  if (!camsim::io::LoadSceneExr(input, "", &scene, &error)) {
    std::fprintf(stderr, "camsim: %s\n", error.c_str());
    return 1;
  }
  std::vector<uint8_t> rgb(static_cast<size_t>(scene.width) * scene.height * 3);
  const camsim::io::FloatPlane* planes[3] = {&scene.r, &scene.g, &scene.b};
  for (size_t i = 0; i < rgb.size() / 3; ++i)
    for (int c = 0; c < 3; ++c) {
      const double v = std::min(1.0, std::max(0.0, planes[c]->data[i] * scale));
      const double e = v <= 0.0031308 ? 12.92 * v : 1.055 * std::pow(v, 1 / 2.4) - 0.055;
      rgb[i * 3 + c] = static_cast<uint8_t>(std::lround(e * 255.0));
    }
  if (!camsim::io::WritePng(output, rgb.data(), scene.width, scene.height, 3, 8, scene.width * 3, &error)) {
    std::fprintf(stderr, "camsim: %s\n", error.c_str());
    return 2;
  }
  return 0;
}

int Main(int argc, char** argv) {
  struct Command {
    const char* name;
    int (*run)(int, char**);
    const char* usage;
  };
  static const Command kCommands[] = {
      {"run", Run, kRunUsage},
      {"config", Config, kConfigUsage},
      {"pattern", camsim::host::PatternCommand, camsim::host::kPatternUsage},
      {"emva", Emva, kEmvaUsage},
      {"tradeoff", Tradeoff, kTradeoffUsage},
      {"preview", Preview, kPreviewUsage},
  };
  const auto is_help = [](const char* a) { return std::strcmp(a, "--help") == 0 || std::strcmp(a, "-h") == 0; };
  if (argc < 2) {
    std::fprintf(stderr, "camsim: no command given\n%s", FullUsage().c_str());
    return 1;
  }
  if (is_help(argv[1]) || std::strcmp(argv[1], "help") == 0) {
    std::fputs(FullUsage().c_str(), stdout);
    return 0;
  }
  for (const Command& c : kCommands) {
    if (std::strcmp(argv[1], c.name) != 0) continue;
    // -h or --help anywhere: the command's usage, and nothing run.
    for (int i = 2; i < argc; ++i)
      if (is_help(argv[i])) {
        std::fputs(UsageOf(c.usage).c_str(), stdout);
        return 0;
      }
    return c.run(argc, argv);
  }
  std::fprintf(stderr, "camsim: unknown command '%s'\n%s", argv[1], FullUsage().c_str());
  return 1;
}

}  // namespace

// Host tools may allocate; running out of memory (a huge --set sensor.width,
// say) is reported, not an abort. Outputs already written stay.
int main(int argc, char** argv) {
  // Ctrl-C or a kill mid-write leaves no temporary file beside an output.
  camsim::io::RemoveTemporariesOnSignal();
  try {
    return Main(argc, argv);
  } catch (const std::bad_alloc&) {
    std::fputs("camsim: out of memory (the frame or a file is larger than this machine can hold)\n", stderr);
    return 2;
  }
}
