// Image and text writers for host tools. Host-side only.
//
// Every writer is atomic: it writes a temporary file of its own beside
// `path` (`path + ".tmp." + pid + "." + n`, created exclusively, so never an
// existing file: an input cannot be overwritten through it) and rename()s it
// onto `path`, so `path` is never left half-written. On failure it returns
// false, sets *error (naming `path` and what went wrong), removes the
// temporary file and leaves any earlier `path` untouched. No exception
// escapes.
//
// Images: `data` points at the top-left sample; `stride_samples` is the
// distance between row starts in samples (>= width * channels); width and
// height must be 1..1000000.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

namespace camsim::io {

// Binary PGM (P5, channels = 1) or PPM (P6, channels = 3, interleaved RGB) with
// the given maxval (1..65535; use 2^bits - 1). Per the Netpbm spec, samples are
// big-endian 16-bit when maxval >= 256 and single bytes when maxval < 256. A
// sample above maxval is an error. Header: "P5\n<width> <height>\n<maxval>\n"
// (P6 for RGB).
bool WritePnm16(const std::string& path, const uint16_t* data, int width, int height, int channels,
                ptrdiff_t stride_samples, int maxval, std::string* error);

// PNG, gray (channels = 1) or RGB (channels = 3), bit_depth 8 (data is
// uint8_t) or 16 (data is native-endian uint16_t). No gamma/colour chunks.
bool WritePng(const std::string& path, const void* data, int width, int height, int channels,
              int bit_depth, ptrdiff_t stride_samples, std::string* error);

// Headerless little-endian 16-bit samples, rows packed (width x channels
// samples each, channels interleaved as in `data`).
bool WriteRaw16(const std::string& path, const uint16_t* data, int width, int height, int channels,
                ptrdiff_t stride_samples, std::string* error);

// The text, byte for byte (JSON sidecars, reports).
bool WriteTextFile(const std::string& path, const std::string& text, std::string* error);

struct ExrChannel {
  std::string name;
  const float* data;
  ptrdiff_t stride_samples;  // floats between row starts, >= width
};

// Single-part scanline OpenEXR, FLOAT channels, ZIP compression, data window =
// display window = (0,0)-(width-1,height-1). Channel names must be unique and
// non-empty.
bool WriteExrFloat(const std::string& path, int width, int height,
                   const std::vector<ExrChannel>& channels, std::string* error);

}  // namespace camsim::io
