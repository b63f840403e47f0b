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
  count.replace(count.find("cols: 8"), 7, "cols: 6");
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
  // A lens the file gives that the stage refuses names the file, not a --set:
  // k1 = -5 folds inside the frame.
  std::string fold = kOpenCv;
  fold.replace(fold.find("-2.6637260909660682e-01"), 23, "-5.");
  const std::string bad = dir + "/fold.yml";
  std::ofstream(bad) << fold;
  const std::string err = dir + "/err.txt";
  EXPECT_NE(std::system((std::string(CAMSIM_BINARY) + " run --input " + dir + "/dot-grid.exr --out " + dir +
                         "/out3 --calibration " + bad + " --quiet 2>'" + err + "' >/dev/null")
                            .c_str()),
            0);
  std::ifstream in(err);
  const std::string text((std::istreambuf_iterator<char>(in)), {});
  // (It read "distortion.calibration gives distortion.k1 the radial model folds over ...".)
  EXPECT_NE(text.find("--calibration '" + bad + "': distortion.k1 (set by the calibration file): the radial model "
                      "folds over"),
            std::string::npos)
      << text;
}

// An OpenCV file with the given camera_matrix and distortion_coefficients data
// (and image size line, if any).
std::string OpenCvFile(const std::string& matrix, const std::string& coefficients, const std::string& size = "") {
  return "%YAML:1.0\n---\n" + size + "camera_matrix: !!opencv-matrix\n   rows: 3\n   cols: 3\n   dt: d\n   data: [ " +
         matrix + " ]\ndistortion_coefficients: !!opencv-matrix\n   rows: 5\n   cols: 1\n   dt: d\n   data: [ " +
         coefficients + " ]\n";
}

// Writes `text` to a temporary file named `name`, returns its path.
std::string TempFile(const std::string& name, const std::string& text) {
  const std::string path = testing::TempDir() + "camsim_" + std::to_string(getpid()) + "_" + name;
  std::ofstream(path) << text;
  return path;
}

// Configures a run of width x height with `toml` (plus `calibration`, a file
// path, as distortion.calibration); false and *error on failure.
bool Configure(const std::string& toml, const std::string& calibration, int width, int height, RunConfig* rc,
               std::string* error) {
  Origins origins;
  std::string text = toml;
  if (!calibration.empty()) text += "\n[distortion]\ncalibration = \"" + calibration + "\"\n";
  if (!ParseConfig(text, "t.toml", rc, &origins, error)) return false;
  return FinishConfig(rc, width, height, origins, 1, error);
}

// A misspelt or missing distortion_coefficients used to give a lens without
// distortion; a camera without distortion says so with zeros.
TEST(Calibration, DistortionCoefficientsAreRequired) {
  Calibration c;
  std::string error;
  std::string misspelt = kOpenCv;
  misspelt.replace(misspelt.find("distortion_coefficients"), 23, "distortion_coeficients");
  EXPECT_FALSE(ParseCalibration(misspelt, "a.yml", false, &c, &error));
  EXPECT_NE(error.find("a.yml: no distortion_coefficients (required"), std::string::npos) << error;
  const std::string no_coefficients = std::string(kOpenCv).substr(0, std::string(kOpenCv).find("distortion_coeff"));
  EXPECT_FALSE(ParseCalibration(no_coefficients, "b.yml", false, &c, &error));
  EXPECT_NE(error.find("b.yml: no distortion_coefficients"), std::string::npos) << error;
  // An empty list is not "no distortion" either.
  std::string empty = kRos;
  empty.replace(empty.find("cols: 8\n  data: [0.5, -0.1, 0.0012, -0.0007, 0.01, 0.8, 0.05, 0.0]"), 66,
                "cols: 0\n  data: []");
  EXPECT_FALSE(ParseCalibration(empty, "e.yaml", false, &c, &error));
  EXPECT_NE(error.find("e.yaml:9: expected 4, 5, 8, 12 or 14 distortion coefficients"), std::string::npos) << error;
  // Zeros: an undistorted lens.
  ASSERT_TRUE(ParseCalibration(OpenCvFile("500, 0, 319.5, 0, 500, 239.5, 0, 0, 1", "0, 0, 0, 0, 0"), "z.yml", false,
                               &c, &error)) << error;
  EXPECT_EQ(c.lens.model, DistortionModel::kBrown);
  EXPECT_EQ(c.lens.k[0], 0.0);
  // A ROS camera_info message dump (K:, D:) is not read, and says so.
  const std::string message = "height: 480\nwidth: 640\ndistortion_model: \"plumb_bob\"\nD: [-0.2, 0.05, 0.0, 0.0, 0.0]\n"
                              "K: [500.0, 0.0, 319.5, 0.0, 500.0, 239.5, 0.0, 0.0, 1.0]\n";
  EXPECT_FALSE(ParseCalibration(message, "m.yaml", false, &c, &error));
  EXPECT_NE(error.find("m.yaml: no camera_matrix"), std::string::npos) << error;
  EXPECT_NE(error.find("a camera_info message dump (K:, D:) is not read"), std::string::npos) << error;
}

