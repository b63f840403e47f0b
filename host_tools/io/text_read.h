// Reading a whole text file (configurations, lists). Host-side only.
#pragma once

#include <string>

namespace camsim::io {

// The file's bytes into *text: a regular file or a pipe (--config <(...)),
// never a directory (one opens on Linux and reads as nothing); a read error
// fails rather than ending the text early. On failure *error says why ("is a directory, not a file", a
// strerror text), without the path (callers name it); *text is unchanged.
bool ReadTextFile(const std::string& path, std::string* text, std::string* error);

}  // namespace camsim::io
