// The run configuration: the core's PipelineConfig plus what only the host
// needs (scene fitting, file paths, output depth), read from TOML.
//
// One table of fields (config.cc) drives parsing, --set overrides, range and
// typo errors (with the file and line), and `camsim config --default`.
#pragma once

#include <map>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "core/control/auto_exposure.h"
#include "core/control/metering.h"
#include "core/pipeline/pipeline.h"
#include "host_tools/io/environment_map.h"

namespace camsim::host {

enum class SceneFit { kCrop, kScale };

struct RunConfig {
  RunConfig() { core.distortion.lens.cx = core.distortion.lens.cy = -1.0; }  // -1 = frame centre
  PipelineConfig core;
  // Sensor size; 0 = the input's size. When it differs from the input, the
  // scene is centre-cropped (fit = crop; the sensor must not be larger) or
  // resampled by area averaging (fit = scale; aspect ratio may change).
  int width = 0;
  int height = 0;
  SceneFit fit = SceneFit::kCrop;
  // Pixel pitch; 0 = the sensor is 36 mm wide (the bundled Blender camera).
  double pixel_pitch_um = 0.0;
  double focal_length_mm = 28.0;  // lens focal length (the bundled scenes: 28 mm)
  std::string vignetting_mask;    // mask image path (vignetting.mode = "mask")
  std::string calibration;        // OpenCV / ROS calibration YAML (distortion.calibration)
  std::string mesh;               // displacement mesh text file (distortion.mesh)
  // The loaded mesh, shared by copies (core.distortion.mesh points into it).
  std::shared_ptr<const std::vector<float>> mesh_data;
  std::string defects_file;       // listed defect pixels (sensor.defects_file, host_tools/defects_file.h)
  // The loaded list, shared by copies (core.sensor.defects points into it).
  std::shared_ptr<const std::vector<DefectPixel>> defects_data;
  std::string environment_map;    // lat-long HDR EXR for flare (flare.environment_map)
  // The loaded map, shared by copies (core.flare.environment points into it);
  // loaded only when flare is on, and again only when the path changes.
  std::shared_ptr<const io::EnvironmentMap> environment_data;
  int output_bits = 8;            // ISP output PNG depth: 8 or 16
  // Auto exposure (core/control/auto_exposure.h), run frame to frame by `camsim run`.
  AutoExposureConfig auto_exposure;
  Metering metering = Metering::kUniform;
  std::string metering_image;     // metering = "image": weight map (PNG or EXR), sensor-sized
  bool meter_input = false;       // measure the input (ideal sensor) instead of the raw output
};

// Where each key was set, for error messages: "file:line" or "--set KEY=VALUE"
// (the argument as given).
using Origins = std::map<std::string, std::string>;

// Parses TOML text into *config (starting from its current values). Unknown
// sections or keys, wrong types and wrong array lengths are errors naming the
// key and line. Range checks happen in the core (ValidateConfig).
bool ParseConfig(const std::string& text, const std::string& source_name, RunConfig* config, Origins* origins,
                 std::string* error);
// Reads a configuration file. A relative path in a file-valued key
// (sensor.defects_file, distortion.calibration, distortion.mesh,
// vignetting.mask, flare.environment_map, auto_exposure.metering_image) is
// taken relative to the file's directory (the one `path` names; through a
// symbolic link, the real file's; a pipe has none: the current directory).
// ParseConfig and ApplyOverride leave paths as given (relative to the
// current directory).
bool LoadConfigFile(const std::string& path, RunConfig* config, Origins* origins, std::string* error);
// Applies one `section.key=value` override (value in TOML syntax; bare words are taken as strings).
bool ApplyOverride(const std::string& assignment, RunConfig* config, Origins* origins, std::string* error);

// The annotated default configuration (every section and key, with units).
std::string DefaultConfigToml();
// The configuration as TOML (same layout, current values).
std::string ConfigToToml(const RunConfig& config, bool annotated);

// Names every key the parser accepts ("section.key").
std::vector<std::string> ConfigKeys();

// The files a configuration reads besides its scene, as (key, path) for each
// path key that is set: what no output of a run may overwrite. A relative
// path read from a configuration file (LoadConfigFile) has that file's
// directory in front already; one from --set is relative to the current
// directory.
std::vector<std::pair<std::string, std::string>> ConfigInputFiles(const RunConfig& config);

// Fills in derived values (focal length in pixels, sizes) once the input size
// is known, then runs the core's validation; errors name the key and its origin.
// previous: a pipeline in use whose results the validation may reuse
// (Pipeline::Configure's `previous`), or nullptr. configured (optional):
// receives the pipeline the validation configured from the finished
// configuration with `workers`, ready for Init (null on failure); it reads
// data `*config` holds (defect list, mesh, maps), so keep that alive.
bool FinishConfig(RunConfig* config, int input_width, int input_height, const Origins& origins, int workers,
                  std::string* error, const Pipeline* previous = nullptr,
                  std::unique_ptr<Pipeline>* configured = nullptr);

// "ORIGIN: key" (where the key was set, then its name), or the key alone when
// its origin is not known: how an error about a key's file starts.
std::string KeyWhere(const Origins& origins, const std::string& key);

// Text of a core Status, with the origin of its field when known:
// "ORIGIN: field message" when the message goes on from the field's name,
// starting with "must", "needs", "is" or "holds" ("f.toml:3: sensor.adc_bits
// must be 8 to 16"), else "ORIGIN: field: message" ("--set distortion.k1=-5:
// distortion.k1: the radial model folds over ...").
std::string DescribeStatus(const Status& status, const Origins& origins);

}  // namespace camsim::host
