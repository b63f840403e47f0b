#include "host_tools/pattern.h"

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>

#include "host_tools/io/image_write.h"

namespace camsim::host {
namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr double kSlantDegrees = 5.0;  // ISO 12233 slanted edge
constexpr int kStarSpokes = 36;        // dark/light cycles around the star (72 sectors)
constexpr double kDotRadiusOfCell = 0.25;

// The board's squares: count and origin (top-left corner), centred, with at
// least one cell of light margin all round.
void Board(const PatternOptions& o, int* nx, int* ny, double* x0, double* y0) {
  const double cell = PatternCell(o);
  *nx = static_cast<int>(std::floor(o.width / cell)) - 2;
  *ny = static_cast<int>(std::floor(o.height / cell)) - 2;
  if (*nx < 1) *nx = 1;
  if (*ny < 1) *ny = 1;
  *x0 = (o.width - 1) / 2.0 - *nx * cell / 2.0;
  *y0 = (o.height - 1) / 2.0 - *ny * cell / 2.0;
}

}  // namespace

bool PatternFromName(const std::string& n, PatternKind* k) {
  if (n == "checkerboard") *k = PatternKind::kCheckerboard;
  else if (n == "dot-grid" || n == "dotgrid" || n == "dots") *k = PatternKind::kDotGrid;
  else if (n == "slanted-edge" || n == "edge") *k = PatternKind::kSlantedEdge;
  else if (n == "siemens-star" || n == "star") *k = PatternKind::kSiemensStar;
  else return false;
  return true;
}

double PatternCell(const PatternOptions& o) { return o.cell > 0.0 ? o.cell : o.height / 12.0; }
double PatternDotRadius(const PatternOptions& o) {
  return o.dot_radius > 0.0 ? o.dot_radius : kDotRadiusOfCell * PatternCell(o);
}

double PatternAt(const PatternOptions& o, double x, double y) {
  const double cell = PatternCell(o);
  const double cx = (o.width - 1) / 2.0, cy = (o.height - 1) / 2.0;
  switch (o.kind) {
    case PatternKind::kCheckerboard: {
      int nx, ny;
      double x0, y0;
      Board(o, &nx, &ny, &x0, &y0);
      const double bx = (x - x0) / cell, by = (y - y0) / cell;
      if (bx < 0 || by < 0 || bx >= nx || by >= ny) return o.high;
      return ((static_cast<int>(bx) + static_cast<int>(by)) & 1) ? o.high : o.low;
    }
    case PatternKind::kDotGrid: {
      int nx, ny;
      double x0, y0;
      Board(o, &nx, &ny, &x0, &y0);
      // Dots at the centres of the board's cells: bright dots on dark.
      const double bx = (x - x0) / cell, by = (y - y0) / cell;
      if (bx < 0 || by < 0 || bx >= nx || by >= ny) return o.low;
      const double dx = (bx - std::floor(bx) - 0.5) * cell, dy = (by - std::floor(by) - 0.5) * cell;
      const double r = PatternDotRadius(o);
      return dx * dx + dy * dy < r * r ? o.high : o.low;
    }
    case PatternKind::kSlantedEdge: {
      const double t = kSlantDegrees * kPi / 180.0;
      // Signed distance to a line through the centre, kSlantDegrees from vertical.
      const double d = (x - cx) * std::cos(t) - (y - cy) * std::sin(t);
      return d < 0 ? o.low : o.high;
    }
    case PatternKind::kSiemensStar: {
      const double r = std::hypot(x - cx, y - cy);
      if (r > 0.45 * std::min(o.width, o.height)) return (o.low + o.high) / 2.0;
      const double a = std::atan2(y - cy, x - cx);
      const int sector = static_cast<int>(std::floor((a + kPi) / (2.0 * kPi) * 2.0 * kStarSpokes));
      return (sector & 1) ? o.high : o.low;
    }
  }
  return 0.0;
}

std::vector<float> RenderPattern(const PatternOptions& o) {
  std::vector<float> img(static_cast<size_t>(o.width) * o.height);
  const int s = o.supersample < 1 ? 1 : o.supersample;
  for (int y = 0; y < o.height; ++y)
    for (int x = 0; x < o.width; ++x) {
      double sum = 0.0;
      for (int j = 0; j < s; ++j)
        for (int i = 0; i < s; ++i) sum += PatternAt(o, x - 0.5 + (i + 0.5) / s, y - 0.5 + (j + 0.5) / s);
      img[static_cast<size_t>(y) * o.width + x] = static_cast<float>(sum / (s * s));
    }
  return img;
}

