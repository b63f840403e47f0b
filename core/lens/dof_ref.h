// Double-precision references for depth of field (dof.h), for tests and reports.
#pragma once

#include <vector>

#include "core/lens/dof.h"

namespace camsim {

// Thin-lens CoC diameter in pixels, straight from the model-notes formula
// c = f^2 |z - z_f| / (N z (z_f - f)) / pitch, with the special depths of
// dof.h (NaN and +inf: infinity; 0: max_coc; < 0: 0), then min/max_coc.
double ReferenceCocPixels(const DofConfig& config, double f_number, double z);

// Textbook Thomas solve of -b_i y_{i-1} + (1 + b_i + b_{i+1}) y_i - b_{i+1} y_{i+1} = x_i
// with b[i] (i = 1 .. n - 1) coupling i - 1 and i (b[0], b[n] ignored: insulated).
void ReferenceSolveLine(const double* x, const double* b, int n, double* y);

// Diffusion DoF of planes (row-major, width x height) given each pixel's
// squared diffusion CoC cc2 (pixels^2): rows solved whole, then columns;
// window < 0 solves whole columns, else row y's column system is the rows
// [yb - window, yb + block - 1 + window] clipped to the frame, insulated at its
// ends, with yb = y - y % block (what DofColumnStage approximates with block =
// DofColumnStage::kBlock; block 1 is a window centred on every row).
std::vector<double> ReferenceDiffusion(const std::vector<double>& plane, const std::vector<double>& cc2, int width,
                                       int height, int window, int block = 1);

// The two passes of ReferenceDiffusion on their own.
std::vector<double> ReferenceDiffusionRows(const std::vector<double>& plane, const std::vector<double>& cc2, int width,
                                           int height);
std::vector<double> ReferenceDiffusionColumns(const std::vector<double>& plane, const std::vector<double>& cc2,
                                              int width, int height, int window, int block = 1);

// Per-pixel inputs of the references from the core's inverse depth (Q12.20),
// through the double thin-lens CoC (ReferenceCocPixels) and, for the
// diffusion, the structural polynomial: squared diffusion CoC (pixels^2) and
// gather radius (pixels, capped at max_radius_px).
std::vector<double> ReferenceCc2(const DofConfig& config, double f_number, const uint32_t* inverse_depth, int width,
                                 int height, bool use_depth);
std::vector<double> ReferenceGatherRadius(const DofConfig& config, double f_number, const uint32_t* inverse_depth,
                                          int width, int height);

// Reverse-mapped gather: source q spreads uniformly over its disc of radius
// radius_q (pixels; integer offsets with dx^2 + dy^2 <= r^2), normalised.
std::vector<double> ReferenceGather(const std::vector<double>& plane, const std::vector<double>& radius, int width,
                                    int height);

}  // namespace camsim