// fx and fy were never checked: with zero coefficients the distortion stage
// is an identity and skips its own checks, so a negative focal length ran.
TEST(Calibration, FocalLengthsMustBeOneToAMillionPixels) {
  Calibration c;
  std::string error;
  for (const auto& [matrix, expected] :
       {std::pair{"-500, 0, 319.5, 0, 500, 239.5, 0, 0, 1", "f.yml:3: camera_matrix fx = -500 must be a focal length"},
        std::pair{"500, 0, 319.5, 0, 0.5, 239.5, 0, 0, 1", "f.yml:3: camera_matrix fy = 0.5 must be a focal length"},
        std::pair{"0, 0, 319.5, 0, 500, 239.5, 0, 0, 1", "f.yml:3: camera_matrix fx = 0 must be"},
        std::pair{"2e6, 0, 319.5, 0, 500, 239.5, 0, 0, 1", "f.yml:3: camera_matrix fx = 2e+06 must be"}}) {
    EXPECT_FALSE(ParseCalibration(OpenCvFile(matrix, "0, 0, 0, 0, 0"), "f.yml", false, &c, &error)) << matrix;
    EXPECT_NE(error.find(expected), std::string::npos) << error;
  }
  ASSERT_TRUE(ParseCalibration(OpenCvFile("1, 0, 319.5, 0, 1, 239.5, 0, 0, 1", "0, 0, 0, 0, 0"), "f.yml", false, &c,
                               &error)) << error;
  // Through the config (the path `camsim run --calibration` takes).
  const std::string path = TempFile("negative_fx.yml", OpenCvFile("-500, 0, 79.5, 0, 500, 59.5, 0, 0, 1", "0, 0, 0, 0, 0"));
  RunConfig rc;
  EXPECT_FALSE(Configure("", path, 160, 120, &rc, &error));
  EXPECT_NE(error.find(path + ":3: camera_matrix fx = -500"), std::string::npos) << error;
  // Scaled down below 1 pixel.
  const std::string small =
      TempFile("small_fx.yml", OpenCvFile("1.5, 0, 319.5, 0, 1.5, 239.5, 0, 0, 1", "0, 0, 0, 0, 0",
                                          "image_width: 640\nimage_height: 480\n"));
  RunConfig rs;
  EXPECT_FALSE(Configure("", small, 160, 120, &rs, &error));
  EXPECT_NE(error.find(small + ":5: camera_matrix fx, fy = 0.375, 0.375 (scaled from 640x480) at the 160x120 sensor"),
            std::string::npos) << error;
}

