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

  // Grid and tick labels: 5 divisions per axis (decades on a log axis).
  for (int i = 0; i <= 5; ++i) {
    const double xv = x0 + (x1 - x0) * i / 5;
    const int gx = px(xv);
    cv.Line(gx, top, gx, top + ph, kGrid);
    cv.Text(gx - 12, top + ph + 8, Short(xv), 2, kInk);
  }
  if (spec.log_y) {  // ticks at 1, 2 and 5 times each decade
    for (int d = static_cast<int>(std::floor(y0)); d <= static_cast<int>(std::ceil(y1)); ++d)
      for (double m : {1.0, 2.0, 5.0}) {
        const double v = m * std::pow(10.0, d);
        if (std::log10(v) < y0 || std::log10(v) > y1) continue;
        const int gy = py(v);
        cv.Line(left, gy, left + pw, gy, kGrid);
        cv.Text(8, gy - 5, Short(v), 2, kInk);
      }
  } else {
    for (int i = 0; i <= 5; ++i) {
      const double yv = y0 + (y1 - y0) * i / 5;
      const int gy = py(yv);
      cv.Line(left, gy, left + pw, gy, kGrid);
      cv.Text(8, gy - 5, Short(yv), 2, kInk);
    }
  }
  cv.Line(left, top, left, top + ph, kInk);
  cv.Line(left, top + ph, left + pw, top + ph, kInk);
  cv.Text(left, 12, spec.title, 3, kInk);
  cv.Text(left + pw / 2 - 80, spec.height - 36, spec.x_label, 2, kInk);
  cv.Text(20, top + ph - 20, spec.y_label, 2, kInk, /*vertical=*/true);

  // The frontier: highlighted points joined in order of x.
  std::vector<const PlotPoint*> front;
  for (const PlotPoint& p : points)
    if (p.highlight) front.push_back(&p);
  std::sort(front.begin(), front.end(), [](const PlotPoint* a, const PlotPoint* b) { return a->x < b->x; });
  for (size_t i = 1; i < front.size(); ++i)
    cv.Line(px(front[i - 1]->x), py(front[i - 1]->y), px(front[i]->x), py(front[i]->y), kFront);
  for (const PlotPoint& p : points) {
    cv.Box(px(p.x), py(p.y), 4, p.highlight, p.highlight ? kFront : kPoint);
    if (!p.label.empty()) cv.Text(px(p.x) + 8, py(p.y) - 4, p.label, 1, kInk);
  }
  return io::WritePng(path, cv.rgb.data(), spec.width, spec.height, 3, 8, static_cast<ptrdiff_t>(spec.width) * 3, error);
}

}  // namespace camsim::host
