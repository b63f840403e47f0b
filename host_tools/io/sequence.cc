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
  auto name = [&](int i) {
    std::string n = std::to_string(i);
    if (n.size() < width) n.insert(0, width - n.size(), '0');
    return prefix + n + suffix;
  };
  int i = IsFile(name(0)) ? 0 : 1;
  if (!IsFile(name(i))) {
    *error = "no files match pattern '" + arg + "' (tried '" + name(0) + "' and '" + name(1) + "')";
    return false;
  }
  for (; IsFile(name(i)); ++i) files->push_back(name(i));
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
