#include "host_tools/io/image_read.h"

#include <sys/stat.h>

#include <algorithm>
#include <bit>
#include <cctype>
#include <cerrno>
#include <csetjmp>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <memory>
#include <new>

#include <OpenEXR/ImfChannelList.h>
#include <png.h>

#include "host_tools/io/exr_common.h"
#include "host_tools/io/png_error.h"

namespace camsim::io {
namespace {

using detail::OnPngError;
using detail::OnPngWarning;
using detail::PngErrorText;

struct DecodedPng {
  uint32_t width = 0, height = 0;
  int channels = 0, bit_depth = 0;  // after expansion: 1 or 3 channels, 8 or 16 bits
  std::unique_ptr<unsigned char[]> pixels;  // rows packed, 16-bit samples native-endian
};

// Decodes `f` into *out. Because of setjmp/longjmp, no object with a
// destructor lives in this frame (*out is the caller's).
bool DecodePng(std::FILE* f, DecodedPng* out, PngErrorText* err) {
  png_structp png = png_create_read_struct(PNG_LIBPNG_VER_STRING, err, OnPngError, OnPngWarning);
  png_infop info = png ? png_create_info_struct(png) : nullptr;
  if (info == nullptr) {
    png_destroy_read_struct(&png, nullptr, nullptr);
    std::snprintf(err->text, sizeof err->text, "out of memory");
    return false;
  }
  if (setjmp(png_jmpbuf(png))) {
    png_destroy_read_struct(&png, &info, nullptr);
    return false;
  }
  png_init_io(png, f);
  png_read_info(png, info);
  out->width = png_get_image_width(png, info);
  out->height = png_get_image_height(png, info);
  if (out->width > detail::kMaxDisplayDim || out->height > detail::kMaxDisplayDim) {
    png_error(png, "image larger than 16384 x 16384");
  }
  png_set_expand(png);  // palette -> RGB, gray < 8 bits -> 8 bits, tRNS -> alpha
  png_set_strip_alpha(png);
  if (png_get_bit_depth(png, info) == 16 && std::endian::native == std::endian::little) {
    png_set_swap(png);
  }
  const int passes = png_set_interlace_handling(png);
  png_read_update_info(png, info);
  out->channels = png_get_channels(png, info);
  out->bit_depth = png_get_bit_depth(png, info);
  const size_t row_bytes = png_get_rowbytes(png, info);
  out->pixels.reset(new (std::nothrow) unsigned char[row_bytes * out->height]);
  if (!out->pixels) png_error(png, "out of memory");
  for (int pass = 0; pass < passes; ++pass) {
    for (uint32_t y = 0; y < out->height; ++y) png_read_row(png, &out->pixels[y * row_bytes], nullptr);
  }
  png_read_end(png, nullptr);
  png_destroy_read_struct(&png, &info, nullptr);
  return true;
}

std::string LowerExtension(const std::string& path) {
  std::string ext = std::filesystem::path(path).extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return ext;
}

bool ReadExrMask(const std::string& path, FloatPlane* out, std::string* error) {
  const std::unique_ptr<Imf::MultiPartInputFile> file = detail::OpenExr(path, error);
  return file && detail::CatchExr(path, error, [&] {
           int part = -1;
           std::string name;
           for (const char* want : {"Y", "R"}) {
             for (int p = 0; p < file->parts() && part < 0; ++p) {
               if (detail::PartHasChannel(*file, p, want)) {
                 part = p;
                 name = want;
               }
             }
           }
           for (int p = 0; p < file->parts() && part < 0; ++p) {
             const Imf::ChannelList& channels = file->header(p).channels();
             if (detail::IsFlatPart(*file, p) && channels.begin() != channels.end()) {
               part = p;
               name = channels.begin().name();
             }
           }
           if (part < 0) {
             *error = "'" + path + "': no channels to use as a mask";
             return false;
           }
           FloatPlane plane;
           detail::ReadChannels(path, *file, part, {{name, &plane, detail::Sanitize::kNone, nullptr}});
           *out = std::move(plane);
           return true;
         });
}

}  // namespace

// Opens and decodes `path`; errors name the file.
static bool DecodePngFile(const std::string& path, DecodedPng* png, std::string* error) {
  struct FileCloser {
    void operator()(std::FILE* f) const { std::fclose(f); }
  };
  std::unique_ptr<std::FILE, FileCloser> f(std::fopen(path.c_str(), "rb"));
  if (!f) {
    *error = "cannot open '" + path + "': " + std::strerror(errno);
    return false;
  }
  struct stat st;
  if (fstat(fileno(f.get()), &st) == 0 && S_ISDIR(st.st_mode)) {  // opens on Linux, then fails to read
    *error = "'" + path + "' is a directory, not a PNG file";
    return false;
  }
  PngErrorText err;
  if (!DecodePng(f.get(), png, &err)) {
    *error = "'" + path + "' is not a readable PNG file: " + err.text;
    return false;
  }
  return true;
}

bool ReadPng(const std::string& path, FloatPlane* gray_out, std::string* error) {
  try {
    DecodedPng png;
    if (!DecodePngFile(path, &png, error)) return false;
    const double max_value = png.bit_depth == 16 ? 65535.0 : 255.0;
    FloatPlane plane;
    plane.width = static_cast<int>(png.width);
    plane.height = static_cast<int>(png.height);
    plane.data.resize(static_cast<size_t>(png.width) * png.height);
    auto sample = [&](size_t s) -> double {
      if (png.bit_depth == 8) return png.pixels[s];
      uint16_t v;
      std::memcpy(&v, &png.pixels[2 * s], 2);
      return v;
    };
    for (size_t i = 0; i < plane.data.size(); ++i) {
      double sum = 0.0;
      for (int c = 0; c < png.channels; ++c) sum += sample(i * png.channels + c);
      plane.data[i] = static_cast<float>(sum / (max_value * png.channels));
    }
    *gray_out = std::move(plane);
    return true;
  } catch (const std::exception& e) {
    *error = "cannot read '" + path + "': " + e.what();
  }
  return false;
}

bool ReadPngGrayRaw(const std::string& path, std::vector<uint16_t>* out, int* width, int* height, int* bit_depth,
                    std::string* error) {
  try {
    DecodedPng png;
    if (!DecodePngFile(path, &png, error)) return false;
    if (png.channels != 1) {
      *error = "'" + path + "': expected a gray PNG, found " + std::to_string(png.channels) + " channels";
      return false;
    }
    std::vector<uint16_t> v(static_cast<size_t>(png.width) * png.height);
    for (size_t i = 0; i < v.size(); ++i) {
      if (png.bit_depth == 8) {
        v[i] = png.pixels[i];
      } else {
        std::memcpy(&v[i], &png.pixels[2 * i], 2);
      }
    }
    *out = std::move(v);
    *width = static_cast<int>(png.width);
    *height = static_cast<int>(png.height);
    *bit_depth = png.bit_depth == 16 ? 16 : 8;
    return true;
  } catch (const std::exception& e) {
    *error = "cannot read '" + path + "': " + e.what();
  }
  return false;
}

bool ReadMaskImage(const std::string& path, FloatPlane* out, std::string* error) {
  const std::string ext = LowerExtension(path);
  if (ext == ".png") return ReadPng(path, out, error);
  if (ext == ".exr") return ReadExrMask(path, out, error);
  *error = "'" + path + "': unsupported mask format (expected .png or .exr)";
  return false;
}

}  // namespace camsim::io
