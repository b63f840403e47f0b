// Loading a rendered HDR scene frame (radiance, optional depth and motion) from
// OpenEXR. Host-side only.
//
// LoadSceneExr(path, depth_path, out, error): the rules
//
// Files: single-part and multi-part files (every part is searched, in file
// order; deep parts are skipped, and a file of deep parts only is an error
// that says so); scanline and tiled; any compression. OpenEXR 3.1 refuses a
// multi-part file with a deep part unless every part has a `version`
// attribute; the error gives its reason. For
// multi-part files the layout gets " (multi-part, colour in part N)" appended.
//
// Colour, first match wins:
//  1. Blender multi-layer: `<Layer>.Combined.R/G/B` (layout "blender-multilayer
//     <Layer>"); the first layer, in part order then channel-name order, that
//     has all three. Only if no layer has Combined: `<Layer>.Image.R/G/B`.
//     Blender's `Composite` layer (the compositor's output, written beside
//     the view layers) comes last: the view layer holds the depth and motion
//     that go with its colour, and the compositor's lens effects are camsim's
//     to model.
//     A bare `Combined.R/G/B` (empty layer name) also counts.
//  2. Plain `R`, `G`, `B` (layout "rgb", or "rgba" if `A` is present; A unused).
//  3. Luminance-only `Y`: r = g = b = Y (layout "y"). Files with chroma
//     channels `RY`/`BY` are rejected (convert them to RGB first).
//  Otherwise: error listing the channels present (up to 20).
//
// Depth (metres along the view axis), when depth_path is empty, looked up in
// the colour part first, then in the other parts:
//  `<Layer>.Depth.Z` (Blender), then `Z`, `depth`, `Depth.Z`. Plain layouts get
//  "+z" appended (e.g. "rgb+z"). No depth channel: has_depth = false.
// Depth from a separate file (depth_path not empty; it wins over depth in the
// colour file): the first of `Z`, `depth`, `Depth.Z`, `<any>.Depth.Z`, `Y`,
// `R` found (each searched in all parts), else the file's only channel. Its
// display window must have the colour file's width and height (else an error
// naming both sizes); pixels are matched relative to each file's display
// window origin. Layout gets " + separate depth" appended; `source` is
// "<path> + <depth_path>".
//
// Motion (pixels, Blender's X/Y towards the previous frame): `<Layer>.Vector.X`
// and `<Layer>.Vector.Y` (plain files: `Vector.X`/`Vector.Y`), both in one part.
// Z and W are ignored. Non-finite motion becomes 0 (counted in motion_stats).
//
// Sample types: HALF and FLOAT are read as float; UINT is converted to float
// (its integer value). Subsampled channels (x/y sampling != 1) are an error.
//
// Windows: the output is the display window (width x height). Display-window
// pixels outside the data window get radiance 0, depth +inf and motion 0 (not
// counted in the stats); data outside the display window is dropped. The
// display window must be non-empty, at most 16384 x 16384 and at most 2^25
// pixels (8K UHD fits); the data window at most 65536 wide.
//
// Sanitising, counted in the stats before replacement (only samples that came
// from the file are counted):
//  radiance (each of R, G, B counted separately): NaN -> 0 (nan), -inf -> 0
//    (neg_inf), finite < 0 -> 0 (negative), +inf -> 65504 (pos_inf; the largest
//    half). Finite values > 65504 are kept.
//  depth: NaN -> +inf (nan); +inf (pos_inf), -inf (neg_inf) and finite < 0
//    (negative) are counted but kept, like 0 and 1e10 (sky): the depth stage
//    decides what they mean.
//  motion (X and Y together): NaN (nan), +inf (pos_inf) and -inf (neg_inf)
//    -> 0.
// Each stats also keeps the first sample replaced (not one only counted), in
// display-window pixels from its top-left: the topmost row, then the
// leftmost; at a tie the channel read first (R before G before B).
//
// Warnings: one line per input file in which samples were replaced (colour,
// NaN depth, motion), naming the file, the counts and the first sample:
//  'f.exr': 3 NaN, 1 +inf colour samples replaced (first: channel R at x=5,
//  y=7); 1 NaN depth sample replaced by +inf (first: channel Z at x=0, y=0)
//
// Errors (return false, *error names the file, *out is left unchanged): file
// missing or a directory; not a readable OpenEXR file, truncated or garbage
// (includes OpenEXR's reason); a chunk to be read that does not decompress to
// the size its rows need ("corrupt chunk at scan line N" or "at tile (x, y)",
// checked by OpenEXRCore as it decodes the pixels; DWAA/DWAB chunks, which
// Core 3.1 cannot decode, by their header's sizes and zlib section, "(DWA
// ...)"); no colour channels (lists those present);
// display window empty or too large; depth file problems as above. No
// exception escapes.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "host_tools/io/float_plane.h"

namespace camsim::io {

struct InputSanitizeStats {
  uint64_t nan = 0, pos_inf = 0, neg_inf = 0, negative = 0;  // counts before replacement
  std::string first_channel;  // the first sample replaced (see above); empty if none was
  int first_x = 0, first_y = 0;
};

struct SceneFrame {
  int width = 0, height = 0;  // the display window size
  FloatPlane r, g, b;         // scene-linear radiance
  bool has_depth = false;
  FloatPlane depth;  // metres along the view axis
  bool has_motion = false;
  FloatPlane motion_x, motion_y;  // pixels (Blender Vector.X/.Y)
  InputSanitizeStats radiance_stats, depth_stats, motion_stats;
  std::vector<std::string> warnings;  // one line per file with samples replaced (see above)
  std::string source;  // path(s) it came from
  std::string layout;  // e.g. "blender-multilayer ViewLayer", "rgb+z", "rgb + separate depth"
};

// See the rules above. depth_path may be empty.
bool LoadSceneExr(const std::string& path, const std::string& depth_path, SceneFrame* out,
                  std::string* error);

}  // namespace camsim::io
