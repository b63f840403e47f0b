// Calibration files (OpenCV FileStorage YAML, ROS camera_info YAML), their
// fitting to the sensor size, the [distortion] config and `camsim pattern`.
#include <sys/wait.h>
#include <unistd.h>

#include <cstdlib>
#include <fstream>
#include <iterator>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

#include <gtest/gtest.h>

#include "host_tools/calibration.h"
#include "host_tools/config.h"
#include "host_tools/io/exr_scene.h"
#include "host_tools/pattern.h"

namespace camsim::host {
namespace {

// As OpenCV's calibration sample writes it (cv::FileStorage, 5 coefficients).
const char kOpenCv[] = R"(%YAML:1.0
---
calibration_time: "Sat Nov 21 10:00:00 2026"
image_width: 640
image_height: 480
camera_matrix: !!opencv-matrix
   rows: 3
   cols: 3
   dt: d
   data: [ 5.3591573396163199e+02, 0., 3.4228315473308373e+02, 0.,
       5.3591573396163199e+02, 2.3557082909788173e+02, 0., 0., 1. ]
distortion_coefficients: !!opencv-matrix
   rows: 5
   cols: 1
   dt: d
   data: [ -2.6637260909660682e-01, -3.8588898922304653e-02,
       1.7831947042852964e-03, -2.8122100441115472e-04,
       2.3839153080878486e-01 ]
avg_reprojection_error: 3.9259098975581364e-01
)";

// ROS camera_calibration_parsers layout.
const char kRos[] = R"(image_width: 1280
image_height: 960
camera_name: narrow_stereo
camera_matrix:
  rows: 3
  cols: 3
  data: [1000.5, 0.0, 645.25, 0.0, 1001.0, 474.5, 0.0, 0.0, 1.0]
distortion_model: rational_polynomial
distortion_coefficients:
  rows: 1
  cols: 8
  data: [0.5, -0.1, 0.0012, -0.0007, 0.01, 0.8, 0.05, 0.0]
rectification_matrix:
  rows: 3
  cols: 3
  data: [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0]
)";

TEST(Calibration, ReadsOpenCvFileStorage) {
  Calibration c;
  std::string error;
  ASSERT_TRUE(ParseCalibration(kOpenCv, "cal.yml", false, &c, &error)) << error;
  EXPECT_EQ(c.lens.model, DistortionModel::kBrown);
  EXPECT_DOUBLE_EQ(c.lens.fx, 5.3591573396163199e+02);
  EXPECT_DOUBLE_EQ(c.lens.cx, 3.4228315473308373e+02);
  EXPECT_DOUBLE_EQ(c.lens.cy, 2.3557082909788173e+02);
  EXPECT_DOUBLE_EQ(c.lens.k[0], -2.6637260909660682e-01);
  EXPECT_DOUBLE_EQ(c.lens.k[1], -3.8588898922304653e-02);
  EXPECT_DOUBLE_EQ(c.lens.p1, 1.7831947042852964e-03);
  EXPECT_DOUBLE_EQ(c.lens.p2, -2.8122100441115472e-04);
  EXPECT_DOUBLE_EQ(c.lens.k[2], 2.3839153080878486e-01);
  EXPECT_EQ(c.width, 640);
  EXPECT_EQ(c.height, 480);
  // The same four numbers as a cv::fisheye calibration when the config says so.
  std::string four = kOpenCv;
  four.replace(four.find("   rows: 5"), 10, "   rows: 4");
  const std::string k3 = ",\n       2.3839153080878486e-01";
  four.erase(four.find(k3), k3.size());
  ASSERT_TRUE(ParseCalibration(four, "f.yml", true, &c, &error)) << error;
  EXPECT_EQ(c.lens.model, DistortionModel::kFisheye);
  EXPECT_DOUBLE_EQ(c.lens.k[3], -2.8122100441115472e-04);
}

TEST(Calibration, ReadsRosCameraInfo) {
  Calibration c;
  std::string error;
  ASSERT_TRUE(ParseCalibration(kRos, "ros.yaml", false, &c, &error)) << error;
  EXPECT_EQ(c.lens.model, DistortionModel::kBrown);
  EXPECT_DOUBLE_EQ(c.lens.fy, 1001.0);
  EXPECT_DOUBLE_EQ(c.lens.k[3], 0.8);
  EXPECT_DOUBLE_EQ(c.lens.k[4], 0.05);
  EXPECT_DOUBLE_EQ(c.lens.p2, -0.0007);
  std::string eq = kRos;
  eq.replace(eq.find("rational_polynomial"), 19, "equidistant");
  eq.replace(eq.find("cols: 8\n  data: [0.5, -0.1, 0.0012, -0.0007, 0.01, 0.8, 0.05, 0.0]"), 66,
             "cols: 4\n  data: [0.05, -0.01, 0.003, -0.0005]");
  ASSERT_TRUE(ParseCalibration(eq, "eq.yaml", false, &c, &error)) << error;
  EXPECT_EQ(c.lens.model, DistortionModel::kFisheye);
  EXPECT_DOUBLE_EQ(c.lens.k[2], 0.003);
}

