#include "host_tools/report/plot.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdint>
#include <cstdio>

#include "host_tools/io/image_write.h"

namespace camsim::host {
namespace {

// 3x5 glyphs, rows top to bottom, '#' = ink.
struct Glyph {
  char c;
  const char* rows;  // 15 characters
};
constexpr Glyph kFont[] = {
    {'0', "####.##.##.####"}, {'1', ".#.##..#..#.###"}, {'2', "###..#####..###"},
    {'3', "###..#.##..####"}, {'4', "#.##.####..#..#"}, {'5', "####..###..####"},
    {'6', "####..####.####"}, {'7', "###..#.#..#..#."}, {'8', "####.#####.####"},
    {'9', "####.####..####"}, {'A', ".#.#.#####.##.#"}, {'B', "##.#.###.#.###."},
    {'C', ".###..#..#...##"}, {'D', "##.#.##.##.###."}, {'E', "####..##.#..###"},
    {'F', "####..##.#..#.."}, {'G', ".###..#.##.#.##"}, {'H', "#.##.#####.##.#"},
    {'I', "###.#..#..#.###"}, {'J', "..#..#..##.#.#."}, {'K', "#.##.###.#.##.#"},
    {'L', "#..#..#..#..###"}, {'M', "#.########.##.#"}, {'N', "##.#.##.##.##.#"},
    {'O', ".#.#.##.##.#.#."}, {'P', "##.#.###.#..#.."}, {'Q', ".#.#.##.###..##"},
    {'R', "##.#.###.#.##.#"}, {'S', ".###...#...###."}, {'T', "###.#..#..#..#."},
    {'U', "#.##.##.##.####"}, {'V', "#.##.##.##.#.#."}, {'W', "#.##.########.#"},
    {'X', "#.##.#.#.#.##.#"}, {'Y', "#.##.#.#..#..#."}, {'Z', "###..#.#.#..###"},
    {'.', ".............#."}, {',', "..........#.#.."}, {'-', "......###......"},
    {'+', "....#.###.#...."}, {'=', "...###...###..."}, {'/', "..#..#.#.#..#.."},
    {'(', ".#.#..#..#...#."}, {')', ".#...#..#..#.#."}, {':', "....#.....#...."},
    {'_', "............###"}, {'%', "#.#..#.#.#..#.#"}, {'x', "...#.#.#.#.#..."},
    {'<', "..#.#.#...#...#"}, {'>', "#...#...#.#.#.."}, {'*', "...#.#.#.#.#..."},
    {' ', "..............."},
};

const char* GlyphRows(char c) {
  if (c != 'x') c = static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
  for (const Glyph& g : kFont)
    if (g.c == c) return g.rows;
  return nullptr;
}

struct Canvas {
  int w, h;
  std::vector<uint8_t> rgb;
  Canvas(int width, int height) : w(width), h(height), rgb(static_cast<size_t>(width) * height * 3, 255) {}
  void Set(int x, int y, const uint8_t* col) {
    if (x < 0 || y < 0 || x >= w || y >= h) return;
    uint8_t* p = &rgb[(static_cast<size_t>(y) * w + x) * 3];
    p[0] = col[0];
    p[1] = col[1];
    p[2] = col[2];
  }
  void Line(int x0, int y0, int x1, int y1, const uint8_t* col) {
    const int steps = std::max(std::abs(x1 - x0), std::abs(y1 - y0));
    for (int i = 0; i <= steps; ++i) {
      const double t = steps ? static_cast<double>(i) / steps : 0.0;
      Set(static_cast<int>(std::lround(x0 + t * (x1 - x0))), static_cast<int>(std::lround(y0 + t * (y1 - y0))), col);
    }
  }
  void Box(int cx, int cy, int r, bool filled, const uint8_t* col) {
    for (int dy = -r; dy <= r; ++dy)
      for (int dx = -r; dx <= r; ++dx)
        if (filled || std::abs(dx) == r || std::abs(dy) == r) Set(cx + dx, cy + dy, col);
  }
  // Text at (x, y) top-left, glyphs scaled by s; returns the width drawn.
  int Text(int x, int y, const std::string& s, int scale, const uint8_t* col, bool vertical = false) {
    int pos = 0;
    for (char c : s) {
      const char* rows = GlyphRows(c);
      if (rows != nullptr)
        for (int r = 0; r < 5; ++r)
          for (int k = 0; k < 3; ++k)
            if (rows[r * 3 + k] == '#')
              for (int a = 0; a < scale; ++a)
                for (int b = 0; b < scale; ++b) {
                  const int gx = (pos + k) * scale + b, gy = r * scale + a;
                  if (vertical)
                    Set(x + gy, y - gx, col);  // reads bottom to top
                  else
                    Set(x + gx, y + gy, col);
                }
      pos += 4;
    }
    return pos * scale;
  }
};

std::string Short(double v) {
  char buf[32];
  if (v != 0 && (std::fabs(v) < 1e-3 || std::fabs(v) >= 1e5))
    std::snprintf(buf, sizeof buf, "%.0e", v);
  else
    std::snprintf(buf, sizeof buf, "%.3g", v);
  return buf;
}

// A tick step of 1, 2 or 5 times a power of ten giving about `divisions` steps.
double NiceStep(double span, int divisions) {
  const double raw = span / divisions;
  const double decade = std::pow(10.0, std::floor(std::log10(raw)));
  for (double m : {1.0, 2.0, 5.0})
    if (m * decade >= raw) return m * decade;
  return 10.0 * decade;
}

// Series colours, distinct on white; the frontier keeps its own red.
constexpr uint8_t kSeriesColours[][3] = {{40, 90, 200},  {30, 150, 70}, {150, 60, 190}, {220, 130, 20},
                                         {20, 160, 170}, {120, 80, 40}, {90, 90, 90},   {200, 70, 150}};

struct Rect {
  int x0, y0, x1, y1;
  bool Overlaps(const Rect& o) const { return x0 < o.x1 && o.x0 < x1 && y0 < o.y1 && o.y0 < y1; }
};

}  // namespace

bool WriteScatterPng(const std::string& path, const PlotSpec& spec, const std::vector<PlotPoint>& points,
                     std::string* error) {
  constexpr uint8_t kInk[3] = {20, 20, 20}, kGrid[3] = {220, 220, 220}, kPoint[3] = {40, 90, 200},
                    kFront[3] = {200, 40, 40};
  Canvas cv(spec.width, spec.height);
  const int left = 110, right = 40, top = 50, bottom = 80;
  const int pw = spec.width - left - right, ph = spec.height - top - bottom;

  auto ty = [&](double y) { return spec.log_y ? std::log10(std::max(y, 1e-12)) : y; };
  double x0 = 0, x1 = 1, y0 = 0, y1 = 1;
  if (!points.empty()) {
    x0 = x1 = points[0].x;
    y0 = y1 = ty(points[0].y);
    for (const PlotPoint& p : points) {
      x0 = std::min(x0, p.x);
      x1 = std::max(x1, p.x);
      y0 = std::min(y0, ty(p.y));
      y1 = std::max(y1, ty(p.y));
    }
  }
  x0 = std::min(0.0, x0);
  const double xpad = (x1 - x0) * 0.08 + 1e-9, ypad = (y1 - y0) * 0.1 + (spec.log_y ? 0.3 : 1e-9);
  x1 += xpad;
  y0 -= ypad;
  y1 += ypad;
  auto px = [&](double x) { return left + static_cast<int>(std::lround((x - x0) / (x1 - x0) * pw)); };
  auto py = [&](double y) { return top + ph - static_cast<int>(std::lround((ty(y) - y0) / (y1 - y0) * ph)); };

  // Grid and tick labels. x: steps of 1, 2 or 5 times a power of ten;
  // y on a log axis: 1, 2 and 5 times each decade. Tick labels end left of the axis.
  constexpr int kTickScale = 2, kGlyphAdvance = 4;
  const double xstep = NiceStep(x1 - x0, 5);
  for (double xv = std::ceil(x0 / xstep) * xstep; xv <= x1 + 1e-9 * xstep; xv += xstep) {
    const int gx = px(xv);
    const std::string t = Short(std::fabs(xv) < 1e-9 * xstep ? 0.0 : xv);
    cv.Line(gx, top, gx, top + ph, kGrid);
    cv.Text(gx - static_cast<int>(t.size()) * kGlyphAdvance * kTickScale / 2, top + ph + 8, t, kTickScale, kInk);
  }
  auto y_tick = [&](double v) {
    const int gy = py(v);
    const std::string t = Short(v);
    cv.Line(left, gy, left + pw, gy, kGrid);
    cv.Text(left - 8 - static_cast<int>(t.size()) * kGlyphAdvance * kTickScale, gy - 5, t, kTickScale, kInk);
  };
  if (spec.log_y) {
    for (int d = static_cast<int>(std::floor(y0)); d <= static_cast<int>(std::ceil(y1)); ++d)
      for (double m : {1.0, 2.0, 5.0}) {
        const double v = m * std::pow(10.0, d);
        if (std::log10(v) >= y0 && std::log10(v) <= y1) y_tick(v);
      }
  } else {
    const double ystep = NiceStep(y1 - y0, 5);
    for (double yv = std::ceil(y0 / ystep) * ystep; yv <= y1 + 1e-9 * ystep; yv += ystep) y_tick(yv);
  }
  cv.Line(left, top, left, top + ph, kInk);
  cv.Line(left, top + ph, left + pw, top + ph, kInk);
  cv.Text(left, 12, spec.title, 3, kInk);
  cv.Text(left + pw / 2 - static_cast<int>(spec.x_label.size()) * kGlyphAdvance, spec.height - 36, spec.x_label, 2,
          kInk);
  cv.Text(6, top + ph / 2 + static_cast<int>(spec.y_label.size()) * kGlyphAdvance, spec.y_label, 2, kInk,
          /*vertical=*/true);

  // Series in order of first appearance, each with a colour and a legend entry.
  std::vector<std::string> series;
  for (const PlotPoint& p : points)
    if (!p.series.empty() && std::find(series.begin(), series.end(), p.series) == series.end())
      series.push_back(p.series);
  auto colour_of = [&](const PlotPoint& p) -> const uint8_t* {
    const size_t i = static_cast<size_t>(std::find(series.begin(), series.end(), p.series) - series.begin());
    return kSeriesColours[i % (sizeof kSeriesColours / sizeof kSeriesColours[0])];
  };

  // The frontier: highlighted points joined in order of x.
  std::vector<const PlotPoint*> front;
  for (const PlotPoint& p : points)
    if (p.highlight) front.push_back(&p);
  std::sort(front.begin(), front.end(), [](const PlotPoint* a, const PlotPoint* b) { return a->x < b->x; });
  for (size_t i = 1; i < front.size(); ++i)
    cv.Line(px(front[i - 1]->x), py(front[i - 1]->y), px(front[i]->x), py(front[i]->y), kFront);

  // Points: hollow, or filled with a red ring on the frontier. Labels
  // (scale 2) go right, left, above or below the point, whichever covers no
  // earlier label or legend; a label with no free place is left out.
  constexpr int kLabelScale = 2, kMarker = 4;
  std::vector<Rect> taken;
  const int legend_x = left + pw - 260;
  int legend_y = top + 6;
  for (const std::string& name : series) {
    const uint8_t* col = kSeriesColours[(&name - series.data()) % (sizeof kSeriesColours / sizeof kSeriesColours[0])];
    cv.Box(legend_x + 6, legend_y + 5, kMarker, true, col);
    const int w = cv.Text(legend_x + 18, legend_y, name, kLabelScale, kInk);
    taken.push_back({legend_x, legend_y - 2, legend_x + 18 + w, legend_y + 12});
    legend_y += 16;
  }
  if (!front.empty()) {
    cv.Line(legend_x, legend_y + 5, legend_x + 12, legend_y + 5, kFront);
    const int w = cv.Text(legend_x + 18, legend_y, "frontier", kLabelScale, kInk);
    taken.push_back({legend_x, legend_y - 2, legend_x + 18 + w, legend_y + 12});
  }
  for (const PlotPoint& p : points) {
    const int cx = px(p.x), cy = py(p.y);
    const uint8_t* col = series.empty() ? kPoint : colour_of(p);
    cv.Box(cx, cy, kMarker, p.highlight, col);
    if (p.highlight) cv.Box(cx, cy, kMarker + 2, false, kFront);
    taken.push_back({cx - kMarker - 2, cy - kMarker - 2, cx + kMarker + 3, cy + kMarker + 3});
  }
  for (const PlotPoint& p : points) {
    if (p.label.empty()) continue;
    const int cx = px(p.x), cy = py(p.y);
    const int w = static_cast<int>(p.label.size()) * kGlyphAdvance * kLabelScale, h = 5 * kLabelScale;
    const Rect places[] = {{cx + 10, cy - h / 2, cx + 10 + w, cy + h / 2 + 1},
                           {cx - 10 - w, cy - h / 2, cx - 10, cy + h / 2 + 1},
                           {cx - w / 2, cy - 10 - h, cx + w / 2, cy - 9},
                           {cx - w / 2, cy + 10, cx + w / 2, cy + 11 + h}};
    for (const Rect& r : places) {
      bool free = r.x0 >= left && r.x1 <= left + pw && r.y0 >= top && r.y1 <= top + ph;
      for (const Rect& t : taken) free = free && !r.Overlaps(t);
      if (!free) continue;
      cv.Text(r.x0, r.y0, p.label, kLabelScale, kInk);
      taken.push_back(r);
      break;
    }
  }
  return io::WritePng(path, cv.rgb.data(), spec.width, spec.height, 3, 8, static_cast<ptrdiff_t>(spec.width) * 3, error);
}

}  // namespace camsim::host
