// Readers for auxiliary images (measured vignetting masks). Host-side only.
// On failure they return false and set *error (naming the file); *out is left
// unchanged. No exception escapes. Images larger than 16384 x 16384 are refused.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "host_tools/io/float_plane.h"

namespace camsim::io {

// PNG of any bit depth and colour type: gray as is, colour (palette expanded)
// as the mean of R, G, B; alpha is ignored. Values are normalised by the
// largest sample value (255 or 65535; 1/2/4-bit gray is scaled up to 8 bits
// first), so they lie in [0, 1]. Gamma and colour chunks are ignored.
bool ReadPng(const std::string& path, FloatPlane* gray_out, std::string* error);

// A gray PNG's raw samples (8-bit expanded to uint16_t, 1/2/4-bit scaled up
// to 8 bits first), for measurement data whose values are counts, not levels.
// A colour PNG is an error.
bool ReadPngGrayRaw(const std::string& path, std::vector<uint16_t>* out, int* width, int* height, int* bit_depth,
                    std::string* error);

// A mask image chosen by extension (case-insensitive): ".png" via ReadPng;
// ".exr": channel Y, else R, else the first channel (by name) of the first
// part, values as stored (no sanitising). For EXR the output is the display
// window; pixels outside the data window are 0.
bool ReadMaskImage(const std::string& path, FloatPlane* out, std::string* error);

}  // namespace camsim::io
