// `camsim tradeoff`: error against run time for every precision knob of every
// stage that runs. For each knob value (the others as configured) the pipeline
// runs on one thread and its output is compared, stage by stage and end to
// end, with the double-precision reference (core/pipeline/pipeline_ref.h) on
// the same input, with sensor noise, DSNU and PRNU off so that the difference
// is the arithmetic's alone. Writes tradeoff.csv, tradeoff.md and tradeoff.png.
#pragma once

#include <string>
#include <vector>

namespace camsim::host {

struct TradeoffOptions {
  std::string config_path;             // empty: defaults
  std::string input;                   // one EXR
  std::string out_dir;
  std::vector<std::string> overrides;  // --set section.key=value
  int frames = 15;                     // timed rounds: one frame of every setting each (the fastest counts)
};

// A knob: a configuration key whose values trade accuracy for time.
struct PrecisionKnob {
  const char* stage;  // the stage it belongs to (swept only when that stage runs)
  const char* key;    // section.key
  std::vector<std::string> values;
  const char* what;
  // The knob picks another model (the remap filter, the demosaic method), not
  // a precision of one: its end-to-end error is also given against its own
  // model's reference, and each stage's against its own.
  bool model = false;
};
const std::vector<PrecisionKnob>& PrecisionKnobs();

// Returns the process exit code (0 ok, 1 input/config error, 2 output error).
int TradeoffCommand(const TradeoffOptions& options);

}  // namespace camsim::host
