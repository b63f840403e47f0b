#include "host_tools/io/exr_common.h"

#include <algorithm>
#include <atomic>
#include <bit>
#include <cctype>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <limits>
#include <mutex>
#include <new>
#include <stdexcept>
#include <string>
#include <system_error>
#include <thread>
#include <vector>

#include <Imath/half.h>
#include <OpenEXR/ImfChannelList.h>
#include <OpenEXR/ImfFrameBuffer.h>
#include <OpenEXR/ImfHeader.h>
#include <OpenEXR/ImfInputPart.h>
#include <OpenEXR/ImfPartType.h>
#include <OpenEXR/ImfThreading.h>
#include <OpenEXR/openexr.h>
#include <zlib.h>

namespace camsim::io::detail {

namespace {

// An OpenEXRCore read context on `path` (headers checked strictly), closed
// when it goes. Core's messages are kept: they say more than its error codes.
class CoreFile {
 public:
  explicit CoreFile(const std::string& path) {
    exr_context_initializer_t init = EXR_DEFAULT_CONTEXT_INITIALIZER;
    init.flags = EXR_CONTEXT_FLAG_STRICT_HEADER;
    init.user_data = &said_;
    init.error_handler_fn = [](exr_const_context_t c, exr_result_t, const char* message) {
      void* said = nullptr;
      if (exr_get_user_data(c, &said) == EXR_ERR_SUCCESS && said != nullptr) {
        Said& s = *static_cast<Said*>(said);
        std::lock_guard<std::mutex> lock(s.mutex);  // decoders on several threads share the context
        s.messages.push_back(message);
      }
    };
    opened_ = exr_start_read(&ctx_, path.c_str(), &init);
  }
  ~CoreFile() {
    if (ctx_ != nullptr) exr_finish(&ctx_);
  }
  CoreFile(const CoreFile&) = delete;
  CoreFile& operator=(const CoreFile&) = delete;

  exr_result_t opened() const { return opened_; }
  exr_const_context_t context() const { return ctx_; }
  // Core's text for `r`, with the first message it gave (if any) in brackets.
  std::string Reason(exr_result_t r) const {
    std::lock_guard<std::mutex> lock(said_.mutex);
    return std::string(exr_get_default_error_message(r)) +
           (said_.messages.empty() ? "" : " (" + Printable(said_.messages.front()) + ")");
  }
  // Forgets what Core said so far (so that the next Reason is about what follows).
  void Forget() {
    std::lock_guard<std::mutex> lock(said_.mutex);
    said_.messages.clear();
  }

