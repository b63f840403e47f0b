#include "host_tools/io/sequence.h"

#include <algorithm>
#include <cctype>
#include <filesystem>
#include <regex>

namespace camsim::io {
namespace {

namespace fs = std::filesystem;

bool IsFile(const std::string& path) {
  std::error_code ec;
  return fs::is_regular_file(path, ec);
}

bool HasExrExtension(const fs::path& p) {
  std::string ext = p.extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return ext == ".exr";
}

bool ExpandDirectory(const std::string& dir, std::vector<std::string>* files, std::string* error) {
  std::vector<std::string> found;
  std::error_code ec;
  for (fs::directory_iterator it(dir, ec), end; !ec && it != end; it.increment(ec)) {
    if (it->is_regular_file(ec) && HasExrExtension(it->path())) found.push_back(it->path().string());
  }
  if (ec) {
    *error = "cannot list directory '" + dir + "': " + ec.message();
    return false;
  }
  if (found.empty()) {
    *error = "directory '" + dir + "' contains no .exr files";
    return false;
  }
  std::sort(found.begin(), found.end());
  files->insert(files->end(), found.begin(), found.end());
  return true;
}

// Index i as a pattern writes it: zero-padded to `width` digits.
std::string Padded(int i, size_t width) {
  std::string n = std::to_string(i);
  if (n.size() < width) n.insert(0, width - n.size(), '0');
  return n;
}

// The lowest index above `missing` whose file exists for prefix + index +
// suffix (index zero-padded to width), or -1. Lists the prefix's directory
// when the suffix names no directory, else tries the next kLookAhead indices.
int LaterIndex(const std::string& prefix, const std::string& suffix, size_t width, int missing) {
  constexpr int kLookAhead = 1000;
  if (suffix.find('/') != std::string::npos) {
    for (int k = missing + 1; k <= missing + kLookAhead; ++k)
      if (IsFile(prefix + Padded(k, width) + suffix)) return k;
    return -1;
  }
  const size_t slash = prefix.rfind('/');
  const std::string dir = slash == std::string::npos ? "." : prefix.substr(0, slash + 1);
  const std::string stem = slash == std::string::npos ? prefix : prefix.substr(slash + 1);
  int best = -1;
  std::error_code ec;
  for (fs::directory_iterator it(dir, ec), end; !ec && it != end; it.increment(ec)) {
    const std::string f = it->path().filename().string();
    if (f.size() <= stem.size() + suffix.size() || f.compare(0, stem.size(), stem) != 0 ||
        f.compare(f.size() - suffix.size(), suffix.size(), suffix) != 0)
      continue;
    const std::string digits = f.substr(stem.size(), f.size() - stem.size() - suffix.size());
    if (!std::all_of(digits.begin(), digits.end(), [](char c) { return c >= '0' && c <= '9'; })) continue;
    // Leading zeros (a %010d pattern) do not count towards int's 9 safe digits.
    const size_t significant = std::min(digits.find_first_not_of('0'), digits.size());
    if (digits.size() - significant > 9) continue;
    const int k = significant == digits.size() ? 0 : std::stoi(digits.substr(significant));
    if (Padded(k, width) != digits || k <= missing || !IsFile(it->path().string())) continue;  // not a name the pattern makes
    if (best < 0 || k < best) best = k;
  }
  return best;
}

bool ExpandPattern(const std::string& arg, std::vector<std::string>* files, std::string* error) {
  static const std::regex kIndex("%(0([0-9]{1,2}))?d");
  std::smatch m;
  if (!std::regex_search(arg, m, kIndex)) {
    *error = "input '" + arg + "' does not exist";
    return false;
  }
  const std::string prefix = m.prefix(), suffix = m.suffix();
  if (std::regex_search(suffix, kIndex)) {
    *error = "input pattern '" + arg + "' has more than one %d";
    return false;
  }
  const size_t width = m[2].matched ? std::stoul(m[2].str()) : 0;
  auto name = [&](int i) { return prefix + Padded(i, width) + suffix; };
  // The first index: 0, else 1, else the lowest present (a sequence from 1001).
  int i = IsFile(name(0)) ? 0 : 1;
  if (!IsFile(name(i))) i = LaterIndex(prefix, suffix, width, 1);
  if (i < 0) {
    *error = "no files match pattern '" + arg + "' (tried '" + name(0) + "', '" + name(1) + "' and later indices)";
    return false;
  }
  for (; IsFile(name(i)); ++i) files->push_back(name(i));
  // A frame after the first missing index means a gap (a failed render, a
  // file not yet copied): an error, not a sequence that silently ends early.
  const int later = LaterIndex(prefix, suffix, width, i);
  if (later > i) {
    *error = "input pattern '" + arg + "' has a gap: '" + name(i) + "' is missing but '" + name(later) +
             "' exists (list the frames to run them anyway)";
    return false;
  }
  return true;
}

}  // namespace

bool ExpandInputs(const std::vector<std::string>& args, std::vector<std::string>* files,
                  std::string* error) {
  if (args.empty()) {
    *error = "no inputs given";
    return false;
  }
  try {
    std::vector<std::string> out;
    for (const std::string& arg : args) {
      std::error_code ec;
      if (IsFile(arg)) {
        out.push_back(arg);
      } else if (fs::is_directory(arg, ec)) {
        if (!ExpandDirectory(arg, &out, error)) return false;
      } else if (!ExpandPattern(arg, &out, error)) {
        return false;
      }
    }
    *files = std::move(out);
    return true;
  } catch (const std::exception& e) {
    *error = std::string("cannot expand inputs: ") + e.what();
  }
  return false;
}

}  // namespace camsim::io