std::vector<std::pair<double, double>> PatternDotCentres(const PatternOptions& o) {
  int nx, ny;
  double x0, y0;
  Board(o, &nx, &ny, &x0, &y0);
  const double cell = PatternCell(o);
  std::vector<std::pair<double, double>> v;
  for (int j = 0; j < ny; ++j)
    for (int i = 0; i < nx; ++i) v.emplace_back(x0 + (i + 0.5) * cell, y0 + (j + 0.5) * cell);
  return v;
}

std::vector<std::pair<double, double>> PatternCorners(const PatternOptions& o, int* cols, int* rows) {
  int nx, ny;
  double x0, y0;
  Board(o, &nx, &ny, &x0, &y0);
  const double cell = PatternCell(o);
  *cols = nx - 1;
  *rows = ny - 1;
  std::vector<std::pair<double, double>> v;
  for (int j = 1; j < ny; ++j)
    for (int i = 1; i < nx; ++i) v.emplace_back(x0 + i * cell, y0 + j * cell);
  return v;
}

extern const char kPatternUsage[] =
    "  camsim pattern checkerboard|dot-grid|slanted-edge|siemens-star --out EXR\n"
    "                 [--width W] [--height H] [--cell PX] [--supersample N]\n"
    "      a calibration target (radiance, R = G = B) to run through camsim\n"
    "      (width/height 8..16384, cell >= 4, supersample 1..64)\n";

int PatternCommand(int argc, char** argv) {
  const std::string usage_text = std::string("usage:\n") + kPatternUsage;
  const char* usage = usage_text.c_str();
  if (argc < 3) {
    std::fputs(usage, stderr);
    return 1;
  }
  PatternOptions o;
  if (!PatternFromName(argv[2], &o.kind)) {
    std::fprintf(stderr, "camsim: unknown pattern '%s'\n%s", argv[2], usage);
    return 1;
  }
  std::string out;
  for (int i = 3; i < argc; ++i) {
    const std::string a = argv[i];
    if (i + 1 >= argc) {
      std::fprintf(stderr, "camsim: %s needs a value\n%s", a.c_str(), usage);
      return 1;
    }
    const char* v = argv[++i];
    char* end = nullptr;
    if (a == "--out") {
      out = v;
      continue;
    }
    const double num = std::strtod(v, &end);
    if (end == v || *end != '\0' || !std::isfinite(num)) {
      std::fprintf(stderr, "camsim: %s: '%s' is not a number\n", a.c_str(), v);
      return 1;
    }
    const bool whole = num == std::floor(num);  // sizes and the supersample count are whole numbers
    if ((a == "--width" || a == "--height" || a == "--supersample") && !whole) {
      std::fprintf(stderr, "camsim: %s: '%s' is not a whole number\n", a.c_str(), v);
      return 1;
    }
    if (a == "--width" && num >= 8 && num <= 16384) o.width = static_cast<int>(num);
    else if (a == "--height" && num >= 8 && num <= 16384) o.height = static_cast<int>(num);
    else if (a == "--cell" && num >= 4) o.cell = num;
    else if (a == "--supersample" && num >= 1 && num <= 64) o.supersample = static_cast<int>(num);
    else {
      std::fprintf(stderr, "camsim: %s %s: unknown option or out of range (width/height 8..16384, cell >= 4, "
                           "supersample 1..64)\n", a.c_str(), v);
      return 1;
    }
  }
  if (out.empty()) {
    std::fprintf(stderr, "camsim: --out FILE.exr is required\n%s", usage);
    return 1;
  }
  std::string error, target;
  if (!io::WritableTarget(out, &target, &error)) {  // a FIFO or device: refused before rendering
    std::fprintf(stderr, "camsim: %s\n", error.c_str());
    return 2;
  }
  const std::vector<float> img = RenderPattern(o);
  std::vector<io::ExrChannel> ch = {{"R", img.data(), o.width}, {"G", img.data(), o.width}, {"B", img.data(), o.width}};
  if (!io::WriteExrFloat(out, o.width, o.height, ch, &error)) {
    std::fprintf(stderr, "camsim: %s\n", error.c_str());
    return 2;
  }
  return 0;
}

}  // namespace camsim::host