// The principal point was never checked against the sensor when the file has
// no image size (and not at all with zero coefficients).
TEST(Calibration, PrincipalPointMustBeOnTheSensor) {
  std::string error;
  for (const char* matrix : {"500, 0, 160, 0, 500, 59.5, 0, 0, 1", "500, 0, 79.5, 0, 500, -1, 0, 0, 1",
                             "500, 0, -0.25, 0, 500, 59.5, 0, 0, 1"})
    for (const char* coefficients : {"0, 0, 0, 0, 0", "-0.1, 0, 0, 0, 0"}) {
      const std::string path = TempFile("pp.yml", OpenCvFile(matrix, coefficients));
      RunConfig rc;
      EXPECT_FALSE(Configure("", path, 160, 120, &rc, &error)) << matrix << " / " << coefficients;
      EXPECT_NE(error.find(path + ":3: camera_matrix principal point (cx, cy) = ("), std::string::npos) << error;
      EXPECT_NE(error.find("is outside the 160x120 sensor's pixels [0, 159] x [0, 119]"), std::string::npos) << error;
    }
  // The frame's corner pixel centres are on it.
  for (const char* matrix : {"500, 0, 0, 0, 500, 0, 0, 0, 1", "500, 0, 159, 0, 500, 119, 0, 0, 1"}) {
    RunConfig rc;
    EXPECT_TRUE(Configure("", TempFile("pp_ok.yml", OpenCvFile(matrix, "-0.1, 0, 0, 0, 0")), 160, 120, &rc, &error))
        << matrix << ": " << error;
  }
  // With an image size, after scaling: 639.75 at 640x480 is 159.5625 at 160x120.
  const std::string scaled = TempFile("pp_scaled.yml", OpenCvFile("500, 0, 639.75, 0, 500, 239.5, 0, 0, 1",
                                                                  "0, 0, 0, 0, 0", "image_width: 640\nimage_height: 480\n"));
  RunConfig rc;
  EXPECT_FALSE(Configure("", scaled, 160, 120, &rc, &error));
  EXPECT_NE(error.find("(159.562, 59.5) (scaled from 640x480) is outside the 160x120"), std::string::npos) << error;
}

// Motion blur and cos4 vignetting took fx = fy = focal_length_mm / pitch and
// the frame centre while distortion used the calibration's camera.
TEST(Calibration, MotionBlurAndVignettingUseTheCalibratedCamera) {
  std::string error;
  const std::string path = TempFile("camera.yml", OpenCvFile("400, 0, 70.5, 0, 441, 65.25, 0, 0, 1", "0, 0, 0, 0, 0"));
  RunConfig rc;
  ASSERT_TRUE(Configure("[motion]\nsource = \"camera\"\nangular_velocity_rad_s = [0.0, 0.5, 0.0]\n"
                        "[vignetting]\nmode = \"cos4\"\n",
                        path, 160, 120, &rc, &error)) << error;
  EXPECT_DOUBLE_EQ(rc.core.motion_blur.fx_px, 400.0);
  EXPECT_DOUBLE_EQ(rc.core.motion_blur.fy_px, 441.0);
  EXPECT_DOUBLE_EQ(rc.core.motion_blur.cx_px, 70.5);
  EXPECT_DOUBLE_EQ(rc.core.motion_blur.cy_px, 65.25);
  EXPECT_DOUBLE_EQ(rc.core.vignetting.focal_length_px, 420.0);  // sqrt(400 * 441)
  // Without a calibration: from the focal length and pitch, the centre.
  RunConfig plain;
  ASSERT_TRUE(Configure("[motion]\nsource = \"camera\"\n[vignetting]\nmode = \"cos4\"\n", "", 160, 120, &plain,
                        &error)) << error;
  EXPECT_DOUBLE_EQ(plain.core.motion_blur.fx_px, 28.0 / (36.0 / 160));
  EXPECT_DOUBLE_EQ(plain.core.vignetting.focal_length_px, 28.0 / (36.0 / 160));
  EXPECT_LT(plain.core.motion_blur.cx_px, 0.0);  // the centre
  // Setting them beside a calibration is refused like the distortion keys.
  for (const char* key : {"[motion]\nfx_px = 300.0\n", "[motion]\ncy_px = 10.0\n", "[vignetting]\nfocal_length_px = 90.0\n"}) {
    RunConfig both;
    EXPECT_FALSE(Configure(key, path, 160, 120, &both, &error)) << key;
    EXPECT_NE(error.find("t.toml:2: "), std::string::npos) << error;
    EXPECT_NE(error.find("is set together with distortion.calibration, which sets it too"), std::string::npos) << error;
  }
  // A stage refusing the calibrated camera names the file: fx = 4 px is too wide a view for motion blur.
  const std::string wide = TempFile("wide.yml", OpenCvFile("4, 0, 79.5, 0, 4, 59.5, 0, 0, 1", "0, 0, 0, 0, 0"));
  RunConfig w;
  Origins origins;
  ASSERT_TRUE(ParseConfig("[motion]\nsource = \"camera\"\nangular_velocity_rad_s = [0.0, 0.5, 0.0]\n", "t.toml", &w,
                          &origins, &error));
  ASSERT_TRUE(ApplyOverride("distortion.calibration='" + wide + "'", &w, &origins, &error)) << error;
  EXPECT_FALSE(FinishConfig(&w, 160, 120, origins, 1, &error));
  EXPECT_NE(error.find("--set distortion.calibration='" + wide +
                       "': motion.fx_px (set by the calibration file): field of view too wide"),
            std::string::npos)
      << error;
}