TEST(Calibration, BadFilesSayWhatAndWhere) {
  Calibration c;
  std::string error;
  EXPECT_FALSE(ParseCalibration("image_width: 3\n", "a.yml", false, &c, &error));
  EXPECT_NE(error.find("a.yml: no camera_matrix"), std::string::npos) << error;
  std::string skew = kRos;
  skew.replace(skew.find("1000.5, 0.0,"), 12, "1000.5, 2.0,");
  EXPECT_FALSE(ParseCalibration(skew, "s.yaml", false, &c, &error));
  EXPECT_NE(error.find("s.yaml:4: camera_matrix has a skew"), std::string::npos) << error;
  std::string nan = kRos;
  nan.replace(nan.find("0.01, 0.8"), 4, "nan");
  EXPECT_FALSE(ParseCalibration(nan, "n.yaml", false, &c, &error));
  EXPECT_NE(error.find("n.yaml:9: distortion_coefficients has a value that is not a finite number"),
            std::string::npos) << error;
  std::string model = kRos;
  const size_t model_at = model.find("rational_polynomial");
  ASSERT_NE(model_at, std::string::npos);
  model.replace(model_at, 19, "fov");
  EXPECT_FALSE(ParseCalibration(model, "m.yaml", false, &c, &error));
  EXPECT_NE(error.find("'fov' is not supported"), std::string::npos) << error;
  std::string count = kRos;
  const size_t count_at = count.find(", 0.05, 0.0]");
  ASSERT_NE(count_at, std::string::npos);
  count.replace(count_at, 12, "]");
  EXPECT_FALSE(ParseCalibration(count, "c.yaml", false, &c, &error));
  EXPECT_NE(error.find("expected 4, 5, 8, 12 or 14"), std::string::npos) << error;
  // The image size: whole pixels, both or neither (atoi read 4294967328 as 32, "32px" as 32).
  const std::string body = std::string(kRos).substr(std::string(kRos).find("camera_name"));
  for (const auto& [size, expected] :
       {std::pair{"image_width: 4294967328\nimage_height: 960\n", "z.yaml:1: image_width '4294967328' must be"},
        std::pair{"image_width: 32px\nimage_height: 960\n", "z.yaml:1: image_width '32px' must be a whole number"},
        std::pair{"image_width: 1280\nimage_height: -960\n", "z.yaml:2: image_height '-960' must be"},
        std::pair{"image_width: 1280\n", "z.yaml:1: image_width is given without image_height"},
        std::pair{"image_height: 960\n", "z.yaml:1: image_height is given without image_width"}}) {
    EXPECT_FALSE(ParseCalibration(size + body, "z.yaml", false, &c, &error)) << size;
    EXPECT_NE(error.find(expected), std::string::npos) << error;
  }
  ASSERT_TRUE(ParseCalibration("image_width: 1280\nimage_height: 960\n" + body, "z.yaml", false, &c, &error)) << error;
  EXPECT_EQ(c.width, 1280);
  EXPECT_EQ(c.height, 960);
  EXPECT_FALSE(LoadCalibration("/nonexistent/cal.yml", false, &c, &error));
  EXPECT_EQ(error, "/nonexistent/cal.yml: cannot read the calibration file: No such file or directory");
}

