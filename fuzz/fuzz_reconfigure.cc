// fuzz_reconfigure: a pipeline reconfigured from another (Pipeline::Configure
// and Init with `previous`, which copy the tables whose inputs did not
// change) gives exactly the bytes of one built from scratch, for every
// running stage, and refuses exactly what the one from scratch refuses.
//
// Blob: byte k; (k & 7) changes applied to both configurations, then
// ((k >> 3) & 7) changes applied to the second only (DecodeChange: a
// Params() number or a table-shaping setting), then a fuzz_core blob
// (fuzz_common.h) for the first configuration and the frame.
#include <cstddef>
#include <cstdint>
#include <cstring>

#include "fuzz/fuzz_common.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using namespace camsim;
  using namespace camsim::fuzz;
  ByteReader r(data, size);
  const uint8_t k = r.Byte();
  // The changes are read once onto a throwaway configuration to find where
  // each part starts, then again onto the decoded one.
  PipelineConfig skipped;
  for (int i = 0; i < (k & 7); ++i) DecodeChange(r, &skipped);
  const size_t second_from = size - r.remaining();
  for (int i = 0; i < ((k >> 3) & 7); ++i) DecodeChange(r, &skipped);
  const size_t core_from = size - r.remaining();
  CoreCase first = DecodeCoreCase(data + core_from, size - core_from);
  // Now on the decoded case: the shared changes, then the second's.
  ByteReader shared(data + 1, second_from > 0 ? second_from - 1 : 0), own(data + second_from, core_from - second_from);
  for (int i = 0; i < (k & 7); ++i) DecodeChange(shared, &first.config);
  PipelineConfig next = first.config;
  for (int i = 0; i < ((k >> 3) & 7); ++i) DecodeChange(own, &next);

  Pipeline previous;
  if (!previous.Configure(first.config, 2, first.has_mask).ok()) return 0;
  std::vector<uint8_t> previous_ws(previous.WorkspaceBytes(), 0xA5);
  const Status pi = previous.Init(Span<uint8_t>{previous_ws.data(), previous_ws.size()});
  FUZZ_CHECK(pi.ok(), "Init failed after Configure succeeded: %s", pi.message());

  Pipeline fresh, reused;
  const Status fc = fresh.Configure(next, 2, first.has_mask);
  const Status rc = reused.Configure(next, 2, first.has_mask, &previous);
  FUZZ_CHECK(fc.ok() == rc.ok() && std::strcmp(fc.message(), rc.message()) == 0,
             "configured from scratch: '%s', from the previous pipeline: '%s'", fc.message(), rc.message());
  if (!fc.ok()) return 0;
  FUZZ_CHECK(fresh.WorkspaceBytes() == reused.WorkspaceBytes(), "workspace %zu vs %zu", fresh.WorkspaceBytes(),
             reused.WorkspaceBytes());
  // Different garbage in each workspace: a table the copy missed shows.
  std::vector<uint8_t> fresh_ws(fresh.WorkspaceBytes(), 0xA5), reused_ws(reused.WorkspaceBytes(), 0x5A);
  const Status fi = fresh.Init(Span<uint8_t>{fresh_ws.data(), fresh_ws.size()});
  const Status ri = reused.Init(Span<uint8_t>{reused_ws.data(), reused_ws.size()}, &previous);
  FUZZ_CHECK(fi.ok() && ri.ok(), "Init: '%s' and '%s'", fi.message(), ri.message());

  // The first configuration's frame (no change alters the frame size).
  const FrameInput plain = first.View();
  const Prepassed pf(fresh, plain), pr(reused, plain);
  FUZZ_CHECK(fresh.CheckInput(pf.input).ok() && reused.CheckInput(pr.input).ok(), "CheckInput");
  TappedRun a(fresh, 0xA5A5A5A5u), b(reused, 0x5A5A5A5Au);
  fresh.ProcessFrame(pf.input, 3, fresh.height(), a.taps.data(), static_cast<int>(a.taps.size()), nullptr, nullptr);
  reused.ProcessFrame(pr.input, 3, reused.height(), b.taps.data(), static_cast<int>(b.taps.size()), nullptr,
                      nullptr);
  for (size_t i = 0; i < a.out.size(); ++i)
    for (size_t j = 0; j < a.out[i].size(); ++j)
      FUZZ_CHECK(a.out[i][j] == b.out[i][j], "stage %zu (%s) sample %zu: %u from scratch, %u reconfigured", i,
                 fresh.running_stage(static_cast<int>(i)).name(), j, a.out[i][j], b.out[i][j]);
  return 0;
}
