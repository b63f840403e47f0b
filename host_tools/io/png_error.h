// libpng error handling shared by the PNG reader and writer: libpng reports
// errors through longjmp, so the message is copied into a buffer first.
#pragma once

#include <png.h>

#include <cstdio>

namespace camsim::io::detail {

struct PngErrorText {
  char text[256] = "";
};

inline void OnPngError(png_structp png, png_const_charp message) {
  auto* e = static_cast<PngErrorText*>(png_get_error_ptr(png));
  std::snprintf(e->text, sizeof e->text, "%s", message);
  png_longjmp(png, 1);
}

inline void OnPngWarning(png_structp, png_const_charp) {}

}  // namespace camsim::io::detail
