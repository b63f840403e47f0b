#include "host_tools/defects_file.h"

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <sstream>

#include "host_tools/io/text_read.h"

namespace camsim::host {
namespace {

struct Field {
  std::string text;
  int column = 1;  // 1-based column of the field's first non-space character
};

std::vector<Field> SplitFields(const std::string& line) {
  std::vector<Field> fields;
  size_t start = 0;
  while (true) {
    const size_t comma = line.find(',', start);
    const size_t end = comma == std::string::npos ? line.size() : comma;
    size_t a = start, b = end;
    while (a < b && (line[a] == ' ' || line[a] == '\t' || line[a] == '\r')) ++a;
    while (b > a && (line[b - 1] == ' ' || line[b - 1] == '\t' || line[b - 1] == '\r')) --b;
    fields.push_back({line.substr(a, b - a), static_cast<int>(a) + 1});
    if (comma == std::string::npos) return fields;
    start = comma + 1;
  }
}

bool ParseInt(const std::string& s, long* v) {
  if (s.empty()) return false;
  errno = 0;
  char* end = nullptr;
  *v = std::strtol(s.c_str(), &end, 10);
  return errno == 0 && *end == '\0';
}

bool ParseDouble(const std::string& s, double* v) {
  if (s.empty()) return false;
  char* end = nullptr;
  *v = std::strtod(s.c_str(), &end);
  return *end == '\0' && std::isfinite(*v);
}

}  // namespace

bool LoadDefectsFile(const std::string& path, int width, int height, int adc_bits, std::vector<DefectPixel>* out,
                     std::string* error) {
  std::string text, why;
  if (!io::ReadTextFile(path, &text, &why)) {
    *error = path + ": cannot read the defects file: " + why;
    return false;
  }
  std::istringstream file(text);
  struct Entry {
    DefectPixel d;
    int line;
  };
  std::vector<Entry> entries;
  std::string line;
  int number = 0;
  // The core refuses adc_bits outside 8..16 after this file is read; until
  // then an out-of-range value must not reach the shift (undefined beyond 62).
  const long max_dn = adc_bits >= 1 && adc_bits <= 30 ? (1L << adc_bits) - 1 : (1L << 30) - 1;
  while (std::getline(file, line)) {
    ++number;
    const size_t hash = line.find('#');
    if (hash != std::string::npos) line.resize(hash);
    if (line.find_first_not_of(" \t\r") == std::string::npos) continue;
    const std::vector<Field> f = SplitFields(line);
    const auto fail = [&](int column, const std::string& what) {
      *error = path + ":" + std::to_string(number) + ":" + std::to_string(column) + ": " + what;
      return false;
    };
    if (f.size() < 3 || f.size() > 4) return fail(1, "expected x,y,kind[,value] (" + std::to_string(f.size()) + " fields)");
    long x = 0, y = 0;
    if (!ParseInt(f[0].text, &x)) return fail(f[0].column, "x '" + f[0].text + "' is not an integer");
    if (!ParseInt(f[1].text, &y)) return fail(f[1].column, "y '" + f[1].text + "' is not an integer");
    if (x < 0 || x >= width)
      return fail(f[0].column, "x " + std::to_string(x) + " is outside the frame (0 .. " + std::to_string(width - 1) + ")");
    if (y < 0 || y >= height)
      return fail(f[1].column,
                  "y " + std::to_string(y) + " is outside the frame (0 .. " + std::to_string(height - 1) + ")");
    DefectPixel d;
    d.x = static_cast<int32_t>(x);
    d.y = static_cast<int32_t>(y);
    if (f[2].text == "hot") d.kind = DefectKind::kHot;
    else if (f[2].text == "dead") d.kind = DefectKind::kDead;
    else if (f[2].text == "stuck") d.kind = DefectKind::kStuck;
    else return fail(f[2].column, "unknown kind '" + f[2].text + "' (hot, dead or stuck)");
    if (f.size() == 4) {
      if (d.kind == DefectKind::kDead) return fail(f[3].column, "a dead pixel takes no value");
      if (d.kind == DefectKind::kStuck) {
        long v = 0;
        if (!ParseInt(f[3].text, &v) || v < 0 || v > max_dn)
          return fail(f[3].column, "stuck value '" + f[3].text + "' must be an integer DN in [0, " +
                                       std::to_string(max_dn) + "]");
        d.value = static_cast<double>(v);
      } else {
        double v = 0;
        if (!ParseDouble(f[3].text, &v) || v < 0 || v > 1e7)
          return fail(f[3].column, "hot value '" + f[3].text + "' must be a dark current in [0, 1e7] e-/s");
        d.value = v;
      }
    }
    entries.push_back({d, number});
  }
  if (entries.size() > static_cast<size_t>(kMaxListedDefects)) {
    *error = path + ": more than " + std::to_string(kMaxListedDefects) + " defects";
    return false;
  }
  std::stable_sort(entries.begin(), entries.end(), [](const Entry& a, const Entry& b) {
    return a.d.y != b.d.y ? a.d.y < b.d.y : a.d.x < b.d.x;
  });
  out->clear();
  for (size_t i = 0; i < entries.size(); ++i) {
    if (i > 0 && entries[i].d.x == entries[i - 1].d.x && entries[i].d.y == entries[i - 1].d.y) {
      *error = path + ":" + std::to_string(entries[i].line) + ":1: duplicate pixel (" + std::to_string(entries[i].d.x) +
               ", " + std::to_string(entries[i].d.y) + "), first listed on line " + std::to_string(entries[i - 1].line);
      return false;
    }
    out->push_back(entries[i].d);
  }
  return true;
}

}  // namespace camsim::host
