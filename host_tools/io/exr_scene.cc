#include "host_tools/io/exr_scene.h"

#include <cstdint>
#include <map>
#include <string>
#include <utility>
#include <vector>

#include <OpenEXR/ImfChannelList.h>

#include "host_tools/io/exr_common.h"

namespace camsim::io {
namespace {

using detail::ChannelRead;
using detail::Sanitize;
using detail::UnsupportedExr;

// The first part having all `names`, trying `first` (if >= 0) before the
// others; -1 if none.
int FindPart(const Imf::MultiPartInputFile& file, int first, const std::vector<std::string>& names) {
  auto has_all = [&](int part) {
    for (const std::string& n : names) {
      if (!detail::PartHasChannel(file, part, n)) return false;
    }
    return true;
  };
  if (first >= 0 && has_all(first)) return first;
  for (int p = 0; p < file.parts(); ++p) {
    if (has_all(p)) return p;
  }
  return -1;
}

bool EndsWith(const std::string& s, const std::string& suffix) {
  return s.size() >= suffix.size() && s.compare(s.size() - suffix.size(), suffix.size(), suffix) == 0;
}

struct Colour {
  int part = -1;
  std::string r, g, b;  // channel names (all three equal for a Y file)
  std::string layer;    // Blender layer prefix including its dot ("ViewLayer."), or ""
  std::string layout;
};

// Blender's compositor output: a layer of its own beside the view layers.
constexpr char kCompositeLayer[] = "Composite.";

// Blender multi-layer: the first `<layer><pass>.R` with G and B beside it;
// the Composite layer only when no other layer has one.
bool FindLayerPass(const Imf::MultiPartInputFile& file, const std::string& pass, Colour* c) {
  const std::string suffix = pass + ".R";
  for (const bool composite : {false, true}) {
    for (int p = 0; p < file.parts(); ++p) {
      if (!detail::IsFlatPart(file, p)) continue;
      const Imf::ChannelList& channels = file.header(p).channels();
      for (auto it = channels.begin(); it != channels.end(); ++it) {
        const std::string name = it.name();
        if (!EndsWith(name, suffix)) continue;
        const std::string layer = name.substr(0, name.size() - suffix.size());
        if (!layer.empty() && layer.back() != '.') continue;
        if ((layer == kCompositeLayer) != composite) continue;
        const std::string base = layer + pass + ".";
        if (FindPart(file, p, {base + "G", base + "B"}) != p) continue;
        *c = {p, name, base + "G", base + "B", layer,
              "blender-multilayer " + (layer.empty() ? std::string("(unnamed)") : layer.substr(0, layer.size() - 1))};
        return true;
      }
    }
  }
  return false;
}

// Colour channels per the rules in exr_scene.h; false with *error if none.
bool FindColour(const Imf::MultiPartInputFile& file, const std::string& path, Colour* c,
                std::string* error) {
  if (FindLayerPass(file, "Combined", c) || FindLayerPass(file, "Image", c)) return true;
  if (int p = FindPart(file, -1, {"R", "G", "B"}); p >= 0) {
    *c = {p, "R", "G", "B", "", detail::PartHasChannel(file, p, "A") ? "rgba" : "rgb"};
    return true;
  }
  if (int p = FindPart(file, -1, {"Y"}); p >= 0) {
    if (detail::PartHasChannel(file, p, "RY") || detail::PartHasChannel(file, p, "BY")) {
      *error = "'" + path + "': luminance/chroma (Y, RY, BY) files are not supported; save as RGB";
      return false;
    }
    *c = {p, "Y", "Y", "Y", "", "y"};
    return true;
  }
  int deep_parts = 0;
  for (int p = 0; p < file.parts(); ++p) deep_parts += detail::IsFlatPart(file, p) ? 0 : 1;
  *error = "'" + path + "': no colour channels (looked for <Layer>.Combined.R/G/B, " +
           "<Layer>.Image.R/G/B, R/G/B, Y); channels present: " + detail::ListChannels(file) +
           (deep_parts ? "; " + std::to_string(deep_parts) + " deep part(s) skipped: deep images are not supported"
                       : "");
  return false;
}

// Reads colour, and depth/motion found in the same file, into *frame.
bool ReadColourFile(Imf::MultiPartInputFile& file, const std::string& path, bool want_depth,
                    SceneFrame* frame, std::string* error) {
  Colour c;
  if (!FindColour(file, path, &c, error)) return false;
  if (!detail::DisplaySize(file.header(c.part), &frame->width, &frame->height)) {
    *error = "'" + path + "': display window is empty, larger than " + std::to_string(detail::kMaxDisplayDim) +
             " x " + std::to_string(detail::kMaxDisplayDim) + " or more than " +
             std::to_string(detail::kMaxDisplayPixels) + " pixels";
    return false;
  }
  frame->layout = c.layout;

  // Channels to read, grouped by part: each part is decoded once.
  std::map<int, std::vector<ChannelRead>> reads;
  InputSanitizeStats* rs = &frame->radiance_stats;
  reads[c.part].push_back({c.r, &frame->r, Sanitize::kRadiance, rs});
  const bool luminance = c.r == c.b;  // Y only: read once, copy to g and b
  if (!luminance) {
    reads[c.part].push_back({c.g, &frame->g, Sanitize::kRadiance, rs});
    reads[c.part].push_back({c.b, &frame->b, Sanitize::kRadiance, rs});
  }

  if (want_depth) {
    std::vector<std::string> names = {"Z", "depth", "Depth.Z"};
    if (!c.layer.empty()) names.insert(names.begin(), c.layer + "Depth.Z");
    for (const std::string& name : names) {
      const int p = FindPart(file, c.part, {name});
      if (p < 0) continue;
      reads[p].push_back({name, &frame->depth, Sanitize::kDepth, &frame->depth_stats});
      frame->has_depth = true;
      if (c.layer.empty()) frame->layout += "+z";
      break;
    }
  }

  const std::string vx = c.layer + "Vector.X", vy = c.layer + "Vector.Y";
  if (const int p = FindPart(file, c.part, {vx, vy}); p >= 0) {
    reads[p].push_back({vx, &frame->motion_x, Sanitize::kMotion, &frame->motion_stats});
    reads[p].push_back({vy, &frame->motion_y, Sanitize::kMotion, &frame->motion_stats});
    frame->has_motion = true;
  }

  for (const auto& [part, list] : reads) detail::ReadChannels(path, file, part, list);
  if (luminance) {
    frame->g = frame->r;
    frame->b = frame->r;
  }

  // Parts of a conforming multi-part file share the display window; check anyway.
  for (const FloatPlane* plane : {&frame->depth, &frame->motion_x}) {
    if (!plane->data.empty() && (plane->width != frame->width || plane->height != frame->height)) {
      throw UnsupportedExr("parts have different display windows");
    }
  }
  if (file.parts() > 1) frame->layout += " (multi-part, colour in part " + std::to_string(c.part) + ")";
  return true;
}

std::string SizeText(int64_t w, int64_t h) { return std::to_string(w) + "x" + std::to_string(h); }

// The depth channel of a separate depth file: the first name found in priority
// order (each searched in all parts), else the file's only channel.
bool FindDepthChannel(const Imf::MultiPartInputFile& file, int* part, std::string* name) {
  for (const std::string want : {"Z", "depth", "Depth.Z", ".Depth.Z", "Y", "R"}) {
    for (int p = 0; p < file.parts(); ++p) {
      if (!detail::IsFlatPart(file, p)) continue;
      const Imf::ChannelList& channels = file.header(p).channels();
      for (auto it = channels.begin(); it != channels.end(); ++it) {
        const std::string n = it.name();
        if (want[0] == '.' ? EndsWith(n, want) : n == want) {
          *part = p;
          *name = n;
          return true;
        }
      }
    }
  }
  int count = 0;
  for (int p = 0; p < file.parts(); ++p) {
    if (!detail::IsFlatPart(file, p)) continue;
    const Imf::ChannelList& channels = file.header(p).channels();
    for (auto it = channels.begin(); it != channels.end(); ++it, ++count) {
      *part = p;
      *name = it.name();
    }
  }
  return count == 1;
}

// Reads depth from its own file, per the rules in exr_scene.h.
bool ReadDepthFile(Imf::MultiPartInputFile& file, const std::string& depth_path,
                   const std::string& colour_path, SceneFrame* frame, std::string* error) {
  int part = -1;
  std::string name;
  if (!FindDepthChannel(file, &part, &name)) {
    *error = "depth file '" + depth_path + "': no depth channel (looked for Z, depth, Depth.Z, " +
             "<Layer>.Depth.Z, Y, R or a sole channel); channels present: " +
             detail::ListChannels(file);
    return false;
  }
  int w = 0, h = 0;
  if (!detail::DisplaySize(file.header(part), &w, &h) || w != frame->width || h != frame->height) {
    const Imath::Box2i& d = file.header(part).displayWindow();
    *error = "depth file '" + depth_path + "' is " +
             SizeText(int64_t{d.max.x} - d.min.x + 1, int64_t{d.max.y} - d.min.y + 1) +
             " but colour file '" + colour_path + "' is " + SizeText(frame->width, frame->height);
    return false;
  }
  detail::ReadChannels(depth_path, file, part, {{name, &frame->depth, Sanitize::kDepth, &frame->depth_stats}});
  frame->has_depth = true;
  frame->layout += " + separate depth";
  return true;
}

// What was replaced in one kind of samples (`what`), for a warning: "3 NaN,
// 1 +inf colour samples replaced (first: channel R at x=5, y=7)"; "" if
// nothing was. `nan_only`: the other counts were kept (depth).
std::string Replaced(const InputSanitizeStats& s, bool nan_only, const std::string& what, const std::string& by) {
  if (s.first_channel.empty()) return "";
  const std::pair<uint64_t, const char*> counts[] = {{s.nan, "NaN"},
                                                     {nan_only ? 0 : s.pos_inf, "+inf"},
                                                     {nan_only ? 0 : s.neg_inf, "-inf"},
                                                     {nan_only ? 0 : s.negative, "negative"}};
  std::string text;
  uint64_t total = 0;
  for (const auto& [n, name] : counts) {
    if (n == 0) continue;
    text += (text.empty() ? "" : ", ") + std::to_string(n) + " " + name;
    total += n;
  }
  return text + " " + what + (total == 1 ? " sample" : " samples") + " replaced" + by + " (first: channel " +
         detail::Printable(s.first_channel) + " at x=" + std::to_string(s.first_x) + ", y=" +
         std::to_string(s.first_y) + ")";
}

// Adds "'path': part; part" to *warnings if any part says something.
void AddWarning(const std::string& path, const std::vector<std::string>& parts, std::vector<std::string>* warnings) {
  std::string line;
  for (const std::string& p : parts) {
    if (!p.empty()) line += (line.empty() ? "'" + path + "': " : "; ") + p;
  }
  if (!line.empty()) warnings->push_back(line);
}

}  // namespace

bool LoadSceneExr(const std::string& path, const std::string& depth_path, SceneFrame* out,
                  std::string* error) {
  std::string ignored;
  if (error == nullptr) error = &ignored;
  SceneFrame frame;
  const std::unique_ptr<Imf::MultiPartInputFile> file = detail::OpenExr(path, error);
  if (!file || !detail::CatchExr(path, error, [&] {
        return ReadColourFile(*file, path, depth_path.empty(), &frame, error);
      })) {
    return false;
  }
  frame.source = path;
  AddWarning(path,
             {Replaced(frame.radiance_stats, false, "colour", ""),
              depth_path.empty() ? Replaced(frame.depth_stats, true, "depth", " by +inf") : "",
              Replaced(frame.motion_stats, false, "motion", " by 0")},
             &frame.warnings);
  if (!depth_path.empty()) {
    const std::unique_ptr<Imf::MultiPartInputFile> depth = detail::OpenExr(depth_path, error);
    if (!depth || !detail::CatchExr(depth_path, error, [&] {
          return ReadDepthFile(*depth, depth_path, path, &frame, error);
        })) {
      return false;
    }
    frame.source += " + " + depth_path;
    AddWarning(depth_path, {Replaced(frame.depth_stats, true, "depth", " by +inf")}, &frame.warnings);
  }
  *out = std::move(frame);
  return true;
}

}  // namespace camsim::io
