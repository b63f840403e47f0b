// The listed-defects file of sensor.defects_file: one defect pixel a line,
//   x,y,kind[,value]
// kind hot | dead | stuck; value (optional): hot: dark current e-/s at the
// reference temperature (default sensor.hot_pixel_dark_e_per_s), stuck: the
// DN the pixel is stuck at (default 2^adc_bits - 1), dead: none. Blank
// lines and everything after '#' are ignored; spaces around fields too.
// Errors name FILE:LINE:COLUMN and the problem (unreadable, malformed
// number, unknown kind, value where none belongs or out of range, pixel
// outside the frame, duplicate pixel with the line of the first).
#pragma once

#include <string>
#include <vector>

#include "core/sensor/emva.h"

namespace camsim::host {

// Reads `path` for a width x height sensor with adc_bits; `out` is sorted by (y, x).
bool LoadDefectsFile(const std::string& path, int width, int height, int adc_bits, std::vector<DefectPixel>* out,
                     std::string* error);

}  // namespace camsim::host
