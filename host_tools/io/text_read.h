// Reading a whole text file (configurations, lists). Host-side only.
#pragma once

#include <cstddef>
#include <string>

namespace camsim::io {

// Above any text file camsim reads (the largest, a 4096 x 4096 displacement
// mesh, is about 300 MB): a bound, so that /dev/zero is an error, not a crash.
inline constexpr size_t kMaxTextBytes = size_t{512} << 20;

// The file's bytes into *text: a regular file or a pipe (--config <(...)),
// never a directory (one opens on Linux and reads as nothing), at most
// max_bytes; a read error fails rather than ending the text early. On failure
// *error says why ("is a directory, not a file", "larger than 512 MiB", a
// strerror text), without the path (callers name it); *text is unchanged.
bool ReadTextFile(const std::string& path, std::string* text, std::string* error, size_t max_bytes = kMaxTextBytes);

}  // namespace camsim::io
