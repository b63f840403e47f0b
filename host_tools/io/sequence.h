// Expanding command-line inputs into a list of frame files. Host-side only.
#pragma once

#include <string>
#include <vector>

namespace camsim::io {

// Sets *files to, for each argument in order:
//  - an existing file: itself;
//  - a directory: all regular files in it ending in ".exr" (any case), sorted
//    by name byte-wise (so zero-pad frame numbers);
//  - otherwise a printf-style pattern with exactly one %d or %0Nd (e.g.
//    "frame_%04d.exr"): indices from 0, else 1, else the lowest present (e.g.
//    1001), up to the first missing index; a file of a later index (a gap) is
//    an error. (Where the index names a directory, later indices are tried
//    up to 1000 past the missing one.)
// Fails (false, *error naming the argument) if an argument matches nothing,
// a pattern has a gap, or `args` is empty; *files is then unchanged. No
// exception escapes.
bool ExpandInputs(const std::vector<std::string>& args, std::vector<std::string>* files,
                  std::string* error);

}  // namespace camsim::io
