// CCD smear: light falling on a column while its charge is shifted out adds
// the same charge to every pixel of that column (a vertical streak through
// bright sources):
//   smear_e(x) = leak * (t_row / t_exp) * sum over y of e(x, y)
// e(x, y): the photo-charge pixel (x, y) collects in the exposure (photons *
// QE, with the CFA's colour or mono weights), t_row: the time a charge packet
// spends under each row during the transfer (sensor.smear_row_transfer_us),
// leak: the share of that light reaching the transfer register (1 for a
// frame-transfer CCD without shutter; ~1e-3 .. 1e-5 for interline CCDs).
// The sensor adds smear_e(x) to each pixel's mean charge before shot noise;
// the sum is clipped at the full well with the rest (the transfer register
// is taken to hold as much as a pixel).
//
// Streaming: every output row needs its column's total over the whole frame,
// which a row-streaming core cannot see before the last row. Choice: a frame
// statistics pre-pass over the caller's input frame (which is in memory
// anyway) before the frame is streamed: ComputeSmear below, called by the host
// once per frame, writes one value per column into caller memory, and the
// sensor reads it through FrameInput::smear_e. No frame buffer is added and
// the result is exact (not the previous frame's, not a window). Vignetting
// (when its stage runs) is applied to each pixel's radiance before the sum,
// with the stage's own Q2.14 gain (curve or mask), so the streak follows the
// vignetted column. Not seen by the sums (documented limitations): flare
// light (its own pre-pass; added after these sums would need the flare model
// per pixel over the whole frame), and blooming, which moves charge already
// collected rather than changing the light. Motion blur, depth of field and
// distortion only move light within the frame: the sums use the input frame
// as rendered, which differs only where they move light across columns.
//
// Formats: vignetted radiance: Q16.16 * Q2.14 gain, RoundShift 14 -> Q16.16;
//          column sums of Q16.16 radiance per row parity and colour, uint64
//          (<= 16384 rows * 2^34 = 2^48 with gains < 4); each times its factor (a UScale of
//          leak * t_row / t_exp * photons per radiance * QE * weight * 2^-8)
//          in a 96-bit product, rounded ties up; out Q24.8 electrons, saturated.
#pragma once

#include "core/base/span.h"
#include "core/pipeline/pipeline.h"

namespace camsim {

// True when the configuration asks for smear (and so for FrameInput::smear_e).
bool SmearEnabled(const PipelineConfig& config);
// Entries ComputeSmear uses: the charges, kMaxChannels * width (channel c at
// [c * width + x]; a 1-channel sensor (mosaic or mono) uses channel 0), then
// its working space: each column's dx2 and sums (13 width + 1 entries, 52
// bytes a column).
int SmearEntries(const PipelineConfig& config);
// The smear charge per column for one frame (Q24.8 electrons). `out` must have
// SmearEntries() entries. The config must have passed Pipeline::Configure.
void ComputeSmear(const PipelineConfig& config, const FrameInput& input, Span<uint32_t> out);

}  // namespace camsim