 private:
  struct Said {
    mutable std::mutex mutex;
    std::vector<std::string> messages;
  };
  exr_context_t ctx_ = nullptr;
  exr_result_t opened_ = EXR_ERR_UNKNOWN;
  Said said_;
};

}  // namespace

std::unique_ptr<Imf::MultiPartInputFile> OpenExr(const std::string& path, std::string* error) {
  std::error_code ec;
  const std::filesystem::file_status st = std::filesystem::status(path, ec);
  if (st.type() == std::filesystem::file_type::not_found) {
    *error = "cannot open '" + path + "': no such file";
    return nullptr;
  }
  if (ec) {
    *error = "cannot open '" + path + "': " + ec.message();
    return nullptr;
  }
  if (std::filesystem::is_directory(st)) {
    *error = "'" + path + "' is a directory, not an OpenEXR file";
    return nullptr;
  }
  // OpenEXRCore checks every header against the file (attribute sizes,
  // windows, duplicates) without allocating what a corrupt header claims;
  // Imf 3.1 allocates first: a 909-byte file with a string attribute "of
  // 1.9 GB" made it allocate 1.9 GB. Strict: without the flag, Core reports
  // such a header of a later part and still returns success.
  // Core's own reason is kept for the message (e.g. a multi-part file with a
  // deep part needs a `version` attribute on every part: Core 3.1 refuses it
  // otherwise, with or without the flag).
  {
    CoreFile core(path);
    if (core.opened() != EXR_ERR_SUCCESS) {
      *error = "'" + path + "' is not a readable OpenEXR file: " + core.Reason(core.opened());
      return nullptr;
    }
  }
  std::unique_ptr<Imf::MultiPartInputFile> file;
  CatchExr(path, error, [&] {
    file = std::make_unique<Imf::MultiPartInputFile>(path.c_str());
    return true;
  });
  return file;
}

bool IsFlatPart(const Imf::MultiPartInputFile& file, int part) {
  const Imf::Header& h = file.header(part);
  return !h.hasType() || (h.type() != Imf::DEEPSCANLINE && h.type() != Imf::DEEPTILE);
}

bool PartHasChannel(const Imf::MultiPartInputFile& file, int part, const std::string& name) {
  return IsFlatPart(file, part) && file.header(part).channels().findChannel(name) != nullptr;
}

std::string Printable(const std::string& bytes) {
  std::string out;
  for (const char c : bytes) {
    const unsigned char b = static_cast<unsigned char>(c);
    char hex[5];
    std::snprintf(hex, sizeof hex, "\\x%02x", b);
    out += b >= 0x20 && b < 0x7f ? std::string(1, c) : std::string(hex);
  }
  return out;
}

std::string ListChannels(const Imf::MultiPartInputFile& file, size_t max_names) {
  std::string list;
  size_t n = 0;
  for (int p = 0; p < file.parts(); ++p) {
    if (!IsFlatPart(file, p)) continue;
    const Imf::ChannelList& channels = file.header(p).channels();
    for (auto it = channels.begin(); it != channels.end(); ++it, ++n) {
      if (n == max_names) return list + ", ...";
      // A name is any bytes: shown printable, so that no terminal control sequence reaches the user.
      list += (n ? ", " : "") + Printable(it.name());
    }
  }
  return n ? list : "(none)";
}

std::string ExrExceptionMessage(const std::string& path, const std::exception& e) {
  if (dynamic_cast<const UnsupportedExr*>(&e) != nullptr) return "'" + path + "': " + e.what();
  if (dynamic_cast<const std::bad_alloc*>(&e) != nullptr)
    return "'" + path + "': out of memory while reading it (a corrupt header, or a frame too large for this machine)";
  return "'" + path + "' is not a readable OpenEXR file: " + e.what();
}

namespace {

constexpr float kLargestHalf = 65504.0f;
constexpr float kInf = std::numeric_limits<float>::infinity();

// Cleans *v per `mode` (exr_scene.h's rules), counting it in *stats; true if
// it was replaced.
bool Clean(float* v, Sanitize mode, InputSanitizeStats* stats) {
  switch (mode) {
    case Sanitize::kNone:
      return false;
    case Sanitize::kRadiance:
      if (std::isnan(*v)) {
        ++stats->nan;
        *v = 0.0f;
      } else if (*v < 0.0f) {
        ++(std::isinf(*v) ? stats->neg_inf : stats->negative);
        *v = 0.0f;
      } else if (std::isinf(*v)) {
        ++stats->pos_inf;
        *v = kLargestHalf;
      } else {
        return false;
      }
      return true;
    case Sanitize::kDepth:
      if (std::isnan(*v)) {
        ++stats->nan;
        *v = kInf;
        return true;
      }
      if (std::isinf(*v)) {
        ++(*v > 0.0f ? stats->pos_inf : stats->neg_inf);
      } else if (*v < 0.0f) {
        ++stats->negative;
      }
      return false;
    case Sanitize::kMotion:
      if (std::isfinite(*v)) return false;
      ++(std::isnan(*v) ? stats->nan : (*v > 0.0f ? stats->pos_inf : stats->neg_inf));
      *v = 0.0f;
      return true;
  }
  return false;
}

// Keeps (channel, x, y) as the first sample replaced if it comes before the
// one kept: a higher row, or the same row further left.
void NoteReplaced(InputSanitizeStats* stats, const std::string& channel, int x, int y) {
  if (!stats->first_channel.empty() && (y > stats->first_y || (y == stats->first_y && x >= stats->first_x))) return;
  stats->first_channel = channel;
  stats->first_x = x;
  stats->first_y = y;
}

std::string BoxText(const Imath::Box2i& b) {
  return "(" + std::to_string(b.min.x) + "," + std::to_string(b.min.y) + ")-(" +
         std::to_string(b.max.x) + "," + std::to_string(b.max.y) + ")";
}

// ---- DWAA/DWAB chunks ----------------------------------------------------
// Core 3.1 cannot decode DWA, and Imf 3.1's DWA decoder fills a chunk's rows
// from sections whose sizes it does not check against the rows: a zlib
// section (the channels DWA stores losslessly, e.g. float depth) that
// inflates short, or a DC count smaller than the blocks, gave rows of
// uninitialised memory (valgrind; or the rows of the chunk decoded before)
// and the load succeeded. Imf does catch the other corruptions tried (sizes
// beyond the chunk, bytes flipped in the zlib and DC sections, bad rules)
// but not all bytes flipped in the Huffman-coded AC values: those can decode
// to wrong pixels, which nothing in the file can tell. So each DWA chunk's header is
// checked here against what its rows need, and its zlib section inflated.
// Layout, as Imf 3.1 writes and reads it: eleven little-endian uint64 sizes,
// then (version 2) the channel rules, then the zlib, AC, DC and RLE sections.

enum DwaField { kDwaVersion, kDwaZlibRaw, kDwaZlibSize, kDwaAcSize, kDwaDcSize, kDwaRleSize, kDwaRleRuns,
                kDwaRleRaw, kDwaAcCount, kDwaDcCount, kDwaAcCompression, kDwaFields };
enum DwaScheme { kDwaZlib, kDwaLossy, kDwaRle };  // Imf's UNKNOWN, LOSSY_DCT, RLE

struct DwaChannel {
  std::string suffix;  // the name after its last dot, as DWA's rules see it
  int type;            // 0 uint, 1 half, 2 float (Imf's and Core's numbering)
  int x_sampling, y_sampling;
};

struct DwaRule {
  std::string suffix;
  int scheme;
  int type;
  bool any_case;  // the channel's suffix is compared lower-cased
};

// The rules of DWA data before version 2 (Imf's initializeLegacyChannelRules;
// Imf 3.1 writes version 2, so no test file has these).
std::vector<DwaRule> LegacyDwaRules() {
  std::vector<DwaRule> rules;
  for (const char* s : {"r", "red", "g", "grn", "green", "b", "blu", "blue", "y", "by", "ry"})
    for (const int type : {1, 2}) rules.push_back({s, kDwaLossy, type, true});
  for (const int type : {0, 1, 2}) rules.push_back({"a", kDwaRle, type, true});
  return rules;
}

// Samples of a channel sampled every `s` in a..b (Imf's numSamples).
int64_t DwaSamples(int s, int64_t a, int64_t b) {
  auto floor_div = [](int64_t v, int64_t d) { return v / d - (v % d != 0 && v < 0 ? 1 : 0); };
  return std::max<int64_t>(0, floor_div(b, s) - floor_div(a - 1, s));
}

// Why the DWA chunk `data` (`size` bytes) holding pixels x0..x1, y0..y1
// cannot fill them all; "" if it can. Only what Imf 3.1 does not check
// itself (the sections against the rows) needs to be exact here.
std::string DwaChunkProblem(const std::vector<DwaChannel>& channels, const uint8_t* data, size_t size, int64_t x0,
                            int64_t y0, int64_t x1, int64_t y1) {
  constexpr size_t kHeader = kDwaFields * 8;
  if (size < kHeader) return "DWA data of " + std::to_string(size) + " bytes, shorter than its header";
  uint64_t f[kDwaFields];
  for (size_t i = 0; i < kDwaFields; ++i) {
    f[i] = 0;
    for (int b = 7; b >= 0; --b) f[i] = (f[i] << 8) | data[8 * i + static_cast<size_t>(b)];
  }
  if (f[kDwaVersion] > 2) return "DWA version " + std::to_string(f[kDwaVersion]) + ", not 0, 1 or 2";

  // Version 2 stores its rules: a uint16 size (itself included), then per rule
  // a NUL-terminated suffix, a byte of flags and a byte of pixel type.
  size_t pos = kHeader;
  std::vector<DwaRule> rules;
  if (f[kDwaVersion] < 2) {
    rules = LegacyDwaRules();
  } else {
    const size_t rules_size = size >= pos + 2 ? data[pos] | (size_t{data[pos + 1]} << 8) : 0;
    if (rules_size < 2 || rules_size > size - pos) return "DWA channel rules cut short";
    const size_t end = pos + rules_size;
    for (pos += 2; pos < end;) {
      const void* nul = std::memchr(data + pos, 0, end - pos);
      const size_t len = nul == nullptr ? end - pos : static_cast<size_t>(static_cast<const uint8_t*>(nul) - (data + pos));
      if (nul == nullptr || len > 254 || end - pos < len + 3) return "DWA channel rules corrupt";
      const signed char flags = static_cast<signed char>(data[pos + len + 1]);
      const signed char type = static_cast<signed char>(data[pos + len + 2]);
      const int csc = (flags >> 4) - 1, scheme = (flags >> 2) & 3;
      if (csc < -1 || csc > 2 || scheme > kDwaRle || type < 0 || type > 2) return "DWA channel rules corrupt";
      rules.push_back({std::string(reinterpret_cast<const char*>(data + pos), len), scheme, type, (flags & 1) != 0});
      pos += len + 3;
    }
  }

  // What the rows need of each section: the last rule matching a channel
  // decides its scheme, zlib if none does.
  uint64_t zlib_bytes = 0, rle_bytes = 0, dc_count = 0;
  for (const DwaChannel& c : channels) {
    int scheme = kDwaZlib;
    std::string lower = c.suffix;
    for (char& ch : lower) ch = static_cast<char>(std::tolower(static_cast<unsigned char>(ch)));
    for (const DwaRule& r : rules) {
      if (r.type == c.type && (r.any_case ? lower : c.suffix) == r.suffix) scheme = r.scheme;
    }
    const uint64_t w = static_cast<uint64_t>(DwaSamples(c.x_sampling, x0, x1));
    const uint64_t h = static_cast<uint64_t>(DwaSamples(c.y_sampling, y0, y1));
    const uint64_t bytes = w * h * (c.type == 1 ? 2 : 4);
    if (scheme == kDwaLossy) {
      // Imf decodes a lossy uint channel to 2 of its 4 bytes a sample.
      if (c.type == 0) return "DWA rules make uint channel '" + Printable(c.suffix) + "' lossy";
      dc_count += ((w + 7) / 8) * ((h + 7) / 8);
    } else {
      (scheme == kDwaRle ? rle_bytes : zlib_bytes) += bytes;
    }
  }
  auto differs = [](const char* what, uint64_t says, uint64_t needs) {
    return "DWA header says " + std::to_string(says) + " " + what + " where its rows need " + std::to_string(needs);
  };
  if (f[kDwaZlibRaw] != zlib_bytes) return differs("bytes of zlib-compressed channels", f[kDwaZlibRaw], zlib_bytes);
  if (f[kDwaDcCount] != dc_count) return differs("DC values", f[kDwaDcCount], dc_count);
  if (f[kDwaRleRaw] != rle_bytes) return differs("bytes of RLE channels", f[kDwaRleRaw], rle_bytes);
  const size_t rest = size - pos;
  uint64_t sections = 0;
  for (const DwaField s : {kDwaZlibSize, kDwaAcSize, kDwaDcSize, kDwaRleSize}) {
    if (f[s] > rest - sections) {
      return "DWA sections of " + std::to_string(f[kDwaZlibSize]) + ", " + std::to_string(f[kDwaAcSize]) + ", " +
             std::to_string(f[kDwaDcSize]) + " and " + std::to_string(f[kDwaRleSize]) + " bytes do not fit in its " +
             std::to_string(rest);
    }
    sections += f[s];
  }
  if (zlib_bytes == 0) return "";

  // Imf inflates the zlib section without checking how much came out.
  z_stream z{};
  if (inflateInit(&z) != Z_OK) throw std::bad_alloc();
  z.next_in = const_cast<Bytef*>(data + pos);
  z.avail_in = static_cast<uInt>(f[kDwaZlibSize]);
  uint64_t out = 0;
  int r = Z_OK;
  Bytef scratch[16384];
  while (r == Z_OK && out <= zlib_bytes) {
    z.next_out = scratch;
    z.avail_out = sizeof scratch;
    r = inflate(&z, Z_NO_FLUSH);
    out += sizeof scratch - z.avail_out;
  }
  const std::string zlib_said = z.msg != nullptr ? z.msg : "";
  inflateEnd(&z);
  if (r == Z_STREAM_END && out == zlib_bytes) return "";
  if (out > zlib_bytes) {
    return "DWA zlib section inflates to more than the " + std::to_string(zlib_bytes) + " bytes its rows need";
  }
  if (r == Z_STREAM_END) {
    return "DWA zlib section inflates to " + std::to_string(out) + " bytes where its rows need " +
           std::to_string(zlib_bytes);
  }
  return "DWA zlib section does not inflate (" + (r == Z_BUF_ERROR ? "cut short" : Printable(zlib_said)) + ")";
}

// Where the chunks' samples go: the reads' planes (display-window sized, with
// the origin disp_x, disp_y), inside the overlap x0..x1, y0..y1 of the data
// and display windows.
struct Unpack {
  const std::vector<ChannelRead>* reads;
  int64_t disp_x, disp_y;
  int width;
  int64_t x0, y0, x1, y1;
  // Set by DecodeChunks: per channel of the part, in file order, its type
  // (0 uint, 1 half, 2 float) and the index of its read (-1 if not read).
  std::vector<int> type, read;
};

uint32_t Load32(const uint8_t* p) {
  return uint32_t{p[0]} | (uint32_t{p[1]} << 8) | (uint32_t{p[2]} << 16) | (uint32_t{p[3]} << 24);
}

// Copies the samples of a chunk holding pixels cx0..cx1, cy0..cy1 (`bytes`
// as the chunk's decompressed data: per row, per channel in file order, a
// sample per pixel, little-endian) into the planes; as Imf reads them: half
// and uint become float, float is copied. `stats` holds a count per read.
// False if the chunk's size is not what its rows need.
bool UnpackChunk(const Unpack& u, const uint8_t* bytes, uint64_t size, int64_t cx0, int64_t cy0, int64_t cx1,
                 int64_t cy1, std::vector<InputSanitizeStats>* stats) {
  uint64_t row = 0;
  for (const int t : u.type) row += static_cast<uint64_t>(cx1 - cx0 + 1) * (t == 1 ? 2 : 4);
  if (size != row * static_cast<uint64_t>(cy1 - cy0 + 1)) return false;
  const int64_t xa = std::max(cx0, u.x0), xb = std::min(cx1, u.x1);
  for (int64_t y = std::max(cy0, u.y0); y <= std::min(cy1, u.y1) && xa <= xb; ++y) {
    const uint8_t* src = bytes + static_cast<uint64_t>(y - cy0) * row;
    for (size_t c = 0; c < u.type.size(); ++c) {
      const int bpe = u.type[c] == 1 ? 2 : 4;
      if (u.read[c] >= 0) {
        const ChannelRead& r = (*u.reads)[static_cast<size_t>(u.read[c])];
        InputSanitizeStats* st = &(*stats)[static_cast<size_t>(u.read[c])];
        float* dst = r.out->data.data() + static_cast<size_t>((y - u.disp_y) * u.width);
        auto copy = [&](auto to_float) {
          for (int64_t x = xa; x <= xb; ++x) {
            float v = to_float(src + (x - cx0) * bpe);
            if (Clean(&v, r.mode, st)) {
              NoteReplaced(st, r.name, static_cast<int>(x - u.disp_x), static_cast<int>(y - u.disp_y));
            }
            dst[x - u.disp_x] = v;
          }
        };
        if (u.type[c] == 1) {
          copy([](const uint8_t* s) -> float { return half(half::FromBits, static_cast<uint16_t>(s[0] | (s[1] << 8))); });
        } else if (u.type[c] == 2) {
          copy([](const uint8_t* s) { return std::bit_cast<float>(Load32(s)); });
        } else {
          copy([](const uint8_t* s) { return static_cast<float>(Load32(s)); });
        }
      }
      src += static_cast<uint64_t>(cx1 - cx0 + 1) * static_cast<uint64_t>(bpe);
    }
  }
  return true;
}

// Throws (naming the chunk) unless every chunk of flat part `part` holding
// rows y0..y1 of its data window decompresses to the size its rows need.
// OpenEXR 3.1's C++ reader does not check that: the rows of a ZIP chunk
// that inflated short were filled from uninitialised memory. Core's decoder
// checks it; then each chunk's samples are copied into `target`'s planes
// (Core decompresses, camsim converts and cleans: the one pass over the
// file), chunks stored as they are read too, and the counts added to the
// reads' stats. Returns true if so; false if the chunks were only checked,
// for Imf to read the pixels after: DWAA/DWAB chunks, which Core 3.1 cannot
// decode (DwaChunkProblem checks them), and parts with a subsampled channel
// (UnpackChunk handles only channels with a sample per pixel).
// The chunks are decompressed on several threads (a decoder each, as Core
// allows); the error names the first bad chunk in file order, whatever the
// threads' timing.
bool DecodeChunks(const std::string& path, int part, int y0, int y1, Unpack* target) {
  CoreFile core(path);
  const exr_const_context_t ctx = core.context();
  auto fail = [&](const std::string& where, const std::string& why) {
    int parts = 1;
    exr_get_count(ctx, &parts);
    throw std::runtime_error("corrupt chunk at " + where + (parts > 1 ? " of part " + std::to_string(part) : "") +
                             " (" + why + ")");
  };
  exr_storage_t storage = EXR_STORAGE_SCANLINE;
  exr_compression_t compression = EXR_COMPRESSION_NONE;
  exr_attr_box2i_t dw{};
  exr_result_t r = core.opened();
  if (r == EXR_ERR_SUCCESS) r = exr_get_storage(ctx, part, &storage);
  if (r == EXR_ERR_SUCCESS) r = exr_get_compression(ctx, part, &compression);
  if (r == EXR_ERR_SUCCESS) r = exr_get_data_window(ctx, part, &dw);
  if (r != EXR_ERR_SUCCESS) throw std::runtime_error(core.Reason(r));
  const bool dwa = compression == EXR_COMPRESSION_DWAA || compression == EXR_COMPRESSION_DWAB;
  const exr_attr_chlist_t* channels = nullptr;
  r = exr_get_channels(ctx, part, &channels);
  if (r != EXR_ERR_SUCCESS) throw std::runtime_error(core.Reason(r));
  std::vector<DwaChannel> dwa_channels;
  Unpack* unpack = dwa ? nullptr : target;
  if (unpack != nullptr) {
    unpack->type.assign(static_cast<size_t>(channels->num_channels), 0);
    unpack->read.assign(static_cast<size_t>(channels->num_channels), -1);
  }
  for (int i = 0; i < channels->num_channels; ++i) {
    const exr_attr_chlist_entry_t& c = channels->entries[i];
    const std::string name(c.name.str, static_cast<size_t>(c.name.length));
    if (dwa) {
      const size_t dot = name.rfind('.');
      dwa_channels.push_back({dot == std::string::npos ? name : name.substr(dot + 1), static_cast<int>(c.pixel_type),
                              std::max(c.x_sampling, 1), std::max(c.y_sampling, 1)});
    }
    if (unpack == nullptr) continue;
    if (c.x_sampling != 1 || c.y_sampling != 1) {
      unpack = nullptr;
      continue;
    }
    unpack->type[static_cast<size_t>(i)] = static_cast<int>(c.pixel_type);
    // As Imf's frame buffer: a channel read twice goes to the last plane.
    for (size_t k = 0; k < unpack->reads->size(); ++k) {
      if ((*unpack->reads)[k].name == name) unpack->read[static_cast<size_t>(i)] = static_cast<int>(k);
    }
  }

  // The chunks to decompress (or, when unpacking, to read as stored), in
  // file order, with the pixels each holds.
  struct Item {
    exr_chunk_info_t chunk;
    std::string where;
    int64_t x0, y0, x1, y1;
    bool stored;  // its bytes are the samples (uncompressed, or no smaller than its rows)
  };
  std::vector<Item> items;
  auto take = [&](const exr_chunk_info_t& chunk, const std::string& where, int64_t x0, int64_t cy0, int64_t x1,
                  int64_t cy1) {
    // Core passes an empty chunk without a word, and does not decode an uncompressed one.
    if ((chunk.packed_size == 0 && chunk.unpacked_size != 0) ||
        (compression == EXR_COMPRESSION_NONE && chunk.packed_size != chunk.unpacked_size)) {
      fail(where, std::to_string(chunk.packed_size) + " bytes where its rows need " +
                      std::to_string(chunk.unpacked_size));
    }
    // A chunk no smaller than its rows is stored as it is, and Imf reads it so
    // (Core 3.1 fails on such a B44 tile at the edge): read, not decoded.
    const bool stored = compression == EXR_COMPRESSION_NONE || chunk.packed_size >= chunk.unpacked_size;
    if (stored && unpack == nullptr) return;
    items.push_back({chunk, where, x0, cy0, x1, cy1, stored});
  };

  exr_chunk_info_t chunk{};
  if (storage == EXR_STORAGE_SCANLINE) {
    int32_t lines = 1;
    r = exr_get_scanlines_per_chunk(ctx, part, &lines);
    if (r != EXR_ERR_SUCCESS) throw std::runtime_error(core.Reason(r));
    for (int64_t y = y0; y <= y1; y = int64_t{chunk.start_y} + std::max(lines, 1)) {
      r = exr_read_scanline_chunk_info(ctx, part, static_cast<int>(y), &chunk);
      if (r != EXR_ERR_SUCCESS) fail("scan line " + std::to_string(y), core.Reason(r));
      take(chunk, "scan line " + std::to_string(chunk.start_y), dw.min.x, chunk.start_y, dw.max.x,
           int64_t{chunk.start_y} + chunk.height - 1);
    }
  } else if (storage == EXR_STORAGE_TILED) {
    // Level 0 only: the others are not read. Whole rows of tiles, as Imf reads them.
    int32_t tile_w = 1, tile_h = 1;
    r = exr_get_tile_sizes(ctx, part, 0, 0, &tile_w, &tile_h);
    if (r != EXR_ERR_SUCCESS) throw std::runtime_error(core.Reason(r));
    tile_w = std::max(tile_w, 1);
    tile_h = std::max(tile_h, 1);
    const int64_t tiles_x = (int64_t{dw.max.x} - dw.min.x + tile_w) / tile_w;
    for (int64_t ty = (int64_t{y0} - dw.min.y) / tile_h; ty <= (int64_t{y1} - dw.min.y) / tile_h; ++ty) {
      for (int64_t tx = 0; tx < tiles_x; ++tx) {
        const std::string where = "tile (" + std::to_string(tx) + ", " + std::to_string(ty) + ")";
        r = exr_read_tile_chunk_info(ctx, part, static_cast<int>(tx), static_cast<int>(ty), 0, 0, &chunk);
        if (r != EXR_ERR_SUCCESS) fail(where, core.Reason(r));
        const int64_t x = dw.min.x + tx * tile_w, y = dw.min.y + ty * tile_h;
        take(chunk, where, x, y, std::min<int64_t>(x + tile_w - 1, dw.max.x), std::min<int64_t>(y + tile_h - 1, dw.max.y));
      }
    }
  }

  // Decompresses (and unpacks) item `only`, or else items taken from `next`;
  // a result per item (and for DWA, why it is corrupt). Item `only` is
  // decoded again for Core's reason alone: not unpacked.
  std::vector<exr_result_t> result(items.size(), EXR_ERR_SUCCESS);
  std::vector<std::string> dwa_problem(items.size());
  std::vector<char> wrong_size(items.size(), 0);  // decompressed, but not to its rows' size
  std::vector<char> no_memory(items.size(), 0);   // std::bad_alloc in camsim's code
  std::atomic<size_t> next{0};
  // A thread per core up to kMaxCheckThreads, for files of many chunks.
  constexpr unsigned kMaxCheckThreads = 8, kChunksPerThread = 16;
  const size_t helpers = std::min<size_t>({std::max(1u, std::thread::hardware_concurrency()), kMaxCheckThreads,
                                           items.size() / kChunksPerThread + 1}) - 1;
  // The counts of each thread (a slot each), per read.
  std::vector<std::vector<InputSanitizeStats>> slots(
      helpers + 1, std::vector<InputSanitizeStats>(unpack != nullptr ? unpack->reads->size() : 0));
  std::atomic<size_t> next_slot{0};
  auto decode = [&](size_t only) {
    exr_decode_pipeline_t decoder{};  // as EXR_DECODE_PIPELINE_INITIALIZER: all zero
    bool started = false;
    std::vector<uint8_t> packed;  // a DWA or stored chunk's bytes
    std::vector<InputSanitizeStats>* stats = only < items.size() ? nullptr : &slots[next_slot.fetch_add(1)];
    for (size_t i; (i = only < items.size() ? only : next.fetch_add(1)) < items.size();) {
      exr_result_t d = EXR_ERR_SUCCESS;
      const Item& it = items[i];
      try {
        const uint8_t* bytes = nullptr;  // the decompressed chunk
        if (dwa || it.stored) {
          packed.resize(it.chunk.packed_size);
          d = exr_read_chunk(ctx, part, &it.chunk, packed.data());
          if (d == EXR_ERR_SUCCESS && dwa)
            dwa_problem[i] = DwaChunkProblem(dwa_channels, packed.data(), packed.size(), it.x0, it.y0, it.x1, it.y1);
          if (!dwa_problem[i].empty()) d = EXR_ERR_CORRUPT_CHUNK;
          bytes = packed.data();  // a stored chunk's first unpacked_size bytes are its samples
        } else {
          if (!started) {
            // No channel has a destination: the decoder decompresses and stops.
            d = exr_decoding_initialize(ctx, part, &it.chunk, &decoder);
            if (d == EXR_ERR_SUCCESS) d = exr_decoding_choose_default_routines(ctx, part, &decoder);
            decoder.unpack_and_convert_fn = nullptr;
            started = d == EXR_ERR_SUCCESS;
          } else {
            d = exr_decoding_update(ctx, part, &it.chunk, &decoder);
          }
          if (d == EXR_ERR_SUCCESS) d = exr_decoding_run(ctx, part, &decoder);
          bytes = static_cast<const uint8_t*>(decoder.unpacked_buffer);
        }
        if (d == EXR_ERR_SUCCESS && unpack != nullptr && stats != nullptr &&
            !UnpackChunk(*unpack, bytes, it.chunk.unpacked_size, it.x0, it.y0, it.x1, it.y1, stats)) {
          wrong_size[i] = 1;
          d = EXR_ERR_CORRUPT_CHUNK;
        }
      } catch (const std::bad_alloc&) {
        d = EXR_ERR_OUT_OF_MEMORY;  // thrown again below, on the caller's thread
        no_memory[i] = 1;
      }
      result[i] = d;
      if (only < items.size()) break;
    }
    exr_decoding_destroy(ctx, &decoder);
  };
  {
    std::vector<std::thread> threads;
    try {
      for (size_t t = 0; t < helpers; ++t) threads.emplace_back(decode, items.size());
    } catch (const std::system_error&) {
      // No more threads now: the ones started and this one do the rest.
    }
    decode(items.size());
    for (std::thread& t : threads) t.join();
  }
  for (size_t i = 0; i < items.size(); ++i) {
    if (result[i] == EXR_ERR_SUCCESS) continue;
    if (!dwa_problem[i].empty()) fail(items[i].where, dwa_problem[i]);
    if (wrong_size[i]) {
      fail(items[i].where, "decompressed to " + std::to_string(items[i].chunk.unpacked_size) +
                               " bytes, not the size of its rows");
    }
    if (no_memory[i]) throw std::bad_alloc();
    // What Core says about this chunk alone: decoded again on this thread.
    core.Forget();
    decode(i);
    fail(items[i].where, core.Reason(result[i]));
  }
  if (unpack == nullptr) return false;
  // The counts add up; the first sample replaced is the lowest (y, x) of
  // all, and of the earlier read at the same pixel (one thread held it: its
  // reads are added in order).
  for (const std::vector<InputSanitizeStats>& stats : slots) {
    for (size_t c = 0; c < stats.size(); ++c) {
      InputSanitizeStats* to = (*unpack->reads)[c].stats;
      const InputSanitizeStats& from = stats[c];
      if (to == nullptr) continue;
      to->nan += from.nan;
      to->pos_inf += from.pos_inf;
      to->neg_inf += from.neg_inf;
      to->negative += from.negative;
      if (!from.first_channel.empty()) NoteReplaced(to, from.first_channel, from.first_x, from.first_y);
    }
  }
  return true;
}

}  // namespace

bool DisplaySize(const Imf::Header& header, int* width, int* height) {
  const Imath::Box2i& d = header.displayWindow();
  const int64_t w = int64_t{d.max.x} - d.min.x + 1, h = int64_t{d.max.y} - d.min.y + 1;
  if (w < 1 || h < 1 || w > kMaxDisplayDim || h > kMaxDisplayDim || w * h > kMaxDisplayPixels) return false;
  *width = static_cast<int>(w);
  *height = static_cast<int>(h);
  return true;
}

void ReadChannels(const std::string& path, Imf::MultiPartInputFile& file, int part,
                  const std::vector<ChannelRead>& reads) {
  // The windows are checked on the header before the part is opened: opening
  // it sizes the decompressor's line buffers from the data window (a 2^30
  // wide window asked for 3 GB; found by fuzz_exr_loader).
  const Imf::Header& header = file.header(part);
  const Imath::Box2i disp = header.displayWindow(), data = header.dataWindow();
  int width = 0, height = 0;
  if (!DisplaySize(header, &width, &height)) {
    throw UnsupportedExr("display window " + BoxText(disp) + " is empty, larger than " +
                         std::to_string(kMaxDisplayDim) + " x " + std::to_string(kMaxDisplayDim) + " or more than " +
                         std::to_string(kMaxDisplayPixels) + " pixels");
  }
  const int64_t data_width = int64_t{data.max.x} - data.min.x + 1;
  if (data_width < 1 || data_width > kMaxDataWidth || data.max.y < data.min.y) {
    throw UnsupportedExr("data window " + BoxText(data) + " is empty or wider than " +
                         std::to_string(kMaxDataWidth));
  }
  for (const ChannelRead& r : reads) {
    const Imf::Channel* ch = header.channels().findChannel(r.name);
    if (ch == nullptr) throw UnsupportedExr("no channel '" + r.name + "'");
    if (ch->xSampling != 1 || ch->ySampling != 1) {
      throw UnsupportedExr("channel '" + r.name + "' is subsampled, which is not supported");
    }
    r.out->width = width;
    r.out->height = height;
    r.out->data.assign(static_cast<size_t>(width) * static_cast<size_t>(height),
                       r.mode == Sanitize::kDepth ? kInf : 0.0f);
  }

  // The part of the data window inside the display window.
  const int x0 = std::max(data.min.x, disp.min.x), x1 = std::min(data.max.x, disp.max.x);
  const int y0 = std::max(data.min.y, disp.min.y), y1 = std::min(data.max.y, disp.max.y);
  if (x0 > x1 || y0 > y1) return;

  Unpack target{&reads, disp.min.x, disp.min.y, width, x0, y0, x1, y1, {}, {}};
  if (DecodeChunks(path, part, y0, y1, &target)) return;

  // Chunks Core cannot decode: read by Imf (checked above).
  // Imf decompresses the line buffers of one readPixels call on its global
  // thread pool (none by default): a thread per core, set once, for every reader.
  static const bool kThreadPoolSet = [] {
    if (Imf::globalThreadCount() == 0)
      Imf::setGlobalThreadCount(static_cast<int>(std::min(8u, std::max(1u, std::thread::hardware_concurrency()))));
    return true;
  }();
  (void)kThreadPoolSet;
  Imf::InputPart in(file, part);
  // Read strips of whole data-window rows (about 1M samples per channel: a
  // bounded buffer, few calls into OpenEXR), copy the overlap.
  const int64_t strip_rows =
      std::min<int64_t>(int64_t{y1} - y0 + 1, std::max<int64_t>(16, (int64_t{1} << 20) / data_width));
  const size_t plane_samples = static_cast<size_t>(data_width * strip_rows);
  std::vector<float> buffer(plane_samples * reads.size());
  for (int64_t y = y0; y <= y1; y += strip_rows) {
    const int64_t y_end = std::min<int64_t>(y1, y + strip_rows - 1);
    Imf::FrameBuffer fb;
    for (size_t c = 0; c < reads.size(); ++c) {
      fb.insert(reads[c].name,
                Imf::Slice::Make(Imf::FLOAT, buffer.data() + c * plane_samples,
                                 Imath::V2i(data.min.x, static_cast<int>(y)), data_width,
                                 y_end - y + 1, sizeof(float), data_width * sizeof(float)));
    }
    in.setFrameBuffer(fb);
    in.readPixels(static_cast<int>(y), static_cast<int>(y_end));
    for (size_t c = 0; c < reads.size(); ++c) {
      const ChannelRead& r = reads[c];
      for (int64_t yy = y; yy <= y_end; ++yy) {
        const float* src = buffer.data() + c * plane_samples +
                           static_cast<size_t>((yy - y) * data_width + (x0 - data.min.x));
        float* dst = r.out->data.data() + static_cast<size_t>((yy - disp.min.y) * width) +
                     static_cast<size_t>(x0 - disp.min.x);
        for (int x = 0; x <= x1 - x0; ++x) {
          float v = src[x];
          if (Clean(&v, r.mode, r.stats)) {
            NoteReplaced(r.stats, r.name, x0 - disp.min.x + x, static_cast<int>(yy - disp.min.y));
          }
          dst[x] = v;
        }
      }
    }
  }
}

}  // namespace camsim::io::detail