// A directory opens as a file on Linux and reads as nothing, and a read error
// used to end the text early: both are refused, with the file and the reason.
TEST(Calibration, DirectoryAndReadErrorAreRefused) {
  Calibration c;
  std::vector<float> dxdy;
  int cols = 0, rows = 0;
  double step = 0;
  std::string error;
  const std::string dir = testing::TempDir();
  EXPECT_FALSE(LoadCalibration(dir, false, &c, &error));
  EXPECT_EQ(error, dir + ": cannot read the calibration file: is a directory, not a file");
  EXPECT_FALSE(LoadCalibration("/proc/self/mem", false, &c, &error));  // reading offset 0 fails (EIO)
  EXPECT_EQ(error.rfind("/proc/self/mem: cannot read the calibration file: read failed: ", 0), 0u) << error;
  EXPECT_FALSE(LoadDisplacementMesh(dir, &dxdy, &cols, &rows, &step, &error));
  EXPECT_EQ(error, dir + ": cannot read the displacement mesh: is a directory, not a file");
  EXPECT_FALSE(LoadDisplacementMesh("/proc/self/mem", &dxdy, &cols, &rows, &step, &error));
  EXPECT_EQ(error.rfind("/proc/self/mem: cannot read the displacement mesh: read failed: ", 0), 0u) << error;
  EXPECT_FALSE(LoadDisplacementMesh("/nonexistent/m.txt", &dxdy, &cols, &rows, &step, &error));
  EXPECT_EQ(error, "/nonexistent/m.txt: cannot read the displacement mesh: No such file or directory");
}

TEST(Calibration, ScalesToTheSameAspectRatioOrRefuses) {
  Calibration c;
  std::string error;
  ASSERT_TRUE(ParseCalibration(kRos, "ros.yaml", false, &c, &error));
  LensModel m;
  ASSERT_TRUE(FitCalibration(c, 640, 480, &m, &error)) << error;
  EXPECT_DOUBLE_EQ(m.fx, 500.25);
  EXPECT_DOUBLE_EQ(m.cx, (645.25 + 0.5) * 0.5 - 0.5);  // pixel centres at integers
  EXPECT_DOUBLE_EQ(m.cy, (474.5 + 0.5) * 0.5 - 0.5);
  EXPECT_DOUBLE_EQ(m.k[0], 0.5);  // normalised coordinates: unchanged
  EXPECT_FALSE(FitCalibration(c, 1280, 720, &m, &error));
  EXPECT_NE(error.find("1280x960"), std::string::npos) << error;
  EXPECT_NE(error.find("aspect ratio"), std::string::npos) << error;
}

TEST(Calibration, ConfigKeysAndCalibrationFile) {
  // Keys: defaults resolved (fx from the focal length, centre).
  RunConfig rc;
  Origins origins;
  std::string error;
  ASSERT_TRUE(ParseConfig("[distortion]\nmodel = \"brown\"\nk1 = -0.1\nfilter = \"bicubic\"\n", "t.toml", &rc,
                          &origins, &error)) << error;
  ASSERT_TRUE(FinishConfig(&rc, 640, 480, origins, 1, &error)) << error;
  EXPECT_DOUBLE_EQ(rc.core.distortion.lens.cx, 319.5);
  EXPECT_DOUBLE_EQ(rc.core.distortion.lens.fx, 28.0 / (36.0 / 640));
  EXPECT_EQ(rc.core.distortion.filter, ResampleFilter::kBicubic);
  // A bad value names the key and its line.
  RunConfig bad;
  Origins o2;
  ASSERT_TRUE(ParseConfig("[distortion]\nmodel = \"brown\"\nk1 = -0.1\ngrid_step = 12\n", "b.toml", &bad, &o2, &error));
  EXPECT_FALSE(FinishConfig(&bad, 640, 480, o2, 1, &error));
  EXPECT_NE(error.find("b.toml:4"), std::string::npos) << error;
  EXPECT_NE(error.find("distortion.grid_step"), std::string::npos) << error;
  // A calibration file, calibrated at twice the size.
  const std::string path = testing::TempDir() + "camsim_cal_" + std::to_string(getpid()) + ".yaml";
  std::ofstream(path) << kRos;
  RunConfig cal;
  Origins o3;
  ASSERT_TRUE(ParseConfig("[distortion]\ncalibration = \"" + path + "\"\n", "c.toml", &cal, &o3, &error));
  ASSERT_TRUE(FinishConfig(&cal, 640, 480, o3, 1, &error)) << error;
  EXPECT_DOUBLE_EQ(cal.core.distortion.lens.fx, 500.25);
  EXPECT_DOUBLE_EQ(cal.core.distortion.lens.k[3], 0.8);
  // ... and not together with coefficients it sets itself.
  RunConfig both;
  Origins o4;
  ASSERT_TRUE(ParseConfig("[distortion]\ncalibration = \"" + path + "\"\nk2 = 0.1\n", "d.toml", &both, &o4, &error));
  EXPECT_FALSE(FinishConfig(&both, 640, 480, o4, 1, &error));
  EXPECT_NE(error.find("d.toml:3: distortion.k2 is set together with distortion.calibration"), std::string::npos)
      << error;
}

