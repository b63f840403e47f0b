#include "host_tools/calibration.h"

#include <cstdio>
#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <map>
#include <sstream>
#include <utility>
#include <vector>

#include "core/lens/distortion.h"
#include "host_tools/io/text_read.h"

namespace camsim::host {
namespace {

// True when a scalar starts after `so_far` (only there does a quote open a
// quoted string; "bob's" is plain): at a line's start or after ':', '[', '{',
// ',' or '-' and blanks.
bool ScalarStarts(const std::string& so_far) {
  const size_t last = so_far.find_last_not_of(" \t");
  if (last == std::string::npos) return true;
  const char c = so_far[last];
  return c == '\n' || c == ':' || c == '[' || c == '{' || c == ',' || c == '-';
}

// The text with YAML comments blanked: from a '#' that starts a line or
// follows a space or tab, outside quotes, to the end of its line. Line
// numbers stay.
std::string StripComments(const std::string& text) {
  std::string out;
  out.reserve(text.size());
  char quote = 0;  // the open quote, or 0
  bool comment = false;
  for (size_t i = 0; i < text.size(); ++i) {
    const char ch = text[i];
    if (ch == '\n') {
      quote = 0;  // camsim's keys are single-line scalars
      comment = false;
      out += ch;
      continue;
    }
    if (comment) continue;
    if (quote != 0) {
      if (ch == quote) quote = 0;
    } else if ((ch == '"' || ch == '\'') && ScalarStarts(out)) {
      quote = ch;
    } else if (ch == '#' && (i == 0 || text[i - 1] == ' ' || text[i - 1] == '\t' || text[i - 1] == '\n')) {
      comment = true;
      continue;
    }
    out += ch;
  }
  return out;
}

// A line that starts a top-level key ("key: ..."), not a directive (%YAML),
// document marker (---), list item, comment or indented line.
bool TopLevel(const std::string& line) {
  return !line.empty() && line[0] != ' ' && line[0] != '\t' && line[0] != '#' && line[0] != '-' && line[0] != '%' &&
         line[0] != '.';
}

// The first top-level key that appears twice (a YAML mapping's keys are
// unique; reading only the first would silently drop the second), or the
// first line that starts with ':' (*key empty: no key, so no YAML mapping).
bool FindRepeatedKey(const std::string& text, std::string* key, int* line_no) {
  std::istringstream in(text);
  std::string line;
  std::map<std::string, int> seen;
  int n = 0;
  while (std::getline(in, line)) {
    ++n;
    if (!TopLevel(line)) continue;
    const size_t colon = line.find(':');
    if (colon == std::string::npos) continue;
    const std::string k = line.substr(0, colon);
    if (k.empty() || !seen.emplace(k, n).second) {
      *key = k;
      *line_no = n;
      return true;
    }
  }
  return false;
}

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
    const bool top = TopLevel(line);
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

// Where the value of field `name` ("rows", "data" ...) of a matrix block
// starts: just after "name:" at the start of a line or after '{' or ','
// (block or flow style). npos if absent; false if it is given twice.
bool FindField(const std::string& block, const std::string& name, size_t* value, std::string* why) {
  *value = std::string::npos;
  const std::string tag = name + ":";
  for (size_t at = block.find(tag); at != std::string::npos; at = block.find(tag, at + 1)) {
    const size_t before = block.find_last_not_of(" \t", at == 0 ? std::string::npos : at - 1);
    const bool starts = at == 0 || before == std::string::npos || block[before] == '\n' || block[before] == '{' ||
                        block[before] == ',';
    if (!starts) continue;
    if (*value != std::string::npos) {
      *why = "has '" + name + ":' twice";
      return false;
    }
    *value = at + tag.size();
  }
  return true;
}

// A matrix block: "data: [ a, b, ... ]" (possibly over several lines) and, if
// given, "rows: R" and "cols: C" with R * C values.
struct Matrix {
  std::vector<double> data;
  int rows = -1, cols = -1;  // -1: not given
};

bool ParseMatrix(const std::string& block, Matrix* m, std::string* why) {
  *m = Matrix();
  size_t d = 0, r = 0, c = 0;
  if (!FindField(block, "data", &d, why) || !FindField(block, "rows", &r, why) || !FindField(block, "cols", &c, why))
    return false;
  if (d == std::string::npos) {
    *why = "has no 'data: [...]'";
    return false;
  }
  const size_t open = block.find_first_not_of(" \t\r\n", d);
  const size_t close = open == std::string::npos ? open : block.find(']', open);
  if (open == std::string::npos || block[open] != '[' || close == std::string::npos) {
    *why = "has a 'data' list without [ ]";
    return false;
  }
  std::string list = block.substr(open + 1, close - open - 1);
  for (char& ch : list)
    if (ch == ',' || ch == '\n' || ch == '\r' || ch == '\t') ch = ' ';
  std::istringstream in(list);
  std::string tok;
  while (in >> tok) {
    char* end = nullptr;
    const double x = std::strtod(tok.c_str(), &end);
    if (end == tok.c_str() || *end != '\0' || !std::isfinite(x)) {
      *why = "has a value that is not a finite number: '" + tok + "'";
      return false;
    }
    m->data.push_back(x);
  }
  if ((r == std::string::npos) != (c == std::string::npos)) {
    *why = r == std::string::npos ? "has 'cols:' without 'rows:'" : "has 'rows:' without 'cols:'";
    return false;
  }
  if (r == std::string::npos) return true;
  // A whole number up to the end of its line, ',' or '}'.
  const auto count = [&](size_t at, const char* name, int* out) {
    const std::string v = Trim(block.substr(at, block.find_first_of(",}\n", at) - at));
    char* end = nullptr;
    errno = 0;
    const long n = std::strtol(v.c_str(), &end, 10);
    if (errno != 0 || end == v.c_str() || *end != '\0' || n < 0 || n > 1000) {
      *why = std::string("has ") + name + " '" + v + "', not a whole number 0 to 1000";
      return false;
    }
    *out = static_cast<int>(n);
    return true;
  };
  if (!count(r, "rows", &m->rows) || !count(c, "cols", &m->cols)) return false;
  if (static_cast<size_t>(m->rows) * m->cols != m->data.size()) {
    *why = "says rows: " + std::to_string(m->rows) + ", cols: " + std::to_string(m->cols) + " (" +
           std::to_string(m->rows * m->cols) + " values) but its data has " + std::to_string(m->data.size());
    return false;
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

bool ParseCalibration(const std::string& file_text, const std::string& source, bool fisheye_hint, Calibration* out,
                      std::string* error) {
  *out = Calibration();
  out->source = source;
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
  // YAML is text without control characters (but tab, line feed and carriage
  // return): anything else (an EXR or PNG given by mistake) is not a
  // calibration file, said as such rather than as a parse error within it.
  int text_line = 1;
  for (const char ch : file_text) {
    const unsigned char u = static_cast<unsigned char>(ch);
    if (u == '\n') ++text_line;
    if ((u < 0x20 && u != '\t' && u != '\n' && u != '\r') || u == 0x7f) {
      char byte[8];
      std::snprintf(byte, sizeof byte, "0x%02x", u);
      return fail(text_line, std::string("not a calibration file: binary data (byte ") + byte +
                                 "), not OpenCV or ROS calibration YAML text");
    }
  }
  const std::string text = StripComments(file_text);
  std::string block, why, repeated;
  int line = 0;
  if (FindRepeatedKey(text, &repeated, &line))
    return fail(line, repeated.empty() ? "not a calibration file: a line starts with ':' (no key), not YAML"
                                       : repeated + " is given twice");
  if (!FindBlock(text, "camera_matrix", &block, &line)) {
    std::string what = "no camera_matrix (expected an OpenCV FileStorage YAML or a ROS camera_info YAML)";
    std::string unused;
    int k_line = 0;
    if (FindBlock(text, "K", &unused, &k_line))
      what += "; a camera_info message dump (K:, D:) is not read: write it with camera_calibration_parsers";
    return fail(0, what);
  }
  out->matrix_line = line;
  Matrix k;
  if (!ParseMatrix(block, &k, &why)) return fail(line, "camera_matrix " + why);
  if (k.data.size() != 9)
    return fail(line, "camera_matrix must have 9 values (3x3), has " + std::to_string(k.data.size()));
  if (k.rows != -1 && (k.rows != 3 || k.cols != 3))
    return fail(line, "camera_matrix must be rows: 3, cols: 3, is " + std::to_string(k.rows) + "x" +
                          std::to_string(k.cols));
  const std::vector<double>& a = k.data;
  if (a[1] != 0.0) return fail(line, "camera_matrix has a skew term (row 0, column 1); camsim does not model skew");
  if (a[3] != 0.0 || a[6] != 0.0 || a[7] != 0.0 || a[8] != 1.0)
    return fail(line, "camera_matrix must be [fx 0 cx; 0 fy cy; 0 0 1]");
  for (const auto& [value, key] : {std::pair{a[0], "fx"}, std::pair{a[4], "fy"}})
    if (!(value >= kMinFocalPx && value <= kMaxFocalPx)) {
      std::ostringstream e;
      e << "camera_matrix " << key << " = " << value << " must be a focal length of 1 to 1e6 pixels";
      return fail(line, e.str());
    }
  LensModel& m = out->lens;
  m.fx = a[0];
  m.cx = a[2];
  m.fy = a[4];
  m.cy = a[5];

  // Required: a misspelt key would otherwise give a lens without distortion.
  int dline = 0;
  if (!FindBlock(text, "distortion_coefficients", &block, &dline))
    return fail(0, "no distortion_coefficients (required; a lens without distortion lists zeros, "
                   "data: [0, 0, 0, 0, 0])");
  Matrix dm;
  if (!ParseMatrix(block, &dm, &why)) return fail(dline, "distortion_coefficients " + why);
  if (dm.rows != -1 && dm.rows != 1 && dm.cols != 1)
    return fail(dline, "distortion_coefficients must be one row or one column, is " + std::to_string(dm.rows) + "x" +
                           std::to_string(dm.cols));
  const std::vector<double>& d = dm.data;
  std::string model_name;
  int model_line = 0;
  out->names_model = FindScalar(text, "distortion_model", &model_name, &model_line);
  bool fisheye = false;
  if (out->names_model) {
    out->model_name = model_name;
    if (model_name == "equidistant" || model_name == "fisheye") fisheye = true;
    else if (model_name != "plumb_bob" && model_name != "rational_polynomial")
      return fail(model_line, "distortion_model '" + model_name +
                                  "' is not supported (plumb_bob, rational_polynomial, equidistant)");
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
    if (n != 4 && n != 5 && n != 8 && n != 12 && n != 14)
      return fail(dline, "expected 4, 5, 8, 12 or 14 distortion coefficients (OpenCV order k1 k2 p1 p2 k3 k4 k5 k6 "
                         "s1..s4 tauX tauY), found " + std::to_string(n));
    for (size_t i = 8; i < n; ++i)
      if (d[i] != 0.0) return fail(dline, "non-zero thin-prism or tilt coefficients (s1..s4, tauX, tauY) are not supported");
    m.model = DistortionModel::kBrown;
    m.k[0] = d[0];
    m.k[1] = d[1];
    m.p1 = d[2];
    m.p2 = d[3];
    m.k[2] = n > 4 ? d[4] : 0.0;
    m.k[3] = n > 5 ? d[5] : 0.0;
    m.k[4] = n > 6 ? d[6] : 0.0;
    m.k[5] = n > 7 ? d[7] : 0.0;
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
  const std::string where = cal.source + ":" + std::to_string(cal.matrix_line) + ": ";
  const bool scaled = cal.width != 0 && (cal.width != width || cal.height != height);
  if (scaled) {
    if (static_cast<int64_t>(cal.width) * height != static_cast<int64_t>(width) * cal.height) {
      *error = cal.source + ": the calibration was made at " + std::to_string(cal.width) + "x" +
               std::to_string(cal.height) + ", the sensor is " + std::to_string(width) + "x" + std::to_string(height) +
               ": a different aspect ratio (a crop) cannot be adapted; calibrate at the sensor's size";
      return false;
    }
    const double s = static_cast<double>(width) / cal.width;
    lens->fx = cal.lens.fx * s;
    lens->fy = cal.lens.fy * s;
    lens->cx = (cal.lens.cx + 0.5) * s - 0.5;
    lens->cy = (cal.lens.cy + 0.5) * s - 0.5;
  }
  const std::string at = scaled ? " (scaled from " + std::to_string(cal.width) + "x" + std::to_string(cal.height) + ")"
                                : "";
  std::ostringstream e;
  if (!(lens->fx >= kMinFocalPx && lens->fy >= kMinFocalPx)) {
    e << where << "camera_matrix fx, fy = " << lens->fx << ", " << lens->fy << at << " at the " << width << "x"
      << height << " sensor: a focal length must be at least 1 pixel";
    *error = e.str();
    return false;
  }
  // The principal point must be on a pixel centre of the frame or between
  // them (no tolerance: motion blur reads a negative one as "the centre").
  if (!(lens->cx >= 0.0 && lens->cx <= width - 1 && lens->cy >= 0.0 && lens->cy <= height - 1)) {
    e << where << "camera_matrix principal point (cx, cy) = (" << lens->cx << ", " << lens->cy << ")" << at
      << " is outside the " << width << "x" << height << " sensor's pixels [0, " << width - 1 << "] x [0, "
      << height - 1 << "]";
    *error = e.str();
    return false;
  }
  return true;
}

}  // namespace camsim::host
