// `camsim run`: a sequence of scene frames through the pipeline to files.
#pragma once

#include <string>
#include <vector>

#include "host_tools/config.h"

namespace camsim::host {

struct RunOptions {
  std::string preset;                  // --preset NAME, applied before the config file
  std::string config_path;             // empty: defaults
  std::vector<std::string> inputs;     // files, directories or printf patterns
  std::string depth_path;              // separate depth file (single frame)
  std::string out_dir;
  std::vector<std::string> overrides;  // --set section.key=value
  std::string calibration_path;        // --calibration YAML: distortion.calibration, named as such in errors
  std::string stages;                  // --stages a,b,c (comma-separated)
  bool stages_given = false;           // --stages was given (an empty list is an error, not "all")
  std::string report_path;             // --report FILE (JSON)
  int threads = 1;
  int strip_rows = 0;                  // 0: StripRows' default (one strip per thread)
  uint32_t first_frame = 0;            // frame index of the first input (keys noise)
  int savings_rounds = 0;              // --measure-savings N: each frame N more times with skipping on and off
  bool dump_stages = false;
  bool quiet = false;
  std::string option_error;            // a bad command line: RunCommand reports it (to --report too)
};

// Returns the process exit code (0 ok, 1 input/config error, 2 output error).
int RunCommand(const RunOptions& options);

}  // namespace camsim::host
