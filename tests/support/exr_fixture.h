// Writing small EXR files for tests and fuzz seeds (test-only; header-only so
// the fuzz project can use it without the test library).
#pragma once

#include <OpenEXR/ImfChannelList.h>
#include <OpenEXR/ImfFrameBuffer.h>
#include <OpenEXR/ImfHeader.h>
#include <OpenEXR/ImfOutputFile.h>
#include <OpenEXR/ImfTiledOutputFile.h>
#include <OpenEXR/ImfTileDescriptionAttribute.h>

#include <cstdint>
#include <string>
#include <vector>

namespace camsim::test {

// A channel: values cover the data window, row-major, converted to `type`
// (UINT takes the integer part of values in (0, 4e9), else 0).
struct ExrChannel {
  std::string name;
  Imf::PixelType type;
  std::vector<float> values;
};

inline Imath::Box2i Box(int x0, int y0, int x1, int y1) { return Imath::Box2i({x0, y0}, {x1, y1}); }

// One single-part scanline (or tile x tile tiled) file with the given windows
// (chunks in `order`).
inline void WriteExrFixture(const std::string& path, const Imath::Box2i& display, const Imath::Box2i& data,
                            const std::vector<ExrChannel>& channels,
                            Imf::Compression compression = Imf::ZIP_COMPRESSION, bool tiled = false, int tile = 4,
                            Imf::LineOrder order = Imf::INCREASING_Y) {
  Imf::Header header(display, data);
  header.compression() = compression;
  header.lineOrder() = order;
  const int w = data.max.x - data.min.x + 1;
  Imf::FrameBuffer fb;
  std::vector<std::vector<half>> halves;
  std::vector<std::vector<uint32_t>> uints;
  halves.reserve(channels.size());  // slices point into these: no reallocation
  uints.reserve(channels.size());
  for (const ExrChannel& c : channels) {
    header.channels().insert(c.name, Imf::Channel(c.type));
    char* base = nullptr;
    size_t size = 4;
    if (c.type == Imf::HALF) {
      halves.emplace_back(c.values.begin(), c.values.end());
      base = reinterpret_cast<char*>(halves.back().data());
      size = 2;
    } else if (c.type == Imf::UINT) {
      uints.emplace_back();
      for (float v : c.values) uints.back().push_back(v > 0 && v < 4e9f ? static_cast<uint32_t>(v) : 0u);
      base = reinterpret_cast<char*>(uints.back().data());
    } else {
      base = reinterpret_cast<char*>(const_cast<float*>(c.values.data()));
    }
    fb.insert(c.name, Imf::Slice::Make(c.type, base, data, size, size * static_cast<size_t>(w)));
  }
  if (tiled) {
    header.setTileDescription(Imf::TileDescription(tile, tile, Imf::ONE_LEVEL));
    Imf::TiledOutputFile file(path.c_str(), header);
    file.setFrameBuffer(fb);
    file.writeTiles(0, file.numXTiles() - 1, 0, file.numYTiles() - 1);
  } else {
    Imf::OutputFile file(path.c_str(), header);
    file.setFrameBuffer(fb);
    file.writePixels(data.max.y - data.min.y + 1);
  }
}

}  // namespace camsim::test
