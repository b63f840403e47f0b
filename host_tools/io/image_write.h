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
// A run killed while a temporary file exists (RemoveTemporariesOnSignal)
// removes it before it dies.
//
// Only a regular file is replaced: a `path` that is a directory, FIFO,
// socket or device is refused (WritableTarget). A symbolic link is followed
// (to any depth): the file it points to is what is written, atomically, with
// the temporary file beside it in the target's directory; the link stays.
//
// Images: `data` points at the top-left sample; `stride_samples` is the
// distance between row starts in samples (>= width * channels); width and
// height must be 1..1000000.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <utility>
#include <vector>

namespace camsim::io {

// For SIGHUP, SIGINT, SIGQUIT, SIGTERM and SIGXFSZ (each unless ignored, as
// under nohup, or already handled): a handler that removes every file
// registered with RemovedOnSignal (the writers' temporary files among them),
// then lets the signal kill the process as it would have. Call it early in
// main.
void RemoveTemporariesOnSignal();

// While alive, `path` is removed by the handler of RemoveTemporariesOnSignal.
// The path is registered in a fixed table (64 entries, shared by all
// threads, each of at most PATH_MAX bytes); beyond that it is not, and a
// signal leaves it. Destruction unregisters and does not remove the file.
class RemovedOnSignal {
 public:
  explicit RemovedOnSignal(const std::string& path);
  ~RemovedOnSignal();
  RemovedOnSignal(const RemovedOnSignal&) = delete;
  RemovedOnSignal& operator=(const RemovedOnSignal&) = delete;

 private:
  int slot_;  // -1: not registered
};

// `path` with its symbolic links followed (the last component, repeatedly;
// a relative link target is taken from the link's directory): the file a
// writer replaces. A dangling link gives its missing target. Empty, with
// *error, on a link loop or an unreadable link.
std::string FollowSymlinks(const std::string& path, std::string* error);

// Whether a writer may write `path`: true, with *target = FollowSymlinks(path),
// when nothing or a regular file is there; false (*error naming `path`, its
// link's target and what is there) for a directory, FIFO, socket or device.
bool WritableTarget(const std::string& path, std::string* target, std::string* error);

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

// A channel of an EXR file: FLOAT samples (32-bit IEEE, what viewers show)
// or UINT samples (32-bit unsigned integers, exact), by the pointer given.
enum class ExrSampleType : uint8_t { kFloat, kUint };
struct ExrChannel {
  ExrChannel(std::string channel_name, const float* samples, ptrdiff_t stride)
      : name(std::move(channel_name)), data(samples), stride_samples(stride), type(ExrSampleType::kFloat) {}
  ExrChannel(std::string channel_name, const uint32_t* samples, ptrdiff_t stride)
      : name(std::move(channel_name)), data(samples), stride_samples(stride), type(ExrSampleType::kUint) {}
  std::string name;
  const void* data;          // float (kFloat) or uint32_t (kUint) samples
  ptrdiff_t stride_samples;  // samples between row starts, >= width
  ExrSampleType type;
};

// A header attribute: OpenEXR "string" (text) or "double" (number).
struct ExrAttribute {
  ExrAttribute(std::string attribute_name, std::string value)
      : name(std::move(attribute_name)), text(std::move(value)), is_text(true) {}
  ExrAttribute(std::string attribute_name, const char* value) : ExrAttribute(std::move(attribute_name), std::string(value)) {}
  ExrAttribute(std::string attribute_name, double value)
      : name(std::move(attribute_name)), number(value), is_text(false) {}
  std::string name;
  std::string text;
  double number = 0;
  bool is_text;
};

// Single-part scanline OpenEXR, ZIP compression, data window = display
// window = (0,0)-(width-1,height-1), each channel of its own sample type,
// and the attributes in the header besides OpenEXR's required ones. Channel
// names must be unique and non-empty; attribute names unique, non-empty and
// none that OpenEXR's header sets itself (channels, compression,
// dataWindow, ...) or reads as the file's structure (name, type, version,
// chunkCount, tiles).
bool WriteExr(const std::string& path, int width, int height, const std::vector<ExrChannel>& channels,
              const std::vector<ExrAttribute>& attributes, std::string* error);

// WriteExr without attributes (its callers write FLOAT channels).
inline bool WriteExrFloat(const std::string& path, int width, int height, const std::vector<ExrChannel>& channels,
                          std::string* error) {
  return WriteExr(path, width, height, channels, {}, error);
}

}  // namespace camsim::io
