// A scatter plot drawn into an RGB8 image and written as PNG: what the reports
// (camsim tradeoff) draw without a plotting library. Text uses a 3x5 pixel
// font (upper case, digits, a few signs) scaled up.
#pragma once

#include <string>
#include <vector>

namespace camsim::host {

struct PlotPoint {
  double x = 0, y = 0;
  std::string series;  // points of one series share a colour, named in the legend
  std::string label;   // drawn beside the point unless it would cover another label
  bool highlight = false;  // drawn filled and joined by the frontier line
};

struct PlotSpec {
  std::string title, x_label, y_label;
  bool log_y = false;  // log10 axis (values <= 0 are drawn at the bottom)
  int width = 960, height = 640;
};

// Renders and writes the plot; false with *error when the file cannot be written.
bool WriteScatterPng(const std::string& path, const PlotSpec& spec, const std::vector<PlotPoint>& points,
                     std::string* error);

}  // namespace camsim::host