// distortion.model beside a calibration was silently ignored unless it was
// "fisheye" for an OpenCV file's 4 coefficients (their only way to say so).
TEST(Calibration, ModelKeyOnlyNamesAnOpenCvFilesModel) {
  std::string error;
  const std::string ros = TempFile("model_ros.yaml", kRos);
  for (const char* model : {"fisheye", "brown", "off"}) {
    RunConfig rc;
    EXPECT_FALSE(Configure(std::string("[distortion]\nmodel = \"") + model + "\"\n", "", 640, 480, &rc, &error) &&
                 Configure(std::string("[distortion]\nmodel = \"") + model + "\"\ncalibration = \"" + ros + "\"\n",
                           "", 640, 480, &rc, &error))
        << model;
    EXPECT_NE(error.find("t.toml:2: distortion.model"), std::string::npos) << model << ": " << error;
    EXPECT_NE(error.find("set together with distortion.calibration"), std::string::npos) << error;
  }
  EXPECT_NE(error.find("with a calibration it may only say brown or fisheye"), std::string::npos) << error;
  RunConfig rc;
  EXPECT_FALSE(Configure("[distortion]\nmodel = \"brown\"\ncalibration = \"" + ros + "\"\n", "", 640, 480, &rc,
                         &error));
  EXPECT_NE(error.find("whose file names its model (distortion_model: rational_polynomial)"), std::string::npos)
      << error;
  // An OpenCV file's 4 coefficients: the model key says fisheye.
  const std::string opencv = TempFile("model_opencv.yml", OpenCvFile("500, 0, 319.5, 0, 500, 239.5, 0, 0, 1",
                                                                     "0.05, -0.01, 0.003, -0.0005"));
  std::string four = OpenCvFile("500, 0, 319.5, 0, 500, 239.5, 0, 0, 1", "0.05, -0.01, 0.003, -0.0005");
  four.replace(four.find("rows: 5"), 7, "rows: 4");
  std::ofstream(opencv) << four;
  RunConfig fish;
  ASSERT_TRUE(Configure("[distortion]\nmodel = \"fisheye\"\ncalibration = \"" + opencv + "\"\n", "", 640, 480,
                        &fish, &error)) << error;
  EXPECT_EQ(fish.core.distortion.lens.model, DistortionModel::kFisheye);
}

