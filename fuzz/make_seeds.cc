// make_seeds OUT_DIR: writes the committed seed corpus (small valid inputs)
// into OUT_DIR/fuzz_exr_loader, OUT_DIR/fuzz_config and OUT_DIR/fuzz_core.
// Run from the source tree (it reads configs/camera.toml and a bundled scene):
//   build/fuzz/make_seeds fuzz/corpus
#include <OpenEXR/ImfChannelList.h>
#include <OpenEXR/ImfFrameBuffer.h>
#include <OpenEXR/ImfHeader.h>
#include <OpenEXR/ImfMultiPartOutputFile.h>
#include <OpenEXR/ImfOutputFile.h>
#include <OpenEXR/ImfOutputPart.h>
#include <OpenEXR/ImfTiledOutputFile.h>
#include <OpenEXR/ImfTileDescriptionAttribute.h>
#include <OpenEXR/ImfPartType.h>

#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <limits>
#include <string>
#include <utility>
#include <vector>

#include "fuzz/fuzz_common.h"
#include "host_tools/config.h"
#include "host_tools/io/exr_scene.h"
#include "tests/support/exr_fixture.h"

namespace fs = std::filesystem;
using namespace camsim;

namespace {

using test::Box;
using Channel = test::ExrChannel;

void WriteExr(const std::string& path, const Imath::Box2i& display, const Imath::Box2i& data,
              const std::vector<Channel>& channels, Imf::Compression compression, bool tiled = false) {
  test::WriteExrFixture(path, display, data, channels, compression, tiled);
}

std::vector<float> Ramp(int n, float scale, float offset = 0.0f) {
  std::vector<float> v(static_cast<size_t>(n));
  for (int i = 0; i < n; ++i) v[static_cast<size_t>(i)] = offset + scale * static_cast<float>(i);
  return v;
}

void ExrSeeds(const fs::path& dir) {
  const float nan = std::numeric_limits<float>::quiet_NaN(), inf = std::numeric_limits<float>::infinity();
  // Plain RGB, float, each compression that OpenEXR 3.1 writes.
  const struct {
    const char* name;
    Imf::Compression c;
  } comps[] = {{"none", Imf::NO_COMPRESSION}, {"rle", Imf::RLE_COMPRESSION},   {"zips", Imf::ZIPS_COMPRESSION},
               {"zip", Imf::ZIP_COMPRESSION},  {"piz", Imf::PIZ_COMPRESSION},   {"pxr24", Imf::PXR24_COMPRESSION},
               {"b44", Imf::B44_COMPRESSION},  {"b44a", Imf::B44A_COMPRESSION}, {"dwaa", Imf::DWAA_COMPRESSION},
               {"dwab", Imf::DWAB_COMPRESSION}};
  for (const auto& comp : comps) {
    WriteExr((dir / (std::string("rgb_half_") + comp.name + ".exr")).string(), Box(0, 0, 3, 2), Box(0, 0, 3, 2),
             {{"R", Imf::HALF, Ramp(12, 0.25f)}, {"G", Imf::HALF, Ramp(12, 0.5f)}, {"B", Imf::HALF, Ramp(12, 1.0f)}},
             comp.c);
  }
  // The 4 x 3 seeds above are stored raw under DWA (no smaller): these are
  // real DWA chunks, with depth as their zlib section (camsim checks it).
  for (const auto& [name, c] : {std::pair{"dwaa", Imf::DWAA_COMPRESSION}, {"dwab", Imf::DWAB_COMPRESSION}}) {
    WriteExr((dir / (std::string("rgbz_half_") + name + ".exr")).string(), Box(0, 0, 15, 15), Box(0, 0, 15, 15),
             {{"R", Imf::HALF, Ramp(256, 0.01f)},
              {"G", Imf::HALF, Ramp(256, 0.02f)},
              {"B", Imf::HALF, Ramp(256, 0.03f)},
              {"Z", Imf::FLOAT, Ramp(256, 0.01f, 1.0f)}},
             c);
  }
  // RGBA + Z, float, with NaN / inf / negative samples.
  WriteExr((dir / "rgbaz_float_special.exr").string(), Box(0, 0, 2, 1), Box(0, 0, 2, 1),
           {{"R", Imf::FLOAT, {nan, inf, -inf, -1.0f, 1e30f, 0.5f}},
            {"G", Imf::FLOAT, Ramp(6, 1.0f)},
            {"B", Imf::FLOAT, Ramp(6, 2.0f)},
            {"A", Imf::FLOAT, Ramp(6, 0.0f, 1.0f)},
            {"Z", Imf::FLOAT, {nan, inf, -inf, -2.0f, 0.0f, 1e10f}}},
           Imf::ZIP_COMPRESSION);
  // Luminance only, UINT and HALF.
  WriteExr((dir / "y_uint.exr").string(), Box(0, 0, 2, 0), Box(0, 0, 2, 0), {{"Y", Imf::UINT, {0, 7, 65536}}},
           Imf::NO_COMPRESSION);
  WriteExr((dir / "y_half_rle.exr").string(), Box(0, 0, 4, 1), Box(0, 0, 4, 1), {{"Y", Imf::HALF, Ramp(10, 0.1f)}},
           Imf::RLE_COMPRESSION);
  // Data window partly outside and partly inside the display window.
  WriteExr((dir / "windows.exr").string(), Box(10, 20, 13, 22), Box(11, 19, 15, 21),
           {{"R", Imf::FLOAT, Ramp(15, 1.0f)}, {"G", Imf::FLOAT, Ramp(15, 2.0f)}, {"B", Imf::FLOAT, Ramp(15, 3.0f)}},
           Imf::NO_COMPRESSION);
  // Tiled.
  WriteExr((dir / "tiled_piz.exr").string(), Box(0, 0, 5, 4), Box(0, 0, 5, 4),
           {{"R", Imf::HALF, Ramp(30, 0.1f)}, {"G", Imf::HALF, Ramp(30, 0.2f)}, {"B", Imf::HALF, Ramp(30, 0.3f)},
            {"Z", Imf::FLOAT, Ramp(30, 1.0f)}},
           Imf::PIZ_COMPRESSION, true);
  // Multi-part: depth in part 0, Blender-style colour and motion in part 1.
  {
    std::vector<Imf::Header> headers(2, Imf::Header(2, 2));
    headers[0].setName("depth");
    headers[0].setType(Imf::SCANLINEIMAGE);
    headers[0].channels().insert("Z", Imf::Channel(Imf::FLOAT));
    headers[1].setName("beauty");
    headers[1].setType(Imf::SCANLINEIMAGE);
    const char* names[] = {"View.Combined.R", "View.Combined.G", "View.Combined.B", "View.Vector.X", "View.Vector.Y"};
    for (const char* c : names) headers[1].channels().insert(c, Imf::Channel(Imf::HALF));
    const std::string path = (dir / "multipart.exr").string();
    Imf::MultiPartOutputFile file(path.c_str(), headers.data(), 2);
    float z[4] = {3, 4, 5, 6};
    half v[4] = {half(0.5f), half(0.75f), half(2.0f), half(-1.0f)};
    Imf::FrameBuffer fb0, fb1;
    fb0.insert("Z", Imf::Slice(Imf::FLOAT, reinterpret_cast<char*>(z), 4, 8));
    for (const char* c : names) fb1.insert(c, Imf::Slice(Imf::HALF, reinterpret_cast<char*>(v), 2, 4));
    Imf::OutputPart p0(file, 0), p1(file, 1);
    p0.setFrameBuffer(fb0);
    p0.writePixels(2);
    p1.setFrameBuffer(fb1);
    p1.writePixels(2);
  }
  // A crop of the bundled Blender render (multi-layer names, depth, motion).
  {
    io::SceneFrame f;
    std::string error;
    if (!io::LoadSceneExr(CAMSIM_SOURCE_DIR "/scenes/aisle_0001.exr", "", &f, &error)) {
      std::fprintf(stderr, "make_seeds: %s\n", error.c_str());
      std::exit(1);
    }
    const int cw = 6, ch = 4, x0 = f.width / 2, y0 = f.height / 2;
    auto crop = [&](const io::FloatPlane& p) {
      std::vector<float> v;
      for (int y = 0; y < ch; ++y)
        for (int x = 0; x < cw; ++x) v.push_back(p.data.empty() ? 0.0f : p.at(x0 + x, y0 + y));
      return v;
    };
    WriteExr((dir / "blender_crop_zip.exr").string(), Box(0, 0, cw - 1, ch - 1), Box(0, 0, cw - 1, ch - 1),
             {{"ViewLayer.Combined.R", Imf::HALF, crop(f.r)},
              {"ViewLayer.Combined.G", Imf::HALF, crop(f.g)},
              {"ViewLayer.Combined.B", Imf::HALF, crop(f.b)},
              {"ViewLayer.Depth.Z", Imf::FLOAT, crop(f.depth)},
              {"ViewLayer.Vector.X", Imf::HALF, crop(f.motion_x)},
              {"ViewLayer.Vector.Y", Imf::HALF, crop(f.motion_y)}},
             Imf::ZIP_COMPRESSION);
  }
}

void WriteText(const fs::path& path, const std::string& text) {
  std::ofstream(path, std::ios::binary) << text;
}

std::string ReadText(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
}

void ConfigSeeds(const fs::path& dir) {
  WriteText(dir / "default.toml", host::DefaultConfigToml());
  const std::string camera = ReadText(CAMSIM_SOURCE_DIR "/configs/camera.toml");
  WriteText(dir / "camera.toml", camera);
  WriteText(dir / "mono.toml",
            "[sensor]\ncfa = \"Mono\"\nadc_bits = 10\nblack_level_dn = 16.0\n[cfa]\nmono_weights = [0.3, 0.6, 0.1]\n"
            "[gamma]\ncurve = \"power\"\ngamma = 2.2\n[output]\nbits = 16\n");
  WriteText(dir / "full_isp.toml",
            "[pipeline]\nstages = [\"exposure\", \"vignetting\", \"cfa\", \"sensor\", \"black_level\", "
            "\"white_balance\", \"demosaic\", \"color_matrix\", \"gamma\"]\nseed = 12345\n"
            "[sensor]\ncfa = \"BayerGB\"\nadc_bits = 16\ngain_db = 12.0\nshot_noise = false\n"
            "[vignetting]\nmode = \"table\"\ntable = [1.0, 0.9, 0.5, 0.1]\n"
            "[white_balance]\ngain = [2.0, 1.0, 1.5]\n[demosaic]\nmethod = \"bilinear\"\n"
            "[color_matrix]\nm = [1.5, -0.3, -0.2, -0.1, 1.2, -0.1, 0.0, -0.5, 1.5]\n[gamma]\ncurve = \"srgb\"\n");
  WriteText(dir / "scaled_mask.toml",
            "[sensor]\nwidth = 17\nheight = 9\nscene_fit = \"scale\"\ncfa = \"BayerGR\"\nadc_bits = 8\n"
            "pixel_pitch_um = 3.45\n[lens]\nfocal_length_mm = 8.0\n"
            "[vignetting]\nmode = \"mask\"\nmask = \"mask.png\"\n[black_level]\nblack_level_dn = 10.5\n");
  WriteText(dir / "cropped_raw.toml",
            "[pipeline]\nstages = [\"exposure\", \"cfa\", \"sensor\"]\n"
            "[sensor]\nwidth = 5\nheight = 3\ncfa = \"BayerBG\"\nfull_well_e = 1000000.0\n"
            "system_gain_dn_per_e = 1000.0\ndark_current_e_per_s = 1e6\ntemperature_c = 150.0\n"
            "[exposure]\nexposure_time_us = 1e8\nf_number = 0.5\nphotons_per_radiance_ms = 1e9\n");
  WriteText(dir / "smear_flare.toml",
            "# CCD smear and lens flare: both need the host's per-frame pre-passes, which\n"
            "# RunChecked runs (the fuzzer once reached smear from default.toml and the\n"
            "# harness, not the core, refused the frame).\n"
            "[sensor]\nsmear_row_transfer_us = 5.0\nsmear_leak = 0.5\n\n[flare]\nenabled = true\nthreshold = 0.5\n");
}

void CoreSeeds(const fs::path& dir) {
  auto demo = [](int w, int h) {
    host::RunConfig rc;
    host::Origins origins;
    std::string error;
    if (!host::LoadConfigFile(CAMSIM_SOURCE_DIR "/configs/camera.toml", &rc, &origins, &error)) {
      std::fprintf(stderr, "make_seeds: %s\n", error.c_str());
      std::exit(1);
    }
    rc.core.vignetting.focal_length_px = 40.0;  // 28 mm over a 36 mm sensor at 51 px
    if (!host::FinishConfig(&rc, w, h, origins, 1, &error)) {
      std::fprintf(stderr, "make_seeds: %s\n", error.c_str());
      std::exit(1);
    }
    return rc.core;
  };
  auto write = [&](const char* name, const PipelineConfig& c, bool mask, const std::vector<uint32_t>& samples) {
    const std::vector<uint8_t> blob = fuzz::EncodeCoreCase(c, mask, samples);
    std::ofstream(dir / name, std::ios::binary).write(reinterpret_cast<const char*>(blob.data()),
                                                      static_cast<std::streamsize>(blob.size()));
  };
  const std::vector<uint32_t> ramp = {0u, 0x4000u, 0x10000u, 0x28000u, 0x100000u, 0xFFFFFFFFu, 0x8000u, 0x30000u};
  write("demo_8x6.bin", demo(8, 6), false, ramp);
  PipelineConfig c = demo(7, 5);
  c.demosaic.method = DemosaicMethod::kBilinear;
  c.color_matrix = ColorMatrixConfig{{1.5, -0.3, -0.2, -0.1, 1.2, -0.1, 0.0, -0.5, 1.5}};
  write("demo_7x5_bilinear_ccm.bin", c, false, {0u, 0xFFFFFFFFu, 0x10000u});
  c = demo(5, 4);
  c.geometry.cfa = Cfa::kMono;
  c.gamma.curve = GammaCurve::kPower;
  c.sensor.shot_noise = false;
  write("mono_5x4.bin", c, false, ramp);
  c = demo(3, 3);
  c.vignetting.mode = VignettingMode::kMask;
  c.geometry.adc_bits = 16;
  c.sensor.black_level_dn = 4096;
  write("mask_3x3_16bit.bin", c, true, ramp);
  c = demo(1, 9);
  c.vignetting.mode = VignettingMode::kTable;
  c.vignetting.table_count = 3;
  c.vignetting.table[0] = 1.0;
  c.vignetting.table[1] = 3.9;
  c.vignetting.table[2] = 0.0;
  c.order_count = 4;  // exposure, vignetting, cfa, sensor: the raw frame
  write("raw_1x9_table.bin", c, false, {0xFFFFFFFFu, 0u});
  c = demo(9, 1);
  c.geometry.cfa = Cfa::kBayerBG;
  c.order[0] = StageId::kExposure;
  c.order[1] = StageId::kCfa;
  c.order[2] = StageId::kVignetting;
  c.order[3] = StageId::kSensor;
  c.order[4] = StageId::kBlackLevel;
  c.order[5] = StageId::kGamma;
  c.order_count = 6;
  write("reordered_9x1.bin", c, false, ramp);
  c = demo(12, 10);  // flare and smear: RunChecked runs their pre-passes
  c.flare.enabled = true;
  c.flare.threshold = 0.5;
  c.sensor.smear_row_transfer_us = 20.0;
  c.sensor.smear_leak = 0.5;
  write("flare_smear_12x10.bin", c, false, ramp);
}

// fuzz_reconfigure: each core seed after changes that copy tables (the
// sensor's stored fixed pattern and column offsets on in both) and a change
// of the second configuration's exposure time (fuzz_reconfigure.cc's layout).
void ReconfigureSeeds(const fs::path& core_dir, const fs::path& dir) {
  const auto selector = [](const char* name) {
    const auto& params = fuzz::Params();
    for (size_t i = 0; i < params.size(); ++i)
      if (std::strcmp(params[i].name, name) == 0) return static_cast<uint8_t>(i);
    std::fprintf(stderr, "make_seeds: no parameter %s\n", name);
    std::exit(1);
  };
  const auto extra = [](int change) { return static_cast<uint8_t>(fuzz::Params().size() + change); };
  std::vector<uint8_t> prefix = {static_cast<uint8_t>(2 | (1 << 3)),  // 2 shared changes, 1 of the second
                                 extra(5), 1,                          // fixed_pattern_table = true
                                 extra(6), 16,                         // column_fpn_e = 2
                                 selector("exposure_time_us"), 255};   // a raw double
  const double exposure = 15000.0;
  uint8_t raw[8];
  std::memcpy(raw, &exposure, 8);
  prefix.insert(prefix.end(), raw, raw + 8);
  for (const auto& e : fs::directory_iterator(core_dir)) {
    std::ifstream in(e.path(), std::ios::binary);
    std::vector<uint8_t> blob = prefix;
    blob.insert(blob.end(), std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
    std::ofstream(dir / e.path().filename(), std::ios::binary)
        .write(reinterpret_cast<const char*>(blob.data()), static_cast<std::streamsize>(blob.size()));
  }
}

}  // namespace

int main(int argc, char** argv) {
  if (argc != 2) {
    std::fprintf(stderr, "usage: make_seeds OUT_DIR\n");
    return 2;
  }
  const fs::path out = argv[1];
  for (const char* t : {"fuzz_exr_loader", "fuzz_config", "fuzz_core", "fuzz_reconfigure"})
    fs::create_directories(out / t);
  ExrSeeds(out / "fuzz_exr_loader");
  ConfigSeeds(out / "fuzz_config");
  CoreSeeds(out / "fuzz_core");
  ReconfigureSeeds(out / "fuzz_core", out / "fuzz_reconfigure");
  std::printf("make_seeds: wrote seeds under %s\n", out.string().c_str());
  return 0;
}
