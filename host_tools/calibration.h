// Camera calibrations from files: OpenCV cv::FileStorage YAML (camera_matrix,
// distortion_coefficients as !!opencv-matrix, optional image_width/height,
// as written by OpenCV's calibration sample) and ROS camera_info YAML as
// camera_calibration_parsers writes it (camera_matrix /
// distortion_coefficients with rows, cols, data; distortion_model plumb_bob,
// rational_polynomial or equidistant). A camera_info message dump (K:, D:) is
// not read.
//
// Both camera_matrix and distortion_coefficients are required (a lens
// without distortion lists zeros). A matrix's rows and cols, when given, must
// match its data; a top-level key given twice is refused; '#' comments
// (outside quotes) are ignored. fx and fy must be 1 to 1e6 pixels.
//
// OpenCV files do not say which model their coefficients belong to: 4, 5, 8
// (or 12, 14 with zero thin-prism/tilt terms) coefficients are Brown-Conrady
// (k1 k2 p1 p2 [k3 [k4 k5 k6]]); a cv::fisheye calibration (k1..k4, also 4
// numbers) needs `fisheye` passed (config distortion.model = "fisheye"; the
// config may set the model only for such files, to brown or fisheye).
// Non-zero thin-prism (s1..s4) or tilt (tauX, tauY) terms and a non-zero skew
// are refused: camsim does not model them.
//
// The run's camera is the calibration's (host_tools/config.cc): distortion,
// the flare environment and motion blur take its fx, fy, cx, cy; cos4
// vignetting (one focal length, centred on the frame) takes sqrt(fx fy).
#pragma once

#include <string>
#include <vector>

#include "core/lens/lens_model.h"

namespace camsim::host {

struct Calibration {
  LensModel lens;
  int width = 0, height = 0;  // image size the calibration was made at; 0 = not given
  bool names_model = false;   // the file gives distortion_model (ROS)
  std::string model_name;     // ... its value
  std::string source;         // the file, and camera_matrix's line in it, for FitCalibration's errors
  int matrix_line = 0;
};

// Parses calibration text; `source` names it in errors. `fisheye_hint`: the
// caller's configured model is fisheye (for OpenCV files' 4 coefficients).
bool ParseCalibration(const std::string& text, const std::string& source, bool fisheye_hint, Calibration* out,
                      std::string* error);
bool LoadCalibration(const std::string& path, bool fisheye_hint, Calibration* out, std::string* error);

// A displacement mesh (core/lens/distortion.h DisplacementMesh) from text:
//   # comments
//   step S          pixels between nodes
//   size COLS ROWS
//   dx dy dx dy ... COLS * ROWS pairs, row-major (any whitespace)
bool LoadDisplacementMesh(const std::string& path, std::vector<float>* dxdy, int* cols, int* rows, double* step,
                          std::string* error);

// Adapts a calibration to a sensor of width x height. The same size: as is.
// The same aspect ratio (w * H == W * h): the camera matrix is scaled by W/w,
// with pixel centres at integer coordinates: c' = (c + 0.5) s - 0.5 (the
// distortion coefficients are in normalised coordinates and stay). Another
// aspect ratio is refused (a crop's offset is unknown), and so is a principal
// point outside the sensor's pixel centres [0, W-1] x [0, H-1] or a focal
// length below 1 pixel after scaling.
bool FitCalibration(const Calibration& cal, int width, int height, LensModel* lens, std::string* error);

}  // namespace camsim::host
