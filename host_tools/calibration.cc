#include "host_tools/calibration.h"

#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <sstream>
#include <vector>

#include "host_tools/io/text_read.h"

namespace camsim::host {
namespace {

// The text of top-level key `key`'s value: everything after "key:" up to the
// next line that starts (unindented) with another key. Empty if absent.
bool FindBlock(const std::string& text, const std::string& key, std::string* block, int* line_no) {
  std::istringstream in(text);
  std::string line;
  bool inside = false;
  int n = 0;
  block->clear();
  while (std::getline(in, line)) {
    ++n;
    if (!line.empty() && line.back() == '\r') line.pop_back();
    const bool top = !line.empty() && line[0] != ' ' && line[0] != '\t' && line[0] != '#' && line[0] != '-';
    if (inside && top) break;
    if (!inside && top && line.compare(0, key.size() + 1, key + ":") == 0) {
      inside = true;
      *line_no = n;
      *block = line.substr(key.size() + 1) + "\n";
      continue;
    }
    if (inside) *block += line + "\n";
  }
  return inside;
}

std::string Trim(const std::string& s) {
  size_t a = s.find_first_not_of(" \t\r\n\"'"), b = s.find_last_not_of(" \t\r\n\"'");
  return a == std::string::npos ? "" : s.substr(a, b - a + 1);
}

// Numbers of "data: [ a, b, ... ]" (possibly over several lines) in a block.
bool ParseData(const std::string& block, std::vector<double>* v, std::string* why) {
  const size_t d = block.find("data:");
  if (d == std::string::npos) {
    *why = "has no 'data: [...]'";
    return false;
  }
  const size_t open = block.find('[', d), close = block.find(']', d);
  if (open == std::string::npos || close == std::string::npos || close < open) {
    *why = "has a 'data' list without [ ]";
    return false;
  }
  std::string list = block.substr(open + 1, close - open - 1);
  for (char& ch : list)
    if (ch == ',' || ch == '\n' || ch == '\r' || ch == '\t') ch = ' ';
  std::istringstream in(list);
  std::string tok;
  v->clear();
  while (in >> tok) {
    char* end = nullptr;
    const double x = std::strtod(tok.c_str(), &end);
    if (end == tok.c_str() || *end != '\0' || !std::isfinite(x)) {
      *why = "has a value that is not a finite number: '" + tok + "'";
      return false;
    }
    v->push_back(x);
  }
  return true;
}

// A scalar "key: value" at top level (image_width, distortion_model ...).
bool FindScalar(const std::string& text, const std::string& key, std::string* value, int* line_out = nullptr) {
  std::string block;
  int line = 0;
  if (!FindBlock(text, key, &block, &line)) return false;
  if (line_out != nullptr) *line_out = line;
  *value = Trim(block.substr(0, block.find('\n')));
  return true;
}

}  // namespace

bool ParseCalibration(const std::string& text, const std::string& source, bool fisheye_hint, Calibration* out,
                      std::string* error) {
  *out = Calibration();
  const auto fail = [&](int line, const std::string& what) {
    std::string where = source;
    if (line > 0) {
      where += ':';
      where += std::to_string(line);
    }
    where += ": ";
    where += what;
    *error = where;
    return false;
  };
  std::string block, why;
  int line = 0;
  if (!FindBlock(text, "camera_matrix", &block, &line))
    return fail(0, "no camera_matrix (expected an OpenCV FileStorage YAML or a ROS camera_info YAML)");
  std::vector<double> k;
  if (!ParseData(block, &k, &why)) return fail(line, "camera_matrix " + why);
  if (k.size() != 9) return fail(line, "camera_matrix must have 9 values (3x3), has " + std::to_string(k.size()));
  if (k[1] != 0.0) return fail(line, "camera_matrix has a skew term (row 0, column 1); camsim does not model skew");
  if (k[3] != 0.0 || k[6] != 0.0 || k[7] != 0.0 || k[8] != 1.0)
    return fail(line, "camera_matrix must be [fx 0 cx; 0 fy cy; 0 0 1]");
  LensModel& m = out->lens;
  m.fx = k[0];
  m.cx = k[2];
  m.fy = k[4];
  m.cy = k[5];

  std::vector<double> d;
  int dline = 0;
  if (FindBlock(text, "distortion_coefficients", &block, &dline)) {
    if (!ParseData(block, &d, &why)) return fail(dline, "distortion_coefficients " + why);
  } else if (FindBlock(text, "D", &block, &dline)) {  // ROS camera_info message style
    if (!ParseData(block, &d, &why)) return fail(dline, "D " + why);
  }
  std::string model_name;
  const bool ros = FindScalar(text, "distortion_model", &model_name);
  bool fisheye = false;
  if (ros) {
    if (model_name == "equidistant" || model_name == "fisheye") fisheye = true;
    else if (model_name != "plumb_bob" && model_name != "rational_polynomial")
      return fail(0, "distortion_model '" + model_name + "' is not supported (plumb_bob, rational_polynomial, equidistant)");
  } else {
    fisheye = fisheye_hint;
  }
  if (fisheye) {
    if (d.size() != 4) return fail(dline, "the equidistant (fisheye) model needs 4 coefficients k1..k4, found " +
                                              std::to_string(d.size()));
    m.model = DistortionModel::kFisheye;
    for (int i = 0; i < 4; ++i) m.k[i] = d[i];
  } else {
    const size_t n = d.size();
    if (n != 0 && n != 4 && n != 5 && n != 8 && n != 12 && n != 14)
      return fail(dline, "expected 4, 5, 8, 12 or 14 distortion coefficients (OpenCV order k1 k2 p1 p2 k3 k4 k5 k6 "
                         "s1..s4 tauX tauY), found " + std::to_string(n));
    for (size_t i = 8; i < n; ++i)
      if (d[i] != 0.0) return fail(dline, "non-zero thin-prism or tilt coefficients (s1..s4, tauX, tauY) are not supported");
    m.model = DistortionModel::kBrown;
    const double get[8] = {n > 0 ? d[0] : 0.0, n > 1 ? d[1] : 0.0, n > 2 ? d[2] : 0.0, n > 3 ? d[3] : 0.0,
                           n > 4 ? d[4] : 0.0, n > 5 ? d[5] : 0.0, n > 6 ? d[6] : 0.0, n > 7 ? d[7] : 0.0};
    m.k[0] = get[0];
    m.k[1] = get[1];
    m.p1 = get[2];
    m.p2 = get[3];
    m.k[2] = get[4];
    m.k[3] = get[5];
    m.k[4] = get[6];
    m.k[5] = get[7];
  }
  std::string w, h;
  int w_line = 0, h_line = 0;
  const bool has_w = FindScalar(text, "image_width", &w, &w_line), has_h = FindScalar(text, "image_height", &h, &h_line);
  if (has_w != has_h)
    return fail(has_w ? w_line : h_line,
                has_w ? "image_width is given without image_height" : "image_height is given without image_width");
  if (has_w) {
    // Whole numbers of pixels, nothing after them (no silent wrap or "32px").
    constexpr long kMaxSide = 1 << 16;
    const auto side = [](const std::string& v, int* px) {
      char* end = nullptr;
      errno = 0;
      const long n = std::strtol(v.c_str(), &end, 10);
      if (errno != 0 || end == v.c_str() || *end != '\0' || n <= 0 || n > kMaxSide) return false;
      *px = static_cast<int>(n);
      return true;
    };
    if (!side(w, &out->width)) return fail(w_line, "image_width '" + w + "' must be a whole number of pixels, 1 to 65536");
    if (!side(h, &out->height)) return fail(h_line, "image_height '" + h + "' must be a whole number of pixels, 1 to 65536");
  }
  return true;
}

bool LoadCalibration(const std::string& path, bool fisheye_hint, Calibration* out, std::string* error) {
  std::string text, why;
  if (!io::ReadTextFile(path, &text, &why)) {
    *error = path + ": cannot read the calibration file: " + why;
    return false;
  }
  return ParseCalibration(text, path, fisheye_hint, out, error);
}

bool LoadDisplacementMesh(const std::string& path, std::vector<float>* dxdy, int* cols, int* rows, double* step,
                          std::string* error) {
  std::string file, why;
  if (!io::ReadTextFile(path, &file, &why)) {
    *error = path + ": cannot read the displacement mesh: " + why;
    return false;
  }
  std::istringstream in(file);
  std::string text, line;
  while (std::getline(in, line)) text += line.substr(0, line.find('#')) + "\n";
  std::istringstream s(text);
  std::string word;
  *cols = *rows = 0;
  *step = 0.0;
  if (!(s >> word) || word != "step" || !(s >> *step) || !(s >> word) || word != "size" || !(s >> *cols >> *rows)) {
    *error = path + ": expected 'step S' then 'size COLS ROWS' before the displacements";
    return false;
  }
  if (*cols < 2 || *rows < 2 || *cols > 4096 || *rows > 4096 || !(*step >= 1.0)) {
    *error = path + ": size must be 2..4096 nodes each way and step >= 1 pixel";
    return false;
  }
  dxdy->assign(static_cast<size_t>(*cols) * *rows * 2, 0.0f);
  for (size_t i = 0; i < dxdy->size(); ++i) {
    double v = 0.0;
    if (!(s >> v) || !std::isfinite(v)) {
      std::ostringstream e;
      e << path << ": displacement of node (" << i / 2 % *cols << ", " << i / 2 / *cols
        << ") is missing or not a finite number";
      *error = e.str();
      return false;
    }
    (*dxdy)[i] = static_cast<float>(v);
  }
  if (s >> word) {
    *error = path + ": more values than size COLS ROWS says";
    return false;
  }
  return true;
}

bool FitCalibration(const Calibration& cal, int width, int height, LensModel* lens, std::string* error) {
  *lens = cal.lens;
  if (cal.width == 0 || (cal.width == width && cal.height == height)) return true;
  if (static_cast<int64_t>(cal.width) * height != static_cast<int64_t>(width) * cal.height) {
    *error = "the calibration was made at " + std::to_string(cal.width) + "x" + std::to_string(cal.height) +
             ", the sensor is " + std::to_string(width) + "x" + std::to_string(height) +
             ": a different aspect ratio (a crop) cannot be adapted; calibrate at the sensor's size";
    return false;
  }
  const double s = static_cast<double>(width) / cal.width;
  lens->fx = cal.lens.fx * s;
  lens->fy = cal.lens.fy * s;
  lens->cx = (cal.lens.cx + 0.5) * s - 0.5;
  lens->cy = (cal.lens.cy + 0.5) * s - 0.5;
  return true;
}

}  // namespace camsim::host
