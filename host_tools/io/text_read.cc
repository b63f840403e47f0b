#include "host_tools/io/text_read.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <string>

namespace camsim::io {

bool ReadTextFile(const std::string& path, std::string* text, std::string* error, size_t max_bytes) {
  const int fd = open(path.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) {
    *error = std::strerror(errno);
    return false;
  }
  struct stat st;
  bool ok = false;
  if (fstat(fd, &st) != 0) *error = std::strerror(errno);
  else if (S_ISDIR(st.st_mode)) *error = "is a directory, not a file";
  else ok = true;  // a regular file, or a pipe: --config <(...), /dev/stdin
  std::string bytes;
  char buf[65536];
  while (ok) {
    const ssize_t n = read(fd, buf, sizeof buf);
    if (n > 0) {
      if (bytes.size() + static_cast<size_t>(n) > max_bytes) {
        *error = max_bytes >= (size_t{1} << 20) ? "larger than " + std::to_string(max_bytes >> 20) + " MiB"
                                                : "larger than " + std::to_string(max_bytes) + " bytes";
        ok = false;
        break;
      }
      bytes.append(buf, static_cast<size_t>(n));
    } else if (n == 0) {
      break;
    } else if (errno != EINTR) {
      *error = std::string("read failed: ") + std::strerror(errno);
      ok = false;
    }
  }
  close(fd);
  if (ok) text->swap(bytes);
  return ok;
}

}  // namespace camsim::io