// rows/cols were never read, a repeated key took the first, and '#' comments
// broke the values they followed.
TEST(Calibration, ParserChecksRowsColsRepeatsAndReadsComments) {
  Calibration c;
  std::string error;
  std::string rows = kOpenCv;
  rows.replace(rows.find("rows: 3"), 7, "rows: 2");
  EXPECT_FALSE(ParseCalibration(rows, "r.yml", false, &c, &error));
  EXPECT_NE(error.find("r.yml:6: camera_matrix says rows: 2, cols: 3 (6 values) but its data has 9"), std::string::npos)
      << error;
  std::string shape = kRos;
  shape.replace(shape.find("rows: 3\n  cols: 3"), 17, "rows: 1\n  cols: 9");
  EXPECT_FALSE(ParseCalibration(shape, "s.yaml", false, &c, &error));
  EXPECT_NE(error.find("s.yaml:4: camera_matrix must be rows: 3, cols: 3, is 1x9"), std::string::npos) << error;
  std::string cols = kRos;
  cols.replace(cols.find("cols: 8"), 7, "cols: 7");
  EXPECT_FALSE(ParseCalibration(cols, "c.yaml", false, &c, &error));
  EXPECT_NE(error.find("c.yaml:9: distortion_coefficients says rows: 1, cols: 7"), std::string::npos) << error;
  std::string only_rows = kRos;
  only_rows.erase(only_rows.find("  cols: 8\n"), 10);
  EXPECT_FALSE(ParseCalibration(only_rows, "o.yaml", false, &c, &error));
  EXPECT_NE(error.find("o.yaml:9: distortion_coefficients has 'rows:' without 'cols:'"), std::string::npos) << error;
  // A key given twice: the second is not silently dropped.
  const std::string twice = std::string(kRos) + "camera_matrix:\n  rows: 3\n  cols: 3\n  data: [1, 0, 1, 0, 1, 1, 0, 0, 1]\n";
  EXPECT_FALSE(ParseCalibration(twice, "t.yaml", false, &c, &error));
  EXPECT_NE(error.find("t.yaml:17: camera_matrix is given twice"), std::string::npos) << error;
  // Review finding: an EXR given as the calibration read as "c_bin.yaml:54:  is given twice" (an empty key).
  std::string binary = kRos;
  binary.insert(binary.find("camera_matrix"), std::string("v\x01\x00\x00:\n", 6));
  EXPECT_FALSE(ParseCalibration(binary, "b.yaml", false, &c, &error));
  EXPECT_NE(error.find("b.yaml:4: not a calibration file: binary data (byte 0x01)"), std::string::npos) << error;
  EXPECT_FALSE(ParseCalibration(std::string(kRos) + ":x\n:y\n", "e.yaml", false, &c, &error));
  EXPECT_NE(error.find("e.yaml:17: not a calibration file: a line starts with ':'"), std::string::npos) << error;
  const std::string exr = CAMSIM_SOURCE_DIR "/scenes/aisle_0001.exr";
  EXPECT_FALSE(LoadCalibration(exr, false, &c, &error));
  EXPECT_NE(error.find(exr + ":1: not a calibration file: binary data"), std::string::npos) << error;
  std::string data_twice = kRos;
  data_twice.insert(data_twice.find("distortion_model"), "  data: [1, 0, 1, 0, 1, 1, 0, 0, 1]\n");
  EXPECT_FALSE(ParseCalibration(data_twice, "d.yaml", false, &c, &error));
  EXPECT_NE(error.find("d.yaml:4: camera_matrix has 'data:' twice"), std::string::npos) << error;
  // Comments: after values, inside a list, on their own lines; not inside quotes.
  const std::string commented = R"(# from the lab's rig
image_width: 1280   # pixels
image_height: 960
camera_name: "rig # 2"
camera_matrix:   # K
  rows: 3  # three
  cols: 3
  data: [1000.5, 0.0, 645.25,  # fx 0 cx
         0.0, 1001.0, 474.5,
         0.0, 0.0, 1.0]
distortion_model: rational_polynomial # k1 k2 p1 p2 k3 k4 k5 k6
distortion_coefficients:
  rows: 1
  cols: 8
  data: [0.5, -0.1, 0.0012, -0.0007, 0.01, 0.8, 0.05, 0.0]
#distortion_coefficients: commented out, not a repeat
)";
  ASSERT_TRUE(ParseCalibration(commented, "k.yaml", false, &c, &error)) << error;
  EXPECT_EQ(c.width, 1280);
  EXPECT_DOUBLE_EQ(c.lens.cx, 645.25);
  EXPECT_DOUBLE_EQ(c.lens.fy, 1001.0);
  EXPECT_DOUBLE_EQ(c.lens.k[3], 0.8);
}

}  // namespace
}  // namespace camsim::host