int RunCamsim(const std::string& args) {
  const int status = std::system((std::string(CAMSIM_BINARY) + " " + args + " 2>/dev/null >/dev/null").c_str());
  return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

TEST(Calibration, PatternCommandWritesLoadableTargets) {
  const std::string dir = testing::TempDir() + "camsim_pattern_" + std::to_string(getpid());
  ASSERT_EQ(std::system(("mkdir -p '" + dir + "'").c_str()), 0);
  for (const char* name : {"checkerboard", "dot-grid", "slanted-edge", "siemens-star"}) {
    const std::string out = dir + "/" + name + ".exr";
    ASSERT_EQ(RunCamsim(std::string("pattern ") + name + " --out " + out + " --width 160 --height 120 --supersample 2"), 0)
        << name;
    io::SceneFrame f;
    std::string error;
    ASSERT_TRUE(io::LoadSceneExr(out, "", &f, &error)) << error;
    EXPECT_EQ(f.width, 160);
    float lo = 1e9f, hi = -1e9f;
    for (float v : f.g.data) {
      lo = std::min(lo, v);
      hi = std::max(hi, v);
    }
    EXPECT_NEAR(lo, 0.05f, 1e-6f) << name;
    EXPECT_NEAR(hi, 0.9f, 1e-6f) << name;
  }
  EXPECT_NE(RunCamsim("pattern hexagons --out " + dir + "/x.exr"), 0);
  EXPECT_NE(RunCamsim("pattern checkerboard --out " + dir + "/x.exr --width 2"), 0);
  EXPECT_NE(RunCamsim("pattern checkerboard --out " + dir + "/x.exr --width 12.7"), 0);  // not truncated to 12
  EXPECT_NE(RunCamsim("pattern checkerboard --out " + dir + "/x.exr --supersample 2.5"), 0);
  // It runs through a camera distorting as a calibration file says: made at
  // 640x480, scaled to this 160x120 target (the same aspect ratio) ...
  const std::string cal = dir + "/cal.yml";
  std::ofstream(cal) << kOpenCv;
  EXPECT_EQ(RunCamsim("run --input " + dir + "/dot-grid.exr --out " + dir + "/out --calibration " + cal + " --quiet"), 0);
  // The calibration moved the dots: the raw frame differs from a run without
  // it (the same seed and frame, so the same noise).
  EXPECT_EQ(RunCamsim("run --input " + dir + "/dot-grid.exr --out " + dir + "/plain --quiet"), 0);
  const auto bytes = [](const std::string& path) {
    std::ifstream in(path, std::ios::binary);
    return std::string(std::istreambuf_iterator<char>(in), {});
  };
  const std::string distorted = bytes(dir + "/out/dot-grid.raw"), plain = bytes(dir + "/plain/dot-grid.raw");
  ASSERT_EQ(distorted.size(), 160u * 120u * 2u);
  ASSERT_EQ(plain.size(), distorted.size());
  size_t moved = 0;
  for (size_t i = 0; i < plain.size(); i += 2) moved += plain.compare(i, 2, distorted, i, 2) != 0;
  EXPECT_GT(moved, plain.size() / 2 / 10) << "samples changed by the calibration";
  // ... and refused for a 16:9 one.
  ASSERT_EQ(RunCamsim("pattern dot-grid --out " + dir + "/wide.exr --width 160 --height 90 --supersample 1"), 0);
  EXPECT_EQ(RunCamsim("run --input " + dir + "/wide.exr --out " + dir + "/out2 --calibration " + cal + " --quiet"), 1);
  // A lens the file gives that the stage refuses names the file, not a --set.
  std::string zero_fx = kOpenCv;
  zero_fx.replace(zero_fx.find("5.3591573396163199e+02"), 22, "0.");
  const std::string bad = dir + "/zero_fx.yml";
  std::ofstream(bad) << zero_fx;
  const std::string err = dir + "/err.txt";
  EXPECT_NE(std::system((std::string(CAMSIM_BINARY) + " run --input " + dir + "/dot-grid.exr --out " + dir +
                         "/out3 --calibration " + bad + " --quiet 2>'" + err + "' >/dev/null")
                            .c_str()),
            0);
  std::ifstream in(err);
  const std::string text((std::istreambuf_iterator<char>(in)), {});
  EXPECT_NE(text.find("--calibration '" + bad + "': distortion.calibration gives distortion.fx"), std::string::npos)
      << text;
}

}  // namespace
}  // namespace camsim::host
