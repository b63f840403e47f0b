// Internal helpers shared by the OpenEXR readers (exr_scene.cc, image_read.cc).
// Not part of the public API.
#pragma once

#include <cstdint>
#include <exception>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

#include <OpenEXR/ImfHeader.h>
#include <OpenEXR/ImfMultiPartInputFile.h>

#include "host_tools/io/exr_scene.h"

namespace camsim::io::detail {

inline constexpr int kMaxDisplayDim = 16384;
// At most 2^25 pixels (8K UHD, 7680 x 4320, fits): a header of a few hundred
// bytes must not make the loader allocate and fill gigabytes (every plane of
// the display window is float; colour, depth and motion are 6 planes).
inline constexpr int64_t kMaxDisplayPixels = int64_t{1} << 25;
inline constexpr int kMaxDataWidth = 65536;

// Opens `path` as a (single- or multi-part) OpenEXR file; nullptr and *error
// on failure. Never throws.
std::unique_ptr<Imf::MultiPartInputFile> OpenExr(const std::string& path, std::string* error);

// Thrown by these helpers for files that are valid OpenEXR but not usable.
struct UnsupportedExr : std::runtime_error {
  using std::runtime_error::runtime_error;
};

// True if part `part` is a flat (scanline or tiled, not deep) image.
bool IsFlatPart(const Imf::MultiPartInputFile& file, int part);

// True if part `part` is a flat image holding channel `name`.
bool PartHasChannel(const Imf::MultiPartInputFile& file, int part, const std::string& name);

// Channel names of all flat parts, comma separated, at most `max_names` (then "...").
std::string ListChannels(const Imf::MultiPartInputFile& file, size_t max_names = 20);
// Bytes from a file shown printable: others as \xNN (no terminal control
// sequence reaches the user).
std::string Printable(const std::string& bytes);

// The display window size; false if empty or larger than kMaxDisplayDim.
bool DisplaySize(const Imf::Header& header, int* width, int* height);

// How samples read from the file are cleaned (see exr_scene.h).
enum class Sanitize { kNone, kRadiance, kDepth, kMotion };

struct ChannelRead {
  std::string name;           // channel in the part
  FloatPlane* out;            // resized to the display window
  Sanitize mode;              // kDepth fills with +inf outside the data window, others 0
  InputSanitizeStats* stats;  // counts for kRadiance / kDepth / kMotion; null for kNone
};

// Reads the channels (all in part `part` of `file`, opened from `path`) as
// float into display-window-sized planes, as Imf would read them. Every
// chunk to be read is decompressed once, by OpenEXRCore, which checks its
// size (Imf 3.1 does not), and its samples copied from there; DWAA/DWAB
// parts (Core 3.1 cannot decode them) and parts with a subsampled channel
// are checked so and then read by Imf.
// Throws on any problem (OpenEXR's Iex exceptions, UnsupportedExr for
// unsupported windows or subsampling, std::runtime_error naming a corrupt
// chunk); the caller catches.
void ReadChannels(const std::string& path, Imf::MultiPartInputFile& file, int part,
                  const std::vector<ChannelRead>& reads);

// Formats the error for an exception thrown while reading `path`:
// "'path': ..." for UnsupportedExr, "'path': out of memory ..." for bad_alloc
// (a corrupt header's sizes, or a real frame too large), else (OpenEXR's Iex
// exceptions, ...) "'path' is not a readable OpenEXR file: ...".
std::string ExrExceptionMessage(const std::string& path, const std::exception& e);

// Runs `fn` (returns bool, may throw) and turns exceptions into false + *error.
template <typename Fn>
bool CatchExr(const std::string& path, std::string* error, Fn&& fn) {
  try {
    return fn();
  } catch (const std::exception& e) {
    *error = ExrExceptionMessage(path, e);
  } catch (...) {
    *error = "'" + path + "' is not a readable OpenEXR file: unknown error";
  }
  return false;
}

}  // namespace camsim::io::detail
