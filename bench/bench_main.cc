// The benchmark binary's main: Google Benchmark's console output, then a table
// of camsim/peer time ratios (bench_common.h) and the demo pipeline against
// the seed paper's 0.9 frames/s at 640x480 (Core 2 Duo P7350, 2 GHz; §6).
#include <benchmark/benchmark.h>

#include <cstdio>
#include <map>
#include <string>

#include "bench/bench_common.h"

namespace {

constexpr double kPaperFps = 0.9;  // the seed paper's simulator, 640x480

// Keeps every run's real time per iteration, in milliseconds.
class RecordingReporter : public benchmark::ConsoleReporter {
 public:
  void ReportRuns(const std::vector<Run>& runs) override {
    for (const Run& run : runs) {
      if (run.error_occurred) continue;
      // One iteration run each, or with --benchmark_repetitions the median.
      const bool median = run.run_type == Run::RT_Aggregate && run.aggregate_name == "median";
      if (run.run_type != Run::RT_Iteration && !median) continue;
      std::string name = run.run_name.str();
      for (const std::string suffix : {"/real_time", "/process_time"})
        if (name.size() > suffix.size() && name.compare(name.size() - suffix.size(), suffix.size(), suffix) == 0)
          name.resize(name.size() - suffix.size());
      ms[name] = run.GetAdjustedRealTime() * 1e3 / benchmark::GetTimeUnitMultiplier(run.time_unit);
    }
    ConsoleReporter::ReportRuns(runs);
  }
  std::map<std::string, double> ms;
};

}  // namespace

int main(int argc, char** argv) {
  benchmark::Initialize(&argc, argv);
  if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1;
  RecordingReporter reporter;
  benchmark::RunSpecifiedBenchmarks(&reporter);
  benchmark::Shutdown();

  bool header = false;
  for (const camsim::bench::PeerPair& p : camsim::bench::PeerPairs()) {
    const auto a = reporter.ms.find(p.camsim);
    auto b = reporter.ms.find(p.peer);
    if (p.peer2 != nullptr) {  // the faster of the peer's two variants that ran
      const auto b2 = reporter.ms.find(p.peer2);
      if (b2 != reporter.ms.end() && (b == reporter.ms.end() || b2->second < b->second)) b = b2;
    }
    const bool have_a = a != reporter.ms.end(), have_b = b != reporter.ms.end();
    if (!have_a && !have_b) continue;
    if (!header) std::printf("\n%-44s %10s %10s %8s\n", "camsim vs peer (1 thread)", "camsim ms", "peer ms", "ratio");
    header = true;
    if (!have_a || !have_b) {  // the filter ran one side only
      std::printf("%-44s no ratio: %s did not run\n", p.what, have_a ? p.peer : p.camsim);
      continue;
    }
    std::printf("%-44s %10.2f %10.2f %8.2f  ", p.what, a->second, b->second, a->second / b->second);
    if (p.peer2 != nullptr) std::printf("[peer %s] ", b->first.c_str());
    std::printf("%s\n", p.error_note);
  }
  const auto demo = reporter.ms.find("BM_Pipeline/640/480/1");
  if (demo != reporter.ms.end())
    std::printf("\ndemo pipeline 640x480, 1 thread: %.1f frames/s = %.0f x the seed paper's %.1f frames/s\n"
                "  (the demo camera: no distortion, no depth of field; this CPU against the paper's)\n",
                1e3 / demo->second, 1e3 / demo->second / kPaperFps, kPaperFps);
  return 0;
}
