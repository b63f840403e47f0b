#include "host_tools/config.h"
#include "host_tools/defects_file.h"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <functional>
#include <sstream>

#include <sys/stat.h>

#include <toml++/toml.h>

#include "host_tools/calibration.h"
#include "host_tools/io/text_read.h"

namespace camsim::host {
namespace {

enum class Kind { kNumber, kInteger, kBool, kEnum, kNumberArray, kString, kStringArray };

struct Field {
  const char* section;
  const char* key;
  Kind kind;
  const char* doc;
  // Numbers, integers, bools: a reference into the config.
  std::function<double&(RunConfig&)> number;
  std::function<int&(RunConfig&)> integer;
  std::function<bool&(RunConfig&)> boolean;
  // Enums: names and accessors.
  std::vector<const char*> choices;
  std::function<int(const RunConfig&)> get_enum;
  std::function<void(RunConfig&, int)> set_enum;
  // Number arrays: storage, count limits and the count's location (may be null).
  std::function<double*(RunConfig&)> array;
  int min_count = 0, max_count = 0;
  std::function<int*(RunConfig&)> count;
  // Strings and string arrays.
  std::function<std::string(const RunConfig&)> get_text;
  std::function<bool(RunConfig&, const std::vector<std::string>&, std::string*)> set_text;
};

Field Make(const char* section, const char* key, Kind kind, const char* doc) {
  Field f;
  f.section = section;
  f.key = key;
  f.kind = kind;
  f.doc = doc;
  return f;
}

Field Number(const char* s, const char* k, const char* doc, std::function<double&(RunConfig&)> ref) {
  Field f = Make(s, k, Kind::kNumber, doc);
  f.number = std::move(ref);
  return f;
}
Field Integer(const char* s, const char* k, const char* doc, std::function<int&(RunConfig&)> ref) {
  Field f = Make(s, k, Kind::kInteger, doc);
  f.integer = std::move(ref);
  return f;
}
Field Bool(const char* s, const char* k, const char* doc, std::function<bool&(RunConfig&)> ref) {
  Field f = Make(s, k, Kind::kBool, doc);
  f.boolean = std::move(ref);
  return f;
}
template <typename E>
Field Enum(const char* s, const char* k, const char* doc, std::vector<const char*> names,
           std::function<E&(RunConfig&)> ref) {
  Field f = Make(s, k, Kind::kEnum, doc);
  f.choices = std::move(names);
  f.get_enum = [ref](const RunConfig& c) { return static_cast<int>(ref(const_cast<RunConfig&>(c))); };
  f.set_enum = [ref](RunConfig& c, int v) { ref(c) = static_cast<E>(v); };
  return f;
}
Field Array(const char* s, const char* k, const char* doc, int min_count, int max_count,
            std::function<double*(RunConfig&)> data, std::function<int*(RunConfig&)> count = nullptr) {
  Field f = Make(s, k, Kind::kNumberArray, doc);
  f.array = std::move(data);
  f.min_count = min_count;
  f.max_count = max_count;
  f.count = std::move(count);
  return f;
}

// A TOML basic string that reads back as exactly `s`.
std::string TomlString(const std::string& s) {
  std::string t = "\"";
  for (const char ch : s) {
    const unsigned char u = static_cast<unsigned char>(ch);
    if (ch == '"' || ch == '\\') {
      t += '\\';
      t += ch;
    } else if (u < 0x20 || u == 0x7F) {
      char buf[8];
      std::snprintf(buf, sizeof buf, "\\u%04X", u);
      t += buf;
    } else {
      t += ch;
    }
  }
  return t + "\"";
}

// Every configuration key, in the order `config --default` prints them.
const std::vector<Field>& Fields() {
  static const std::vector<Field> fields = [] {
    std::vector<Field> v;
    // [pipeline]
    Field stages = Make("pipeline", "stages", Kind::kStringArray,
                 "stages in run order; a stage not listed does not run. All, in the default order: flare, dof_gather, "
                 "dof_rows, dof_columns, motion_blur, distortion, exposure, vignetting, cfa, blooming, "
                 "sensor, black_level, white_balance, demosaic, color_matrix, gamma");
    stages.get_text = [](const RunConfig& c) {
      std::string t = "[";
      for (int i = 0; i < c.core.order_count; ++i)
        t += std::string(i ? ", \"" : "\"") + StageName(c.core.order[i]) + "\"";
      return t + "]";
    };
    stages.set_text = [](RunConfig& c, const std::vector<std::string>& names, std::string* err) {
      if (names.empty() || names.size() > static_cast<size_t>(kStageCount)) {
        *err = "must list 1 to " + std::to_string(kStageCount) + " stages";
        return false;
      }
      StageId order[kStageCount];
      for (size_t i = 0; i < names.size(); ++i) {
        if (!StageFromName(names[i].c_str(), &order[i])) {
          *err = "unknown stage '" + names[i] + "'";
          return false;
        }
        if (std::find(order, order + i, order[i]) != order + i) {
          *err = "lists stage '" + names[i] + "' twice";
          return false;
        }
      }
      std::copy(order, order + names.size(), c.core.order);
      c.core.order_count = static_cast<int>(names.size());
      return true;
    };
    v.push_back(stages);
    Field seed = Make("pipeline", "seed", Kind::kInteger, "keys all randomness with (frame, x, y, channel); 0 .. 2^53");
    seed.get_text = [](const RunConfig& c) { return std::to_string(c.core.seed); };
    seed.set_text = nullptr;
    v.push_back(seed);

    // [sensor]
    v.push_back(Integer("sensor", "width", "pixels; 0 = the input's width", [](RunConfig& c) -> int& { return c.width; }));
    v.push_back(Integer("sensor", "height", "pixels; 0 = the input's height", [](RunConfig& c) -> int& { return c.height; }));
    v.push_back(Enum<SceneFit>("sensor", "scene_fit",
                               "when the sensor size differs from the input: crop (centre) or scale (area average)",
                               {"crop", "scale"}, [](RunConfig& c) -> SceneFit& { return c.fit; }));
    v.push_back(Enum<Cfa>("sensor", "cfa", "colour filter array (GenICam names)",
                          {"Mono", "BayerRG", "BayerGR", "BayerGB", "BayerBG"},
                          [](RunConfig& c) -> Cfa& { return c.core.geometry.cfa; }));
    v.push_back(Integer("sensor", "adc_bits", "ADC resolution, 8 .. 16 bits",
                        [](RunConfig& c) -> int& { return c.core.geometry.adc_bits; }));
    v.push_back(Number("sensor", "pixel_pitch_um", "micrometres; 0 = sensor 36 mm wide (the bundled scenes' camera)",
                       [](RunConfig& c) -> double& { return c.pixel_pitch_um; }));
    v.push_back(Array("sensor", "quantum_efficiency", "QE for R, G, B (mono uses G), 0 .. 1", 3, 3,
                      [](RunConfig& c) { return c.core.sensor.quantum_efficiency; }));
    v.push_back(Number("sensor", "full_well_e", "saturation capacity, electrons (1 .. 1e6)",
                       [](RunConfig& c) -> double& { return c.core.sensor.full_well_e; }));
    v.push_back(Number("sensor", "system_gain_dn_per_e", "K at 0 dB gain, DN per electron",
                       [](RunConfig& c) -> double& { return c.core.sensor.system_gain_dn_per_e; }));
    v.push_back(Number("sensor", "gain_db", "analog gain, dB (0 .. 48); multiplies K",
                       [](RunConfig& c) -> double& { return c.core.sensor.gain_db; }));
    v.push_back(Number("sensor", "dark_noise_e", "temporal dark (read) noise, electrons rms",
                       [](RunConfig& c) -> double& { return c.core.sensor.dark_noise_e; }));
    v.push_back(Number("sensor", "dark_current_e_per_s", "mean dark current at dark_current_ref_c, e-/s",
                       [](RunConfig& c) -> double& { return c.core.sensor.dark_current_e_per_s; }));
    v.push_back(Number("sensor", "temperature_c", "sensor temperature, degrees C",
                       [](RunConfig& c) -> double& { return c.core.sensor.temperature_c; }));
    v.push_back(Number("sensor", "dark_current_ref_c", "temperature at which dark_current_e_per_s holds, degrees C",
                       [](RunConfig& c) -> double& { return c.core.sensor.dark_current_ref_c; }));
    v.push_back(Number("sensor", "dark_current_doubling_c", "dark current doubles every this many kelvin",
                       [](RunConfig& c) -> double& { return c.core.sensor.dark_current_doubling_c; }));
    v.push_back(Number("sensor", "dsnu_e", "dark signal non-uniformity (offset pattern), electrons rms",
                       [](RunConfig& c) -> double& { return c.core.sensor.dsnu_e; }));
    v.push_back(Number("sensor", "prnu_percent", "photo response non-uniformity (gain pattern), % rms",
                       [](RunConfig& c) -> double& { return c.core.sensor.prnu_percent; }));
    v.push_back(Number("sensor", "dcnu_percent",
                       "dark current non-uniformity (dark-current gain pattern: grows with exposure time and "
                       "temperature), % rms of the mean dark current (0 .. 100)",
                       [](RunConfig& c) -> double& { return c.core.sensor.dcnu_percent; }));
    v.push_back(Number("sensor", "black_level_dn", "offset added to the raw output, DN",
                       [](RunConfig& c) -> double& { return c.core.sensor.black_level_dn; }));
    v.push_back(Bool("sensor", "shot_noise", "Poisson noise of photo and dark charge",
                     [](RunConfig& c) -> bool& { return c.core.sensor.shot_noise; }));
    v.push_back(Bool("sensor", "fixed_pattern_table",
                     "build PRNU/DSNU once per configuration (8 bytes per pixel and channel; 4 more with DCNU) "
                     "instead of every frame: same output, faster",
                     [](RunConfig& c) -> bool& { return c.core.sensor.fixed_pattern_table; }));
    v.push_back(Number("sensor", "row_fpn_e", "row offset pattern, electrons rms (0 = off)",
                       [](RunConfig& c) -> double& { return c.core.sensor.row_fpn_e; }));
    v.push_back(Number("sensor", "column_fpn_e", "column offset pattern, electrons rms (0 = off)",
                       [](RunConfig& c) -> double& { return c.core.sensor.column_fpn_e; }));
    Field defects = Make("sensor", "defects_file", Kind::kString,
                         "listed defect pixels, one 'x,y,kind[,value]' a line (kind hot | dead | stuck; value: "
                         "hot e-/s, stuck DN; '#' comments); wins over the seeded map at its pixels");
    defects.get_text = [](const RunConfig& c) { return TomlString(c.defects_file); };
    defects.set_text = [](RunConfig& c, const std::vector<std::string>& s, std::string*) {
      c.defects_file = s[0];
      return true;
    };
    v.push_back(defects);
    v.push_back(Number("sensor", "hot_pixel_fraction", "share of hot pixels (seeded map), 0 .. 0.01",
                       [](RunConfig& c) -> double& { return c.core.sensor.hot_pixel_fraction; }));
    v.push_back(Number("sensor", "hot_pixel_dark_e_per_s",
                       "median dark current of hot pixels at the reference temperature, e-/s (spread 0.5x .. 1.5x)",
                       [](RunConfig& c) -> double& { return c.core.sensor.hot_pixel_dark_e_per_s; }));
    v.push_back(Number("sensor", "dead_pixel_fraction", "share of dead pixels (no photo or dark charge), 0 .. 0.01",
                       [](RunConfig& c) -> double& { return c.core.sensor.dead_pixel_fraction; }));
    v.push_back(Number("sensor", "smear_row_transfer_us",
                       "CCD smear: time a charge packet spends under each row during transfer, us (0 = off)",
                       [](RunConfig& c) -> double& { return c.core.sensor.smear_row_transfer_us; }));
    v.push_back(Number("sensor", "smear_leak",
                       "CCD smear: share of the light reaching the transfer register (1 frame transfer, "
                       "~1e-4 interline)",
                       [](RunConfig& c) -> double& { return c.core.sensor.smear_leak; }));
    v.push_back(Number("sensor", "stuck_pixel_fraction", "share of pixels stuck at full scale, 0 .. 0.01",
                       [](RunConfig& c) -> double& { return c.core.sensor.stuck_pixel_fraction; }));

    // [blooming]
    v.push_back(Bool("blooming", "enabled", "charge above the full well spills along columns (before the sensor)",
                     [](RunConfig& c) -> bool& { return c.core.blooming.enabled; }));
    v.push_back(Integer("blooming", "rows", "how far a spill is followed each way, rows (1 .. 64)",
                        [](RunConfig& c) -> int& { return c.core.blooming.rows; }));

    // [flare]
    v.push_back(Bool("flare", "enabled", "lens flare from pixels above the threshold: glare, ghosts, veiling haze",
                     [](RunConfig& c) -> bool& { return c.core.flare.enabled; }));
    v.push_back(Number("flare", "threshold", "radiance above which a pixel sources flare",
                       [](RunConfig& c) -> double& { return c.core.flare.threshold; }));
    v.push_back(Number("flare", "glare_fraction", "share of the excess spread by the glare kernel (energy kept)",
                       [](RunConfig& c) -> double& { return c.core.flare.glare_fraction; }));
    v.push_back(Integer("flare", "glare_radius", "glare kernel radius, pixels (1 .. 32)",
                        [](RunConfig& c) -> int& { return c.core.flare.glare_radius; }));
    v.push_back(Integer("flare", "blades", "aperture blades: glare spikes and ghost polygons; 0 = round",
                        [](RunConfig& c) -> int& { return c.core.flare.blades; }));
    v.push_back(Number("flare", "haze", "veiling glare: share of the frame's total excess spread evenly",
                       [](RunConfig& c) -> double& { return c.core.flare.haze; }));
    v.push_back(Integer("flare", "ghost_count", "ghosts per bright tile, 0 .. 4",
                        [](RunConfig& c) -> int& { return c.core.flare.ghost_count; }));
    v.push_back(Array("flare", "ghost_scale", "ghost position = centre + scale * (source - centre); -1 = mirror",
                      kMaxGhosts, kMaxGhosts, [](RunConfig& c) { return c.core.flare.ghost_scale; }));
    v.push_back(Array("flare", "ghost_radius_px", "ghost radius, pixels (1 .. 64)", kMaxGhosts, kMaxGhosts,
                      [](RunConfig& c) { return c.core.flare.ghost_radius_px; }));
    v.push_back(Array("flare", "ghost_intensity", "share of the source's excess in each ghost", kMaxGhosts, kMaxGhosts,
                      [](RunConfig& c) { return c.core.flare.ghost_intensity; }));
    v.push_back(Array("flare", "ghost_tint", "R, G, B tint of each ghost (3 per ghost)", 3 * kMaxGhosts, 3 * kMaxGhosts,
                      [](RunConfig& c) { return c.core.flare.ghost_tint; }));
    Field env_map = Make("flare", "environment_map", Kind::kString,
                         "lat-long (equirectangular) HDR EXR around the camera, 2:1, scene radiance units: bright "
                         "light outside the field of view adds glare, ghosts and haze; \"\" = none");
    env_map.get_text = [](const RunConfig& c) { return TomlString(c.environment_map); };
    env_map.set_text = [](RunConfig& c, const std::vector<std::string>& s, std::string*) {
      c.environment_map = s[0];
      return true;
    };
    v.push_back(env_map);
    v.push_back(Number("flare", "environment_yaw_deg",
                       "camera heading in the map: 0 looks at its centre, + turns right (-360 .. 360)",
                       [](RunConfig& c) -> double& { return c.core.flare.environment.yaw_deg; }));
    v.push_back(Number("flare", "environment_pitch_deg", "camera tilt, + looks up (-90 .. 90)",
                       [](RunConfig& c) -> double& { return c.core.flare.environment.pitch_deg; }));
    v.push_back(Number("flare", "environment_roll_deg",
                       "camera roll about its axis, + clockwise seen from behind (-360 .. 360)",
                       [](RunConfig& c) -> double& { return c.core.flare.environment.roll_deg; }));
    v.push_back(Number("flare", "environment_gain", "radiance scale of the map (0 .. 1e6)",
                       [](RunConfig& c) -> double& { return c.core.flare.environment.gain; }));
    v.push_back(Integer("flare", "environment_max_sources",
                        "strongest map texels kept as glare/ghost sources (1 .. 1024); the rest add haze only",
                        [](RunConfig& c) -> int& { return c.core.flare.environment.max_sources; }));

    // [auto_exposure]
    v.push_back(Enum<AutoExposureMode>("auto_exposure", "mode",
                                       "off, once (settle, then hold) or continuous; carried frame to frame by camsim run",
                                       {"off", "once", "continuous"},
                                       [](RunConfig& c) -> AutoExposureMode& { return c.auto_exposure.mode; }));
    v.push_back(Number("auto_exposure", "target", "mean raw signal above black, fraction of the range (0.18: middle grey)",
                       [](RunConfig& c) -> double& { return c.auto_exposure.target; }));
    v.push_back(Enum<Metering>("auto_exposure", "metering", "weights: uniform, centre, spot or image",
                               {"uniform", "centre", "spot", "image"},
                               [](RunConfig& c) -> Metering& { return c.metering; }));
    Field meter_image = Make("auto_exposure", "metering_image", Kind::kString,
                             "metering = image: weight map (PNG or EXR), sensor-sized");
    meter_image.get_text = [](const RunConfig& c) { return TomlString(c.metering_image); };
    meter_image.set_text = [](RunConfig& c, const std::vector<std::string>& s, std::string*) {
      c.metering_image = s[0];
      return true;
    };
    v.push_back(meter_image);
    v.push_back(Enum<bool>("auto_exposure", "source", "measure the raw output or the input (an ideal, noiseless sensor)",
                           {"output", "input"}, [](RunConfig& c) -> bool& { return c.meter_input; }));
    v.push_back(Number("auto_exposure", "ki", "integral gain per frame (0 .. 1)",
                       [](RunConfig& c) -> double& { return c.auto_exposure.ki; }));
    v.push_back(Number("auto_exposure", "kp", "proportional gain on the change of error (0 .. 1)",
                       [](RunConfig& c) -> double& { return c.auto_exposure.kp; }));
    v.push_back(Number("auto_exposure", "max_step_ev", "largest EV change per frame",
                       [](RunConfig& c) -> double& { return c.auto_exposure.max_step_ev; }));
    v.push_back(Number("auto_exposure", "start_ev", "deadband: start moving above this error, EV",
                       [](RunConfig& c) -> double& { return c.auto_exposure.start_ev; }));
    v.push_back(Number("auto_exposure", "settle_ev", "deadband: stop below this error, EV",
                       [](RunConfig& c) -> double& { return c.auto_exposure.settle_ev; }));
    v.push_back(Integer("auto_exposure", "average_frames", "frames averaged (2 cancels alternating flicker), 1 .. 8",
                        [](RunConfig& c) -> int& { return c.auto_exposure.average_frames; }));
    v.push_back(Number("auto_exposure", "exposure_time_min_us", "shortest exposure time, us",
                       [](RunConfig& c) -> double& { return c.auto_exposure.exposure_time_min_us; }));
    v.push_back(Number("auto_exposure", "exposure_time_max_us", "longest exposure time, us",
                       [](RunConfig& c) -> double& { return c.auto_exposure.exposure_time_max_us; }));
    v.push_back(Number("auto_exposure", "gain_min_db", "least analog gain, dB",
                       [](RunConfig& c) -> double& { return c.auto_exposure.gain_min_db; }));
    v.push_back(Number("auto_exposure", "gain_max_db", "most analog gain, dB",
                       [](RunConfig& c) -> double& { return c.auto_exposure.gain_max_db; }));
    v.push_back(Number("auto_exposure", "f_number_min", "widest aperture; 0 with f_number_max 0: aperture fixed",
                       [](RunConfig& c) -> double& { return c.auto_exposure.f_number_min; }));
    v.push_back(Number("auto_exposure", "f_number_max", "narrowest aperture; 0: fixed",
                       [](RunConfig& c) -> double& { return c.auto_exposure.f_number_max; }));
    Field priority = Make("auto_exposure", "priority", Kind::kStringArray,
                          "order in which time, gain and aperture take exposure from the darkest setting");
    priority.get_text = [](const RunConfig& c) {
      const char* names[3] = {"time", "gain", "aperture"};
      std::string t = "[";
      for (int i = 0; i < 3; ++i)
        t += std::string(i ? ", \"" : "\"") + names[static_cast<int>(c.auto_exposure.priority[i])] + "\"";
      return t + "]";
    };
    priority.set_text = [](RunConfig& c, const std::vector<std::string>& names, std::string* err) {
      const char* known[3] = {"time", "gain", "aperture"};
      bool seen[3] = {};
      if (names.size() != 3) {
        *err = "must list time, gain and aperture once each";
        return false;
      }
      for (size_t i = 0; i < 3; ++i) {
        int k = -1;
        for (int j = 0; j < 3; ++j)
          if (names[i] == known[j]) k = j;
        if (k < 0 || seen[k]) {
          *err = "must list time, gain and aperture once each";
          return false;
        }
        seen[k] = true;
        c.auto_exposure.priority[i] = static_cast<Actuator>(k);
      }
      return true;
    };
    v.push_back(priority);

    // [exposure]
    v.push_back(Number("exposure", "exposure_time_us", "exposure time, microseconds",
                       [](RunConfig& c) -> double& { return c.core.exposure.exposure_time_us; }));
    v.push_back(Number("exposure", "f_number", "aperture f-number N (photons go as 1/N^2)",
                       [](RunConfig& c) -> double& { return c.core.exposure.f_number; }));
    v.push_back(Number("exposure", "photons_per_radiance_ms",
                       "calibration: photons per pixel per unit radiance per ms at f/1",
                       [](RunConfig& c) -> double& { return c.core.exposure.photons_per_radiance_ms; }));

    // [lens]
    v.push_back(Number("lens", "focal_length_mm", "focal length, mm",
                       [](RunConfig& c) -> double& { return c.focal_length_mm; }));

    // [motion]
    v.push_back(Enum<MotionSource>("motion", "source",
                                   "motion blur and rolling shutter: off, camera (velocities below) or vectors "
                                   "(the input's motion vectors)",
                                   {"off", "camera", "vectors"},
                                   [](RunConfig& c) -> MotionSource& { return c.core.motion_blur.source; }));
    v.push_back(Array("motion", "angular_velocity_rad_s", "camera angular velocity wx, wy, wz, rad/s (x right, y down, z forward)",
                      3, 3, [](RunConfig& c) { return c.core.motion_blur.angular_velocity_rad_s; }));
    v.push_back(Array("motion", "linear_velocity_m_s", "camera linear velocity vx, vy, vz, m/s (needs the input's depth)",
                      3, 3, [](RunConfig& c) { return c.core.motion_blur.linear_velocity_m_s; }));
    v.push_back(Number("motion", "fx_px",
                       "focal length x, pixels; 0 = lens.focal_length_mm / pixel pitch (distortion.calibration: its fx)",
                       [](RunConfig& c) -> double& { return c.core.motion_blur.fx_px; }));
    v.push_back(Number("motion", "fy_px",
                       "focal length y, pixels; 0 = lens.focal_length_mm / pixel pitch (distortion.calibration: its fy)",
                       [](RunConfig& c) -> double& { return c.core.motion_blur.fy_px; }));
    v.push_back(Number("motion", "cx_px",
                       "principal point x, pixels; negative = the centre (distortion.calibration: its cx)",
                       [](RunConfig& c) -> double& { return c.core.motion_blur.cx_px; }));
    v.push_back(Number("motion", "cy_px",
                       "principal point y, pixels; negative = the centre (distortion.calibration: its cy)",
                       [](RunConfig& c) -> double& { return c.core.motion_blur.cy_px; }));
    v.push_back(Number("motion", "vector_fps", "vectors: frames per second of the render (the vectors span 1 / fps)",
                       [](RunConfig& c) -> double& { return c.core.motion_blur.vector_fps; }));
    v.push_back(Number("motion", "line_time_us", "rolling shutter: delay from one row's exposure to the next, us; 0 = global shutter",
                       [](RunConfig& c) -> double& { return c.core.motion_blur.line_time_us; }));
    v.push_back(Integer("motion", "max_displacement_px", "bound on each sample's offset, 1 .. 511 px (longer motion stops there)",
                        [](RunConfig& c) -> int& { return c.core.motion_blur.max_displacement_px; }));
    v.push_back(Number("motion", "samples_per_px", "samples per pixel of motion length (precision knob), 1/16 .. 16",
                       [](RunConfig& c) -> double& { return c.core.motion_blur.samples_per_px; }));
    v.push_back(Integer("motion", "max_samples", "bound on the samples per pixel, 1 .. 256",
                        [](RunConfig& c) -> int& { return c.core.motion_blur.max_samples; }));
    // [dof]
    v.push_back(Enum<DofMethod>("dof", "method",
                                "depth of field: off, diffusion (implicit heat diffusion, rows then windowed columns) "
                                "or gather (reverse-mapped z-buffer disc gather); needs a depth plane",
                                {"off", "diffusion", "gather"}, [](RunConfig& c) -> DofMethod& { return c.core.dof.method; }));
    v.push_back(Number("dof", "focus_distance_m", "focus distance, metres (> focal length)",
                       [](RunConfig& c) -> double& { return c.core.dof.focus_distance_m; }));
    v.push_back(Number("dof", "max_coc_px", "circle-of-confusion diameter cap, pixels (0.25 .. 1023)",
                       [](RunConfig& c) -> double& { return c.core.dof.max_coc_px; }));
    v.push_back(Number("dof", "min_coc_px", "CoC diameters below this are 0: those pixels are not blurred (skipped)",
                       [](RunConfig& c) -> double& { return c.core.dof.min_coc_px; }));
    v.push_back(Number("dof", "diffusion_scale",
                       "diffusion: beta = (scale * CoC)^2; 1/sqrt(32) matches a disc's variance",
                       [](RunConfig& c) -> double& { return c.core.dof.diffusion_scale; }));
    v.push_back(Integer("dof", "column_window", "diffusion: rows solved each side per column (precision knob, 1 .. 496)",
                        [](RunConfig& c) -> int& { return c.core.dof.column_window; }));
    v.push_back(Integer("dof", "max_radius_px", "gather: disc radius cap, pixels (precision knob, 1 .. 255)",
                        [](RunConfig& c) -> int& { return c.core.dof.max_radius_px; }));
    v.push_back(Array("dof", "structural_poly",
                      "structural blur: diameter in pixels = sum a_k r^k, r = normalised radius (0 centre, 1 corner); "
                      "0 .. 5 coefficients; runs the diffusion stages",
                      0, DofConfig::kPolyTerms, [](RunConfig& c) { return c.core.dof.structural_poly; },
                      [](RunConfig& c) { return &c.core.dof.structural_poly_count; }));
    v.push_back(Bool("dof", "structural_only", "diffusion stages blur by structural_poly only (no depth needed)",
                     [](RunConfig& c) -> bool& { return c.core.dof.structural_only; }));
    // [distortion]
    v.push_back(Enum<DistortionModel>("distortion", "model",
                                      "off, brown (OpenCV/ROS plumb_bob and rational_polynomial: k1 k2 p1 p2 k3 k4 k5 k6) "
                                      "or fisheye (OpenCV fisheye / ROS equidistant: k1..k4)",
                                      {"off", "brown", "fisheye"},
                                      [](RunConfig& c) -> DistortionModel& { return c.core.distortion.lens.model; }));
    Field calibration = Make("distortion", "calibration", Kind::kString,
                             "OpenCV FileStorage or ROS camera_info YAML; sets model (ROS; an OpenCV file's is "
                             "distortion.model, brown or fisheye), fx fy cx cy, k1..k6, p1 p2 (scaled to the sensor "
                             "if calibrated at another size of the same aspect ratio), and motion.fx_px..cy_px and "
                             "vignetting.focal_length_px; those keys are refused beside it");
    calibration.get_text = [](const RunConfig& c) { return TomlString(c.calibration); };
    calibration.set_text = [](RunConfig& c, const std::vector<std::string>& s, std::string*) {
      c.calibration = s[0];
      return true;
    };
    v.push_back(calibration);
    Field mesh = Make("distortion", "mesh", Kind::kString,
                      "displacement mesh text file (step S / size COLS ROWS / dx dy pairs): moves each output "
                      "pixel's source, on top of the lens model (asymmetric or measured distortion)");
    mesh.get_text = [](const RunConfig& c) { return TomlString(c.mesh); };
    mesh.set_text = [](RunConfig& c, const std::vector<std::string>& s, std::string*) {
      c.mesh = s[0];
      return true;
    };
    v.push_back(mesh);
    v.push_back(Number("distortion", "fx", "focal length x, pixels; 0 = lens.focal_length_mm / pixel pitch",
                       [](RunConfig& c) -> double& { return c.core.distortion.lens.fx; }));
    v.push_back(Number("distortion", "fy", "focal length y, pixels; 0 = fx",
                       [](RunConfig& c) -> double& { return c.core.distortion.lens.fy; }));
    v.push_back(Number("distortion", "cx", "principal point x, pixels (pixel centres at integers); -1 = frame centre",
                       [](RunConfig& c) -> double& { return c.core.distortion.lens.cx; }));
    v.push_back(Number("distortion", "cy", "principal point y, pixels; -1 = frame centre",
                       [](RunConfig& c) -> double& { return c.core.distortion.lens.cy; }));
    static constexpr const char* kKNames[6] = {"k1", "k2", "k3", "k4", "k5", "k6"};
    for (int i = 0; i < 6; ++i)
      v.push_back(Number("distortion", kKNames[i], i < 3 ? "radial coefficient" : "rational (brown) radial denominator coefficient; fisheye: k4 is the 4th",
                         [i](RunConfig& c) -> double& { return c.core.distortion.lens.k[i]; }));
    v.push_back(Number("distortion", "p1", "tangential coefficient (brown)",
                       [](RunConfig& c) -> double& { return c.core.distortion.lens.p1; }));
    v.push_back(Number("distortion", "p2", "tangential coefficient (brown)",
                       [](RunConfig& c) -> double& { return c.core.distortion.lens.p2; }));
    v.push_back(Array("distortion", "chromatic_scale",
                      "lateral chromatic aberration: radial scale of R, G, B about (cx, cy), 0.5 .. 2 (1 = none)", 3, 3,
                      [](RunConfig& c) { return c.core.distortion.chromatic_scale; }));
    v.push_back(Enum<ResampleFilter>("distortion", "filter", "resampling: bilinear, bicubic (Keys a = -0.5), lanczos3 or lanczos4 (OpenCV's INTER_LANCZOS4)",
                                     {"bilinear", "bicubic", "lanczos3", "lanczos4"},
                                     [](RunConfig& c) -> ResampleFilter& { return c.core.distortion.filter; }));
    v.push_back(Integer("distortion", "phases", "sub-pixel filter phases: 16, 32, 64, 128 or 256",
                        [](RunConfig& c) -> int& { return c.core.distortion.phases; }));
    v.push_back(Integer("distortion", "grid_step", "remap table grid spacing, pixels: 4, 8, 16, 32 or 64 (precision knob)",
                        [](RunConfig& c) -> int& { return c.core.distortion.grid_step; }));
    v.push_back(Bool("distortion", "ringing_clamp",
                     "bicubic, lanczos: clamp to the 2x2 samples around the source (no halo at hard edges; "
                     "false: the filter as it is, for band-limited images)",
                     [](RunConfig& c) -> bool& { return c.core.distortion.ringing_clamp; }));

    // [vignetting]
    v.push_back(Enum<VignettingMode>("vignetting", "mode",
                                     "off, cos4 (natural fall-off from the lens), table (curve below) or mask (image)",
                                     {"off", "cos4", "table", "mask"},
                                     [](RunConfig& c) -> VignettingMode& { return c.core.vignetting.mode; }));
    v.push_back(Number("vignetting", "focal_length_px",
                       "cos4 focal length in pixels; 0 = lens.focal_length_mm / pixel pitch "
                       "(distortion.calibration: sqrt(fx fy))",
                       [](RunConfig& c) -> double& { return c.core.vignetting.focal_length_px; }));
    v.push_back(Array("vignetting", "table", "table mode: gains from centre (rho 0) to corner (rho 1), 2 .. 64 values",
                      0, VignettingConfig::kMaxTable, [](RunConfig& c) { return c.core.vignetting.table; },
                      [](RunConfig& c) { return &c.core.vignetting.table_count; }));
    Field mask = Make("vignetting", "mask", Kind::kString, "mask mode: image file (PNG or EXR), gain per pixel, resampled to the sensor");
    mask.get_text = [](const RunConfig& c) { return TomlString(c.vignetting_mask); };
    mask.set_text = [](RunConfig& c, const std::vector<std::string>& s, std::string*) {
      c.vignetting_mask = s[0];
      return true;
    };
    v.push_back(mask);

    // [cfa]
    v.push_back(Array("cfa", "mono_weights", "mono sensor: response to R, G, B", 3, 3,
                      [](RunConfig& c) { return c.core.cfa.mono_weights; }));
    // [black_level]
    v.push_back(Number("black_level", "black_level_dn", "subtracted before the ISP, DN; -1 = the sensor's",
                       [](RunConfig& c) -> double& { return c.core.black_level.black_level_dn; }));
    // [white_balance]
    v.push_back(Array("white_balance", "gain", "gains for R, G, B (0 .. 16)", 3, 3,
                      [](RunConfig& c) { return c.core.white_balance.gain; }));
    // [demosaic]
    v.push_back(Enum<DemosaicMethod>("demosaic", "method", "bilinear (the paper's eq. 23-24) or malvar (Malvar-He-Cutler)",
                                     {"bilinear", "malvar"},
                                     [](RunConfig& c) -> DemosaicMethod& { return c.core.demosaic.method; }));
    // [color_matrix]
    v.push_back(Array("color_matrix", "m", "3x3 row-major matrix applied to linear RGB (-16 .. 16)", 9, 9,
                      [](RunConfig& c) { return c.core.color_matrix.m; }));
    // [gamma]
    v.push_back(Enum<GammaCurve>("gamma", "curve", "linear, srgb or power", {"linear", "srgb", "power"},
                                 [](RunConfig& c) -> GammaCurve& { return c.core.gamma.curve; }));
    v.push_back(Number("gamma", "gamma", "power curve: output = input^(1/gamma)",
                       [](RunConfig& c) -> double& { return c.core.gamma.gamma; }));
    // [output]
    v.push_back(Integer("output", "bits", "ISP output PNG depth: 8 or 16", [](RunConfig& c) -> int& { return c.output_bits; }));
    return v;
  }();
  return fields;
}

const Field* FindField(const std::string& section, const std::string& key) {
  for (const Field& f : Fields())
    if (section == f.section && key == f.key) return &f;
  return nullptr;
}

size_t EditDistance(const std::string& a, const std::string& b) {
  std::vector<size_t> row(b.size() + 1);
  for (size_t j = 0; j <= b.size(); ++j) row[j] = j;
  for (size_t i = 1; i <= a.size(); ++i) {
    size_t prev = row[0];
    row[0] = i;
    for (size_t j = 1; j <= b.size(); ++j) {
      const size_t cur = row[j];
      row[j] = std::min({row[j] + 1, row[j - 1] + 1, prev + (a[i - 1] == b[j - 1] ? 0 : 1)});
      prev = cur;
    }
  }
  return row[b.size()];
}

// " (did you mean 'X'?)" for the closest candidate (edit distance below 4),
// or "". Candidates: (text compared with `wrong`, name shown).
std::string Closest(const std::string& wrong, const std::vector<std::pair<std::string, std::string>>& candidates) {
  std::string best;
  size_t best_d = 4;  // suggest only close matches
  for (const auto& [text, shown] : candidates) {
    const size_t d = EditDistance(wrong, text);
    if (d < best_d) {
      best_d = d;
      best = shown;
    }
  }
  return best.empty() ? "" : " (did you mean '" + best + "'?)";
}

std::string SuggestSection(const std::string& wrong) {
  std::vector<std::pair<std::string, std::string>> sections;
  for (const Field& f : Fields())
    if (sections.empty() || sections.back().first != f.section) sections.emplace_back(f.section, f.section);
  return Closest(wrong, sections);
}

// A key of the same section close to `key`; else the same key in another
// section (a key put under the wrong heading).
std::string SuggestKey(const std::string& section, const std::string& key) {
  std::vector<std::pair<std::string, std::string>> same, elsewhere;
  for (const Field& f : Fields()) {
    const std::string name = std::string(f.section) + "." + f.key;
    if (section == f.section) same.emplace_back(f.key, name);
    else if (key == f.key) elsewhere.emplace_back(f.key, name);
  }
  const std::string s = Closest(key, same);
  return s.empty() ? Closest(key, elsewhere) : s;
}

// Shortest text that reads back as the same double.
std::string FormatNumber(double v) {
  char buf[32];
  const auto r = std::to_chars(buf, buf + sizeof buf, v);
  std::string t(buf, r.ptr);
  if (t.find_first_of(".eEn") == std::string::npos) t += ".0";  // keep it a TOML float
  return t;
}

std::string Where(const toml::node& n, const std::string& source) {
  return source + ":" + std::to_string(n.source().begin.line);
}

// Sets one field from a TOML node. *error gets the reason without location.
bool SetField(const Field& f, const toml::node& n, RunConfig* c, std::string* error) {
  switch (f.kind) {
    case Kind::kNumber: {
      std::optional<double> v = n.value<double>();
      if (!v || !(n.is_floating_point() || n.is_integer())) {
        *error = "expects a number";
        return false;
      }
      // No key means anything by nan or inf, and a stage that is off would
      // not check its own ranges: refused here for every key.
      if (!std::isfinite(*v)) {
        *error = "must be a finite number";
        return false;
      }
      f.number(*c) = *v;
      return true;
    }
    case Kind::kInteger: {
      if (!n.is_integer()) {
        *error = "expects a whole number";
        return false;
      }
      const int64_t v = *n.value<int64_t>();
      if (std::string(f.key) == "seed") {
        if (v < 0 || v > (int64_t{1} << 53)) {
          *error = "must be in [0, 2^53]";
          return false;
        }
        c->core.seed = static_cast<uint64_t>(v);
        return true;
      }
      if (v < -1000000000 || v > 1000000000) {
        *error = "is out of range";
        return false;
      }
      f.integer(*c) = static_cast<int>(v);
      return true;
    }
    case Kind::kBool:
      if (!n.is_boolean()) {
        *error = "expects true or false";
        return false;
      }
      f.boolean(*c) = *n.value<bool>();
      return true;
    case Kind::kEnum: {
      std::optional<std::string> s = n.value<std::string>();
      if (s)
        for (size_t i = 0; i < f.choices.size(); ++i)
          if (*s == f.choices[i]) {
            f.set_enum(*c, static_cast<int>(i));
            return true;
          }
      *error = "must be one of:";
      for (const char* ch : f.choices) *error += std::string(" \"") + ch + "\"";
      return false;
    }
    case Kind::kNumberArray: {
      const toml::array* a = n.as_array();
      if (a == nullptr) {
        *error = "expects an array of numbers";
        return false;
      }
      const int count = static_cast<int>(a->size());
      if (count < f.min_count || count > f.max_count) {
        *error = f.min_count == f.max_count ? "expects exactly " + std::to_string(f.min_count) + " numbers"
                                            : "expects " + std::to_string(f.min_count) + " to " +
                                                  std::to_string(f.max_count) + " numbers";
        return false;
      }
      double* dst = f.array(*c);
      for (int i = 0; i < count; ++i) {
        const toml::node& e = (*a)[static_cast<size_t>(i)];
        if (!(e.is_floating_point() || e.is_integer())) {
          *error = "element " + std::to_string(i) + " is not a number";
          return false;
        }
        if (!std::isfinite(*e.value<double>())) {
          *error = "element " + std::to_string(i) + " must be a finite number";
          return false;
        }
        dst[i] = *e.value<double>();
      }
      if (f.count) *f.count(*c) = count;
      return true;
    }
    case Kind::kString:
    case Kind::kStringArray: {
      std::vector<std::string> items;
      if (f.kind == Kind::kString) {
        std::optional<std::string> s = n.value<std::string>();
        if (!s) {
          *error = "expects a string";
          return false;
        }
        items.push_back(*s);
      } else {
        const toml::array* a = n.as_array();
        if (a == nullptr) {
          *error = "expects an array of strings";
          return false;
        }
        for (const toml::node& e : *a) {
          std::optional<std::string> s = e.value<std::string>();
          if (!s) {
            *error = "expects an array of strings";
            return false;
          }
          items.push_back(*s);
        }
      }
      return f.set_text(*c, items, error);
    }
  }
  return false;
}

std::string ValueText(const Field& f, const RunConfig& c) {
  RunConfig& m = const_cast<RunConfig&>(c);
  switch (f.kind) {
    case Kind::kNumber: return FormatNumber(f.number(m));
    case Kind::kInteger: return f.integer ? std::to_string(f.integer(m)) : f.get_text(c);
    case Kind::kBool: return f.boolean(m) ? "true" : "false";
    case Kind::kEnum: return std::string("\"") + f.choices[static_cast<size_t>(f.get_enum(c))] + "\"";
    case Kind::kNumberArray: {
      const int n = f.count ? *f.count(m) : f.max_count;
      std::string t = "[";
      for (int i = 0; i < n; ++i) t += (i ? ", " : "") + FormatNumber(f.array(m)[i]);
      return t + "]";
    }
    case Kind::kString:
    case Kind::kStringArray: return f.get_text(c);
  }
  return "";
}

// The keys whose value is a file the configuration reads, and where each is held.
constexpr std::pair<const char*, std::string RunConfig::*> kPathKeys[] = {
    {"sensor.defects_file", &RunConfig::defects_file},     {"distortion.calibration", &RunConfig::calibration},
    {"distortion.mesh", &RunConfig::mesh},                 {"vignetting.mask", &RunConfig::vignetting_mask},
    {"flare.environment_map", &RunConfig::environment_map}, {"auto_exposure.metering_image", &RunConfig::metering_image}};

// base_dir: the directory relative paths of a configuration file are
// resolved against (its own; "" for the current directory).
bool ApplyTable(const toml::table& root, const std::string& source, const std::string& base_dir, RunConfig* c,
                Origins* origins, std::string* error) {
  for (auto&& [section_key, section_node] : root) {
    const std::string section(section_key.str());
    const toml::table* t = section_node.as_table();
    bool known_section = false;
    for (const Field& f : Fields()) known_section |= section == f.section;
    if (known_section && t == nullptr) {
      // [[sensor]] (an array of tables) or sensor = 1 at the top level.
      *error = Where(section_node, source) + ": '" + section + "' must be a table: write [" + section + "] " +
               (section_node.is_array() ? "(one pair of brackets, not [[" + section + "]])" : "and its keys below it");
      return false;
    }
    if (!known_section && t == nullptr) {
      // A key above every [section] header: name the section that has it.
      std::string home;
      for (const Field& f : Fields())
        if (section == f.key && home.empty()) home = f.section;
      if (!home.empty()) {
        *error = Where(section_node, source) + ": '" + section + "' is outside any section: write it under [" +
                 home + "] (" + home + "." + section + ")";
        return false;
      }
    }
    if (!known_section) {
      *error = Where(section_node, source) + ": unknown section '" + section + "'" + SuggestSection(section);
      return false;
    }
    for (auto&& [key, node] : *t) {
      const std::string name = section + "." + std::string(key.str());
      const Field* f = FindField(section, std::string(key.str()));
      if (f == nullptr) {
        *error = Where(node, source) + ": unknown key '" + name + "'" + SuggestKey(section, std::string(key.str()));
        return false;
      }
      std::string why;
      if (!SetField(*f, node, c, &why)) {
        *error = Where(node, source) + ": " + name + " " + why;
        return false;
      }
      if (!base_dir.empty())
        for (const auto& [path_key, member] : kPathKeys) {
          std::string& path = c->*member;
          if (name == path_key && !path.empty() && path[0] != '/')
            path = (base_dir == "/" ? base_dir : base_dir + "/") + path;
        }
      (*origins)[name] = Where(node, source);
    }
  }
  return true;
}

}  // namespace

std::vector<std::pair<std::string, std::string>> ConfigInputFiles(const RunConfig& c) {
  std::vector<std::pair<std::string, std::string>> files;
  for (const auto& [key, member] : kPathKeys)
    if (!(c.*member).empty()) files.emplace_back(key, c.*member);
  return files;
}

std::string KeyWhere(const Origins& origins, const std::string& key) {
  const auto it = origins.find(key);
  return it == origins.end() || it->second.empty() ? key : it->second + ": " + key;
}

std::vector<std::string> ConfigKeys() {
  std::vector<std::string> keys;
  for (const Field& f : Fields()) keys.push_back(std::string(f.section) + "." + f.key);
  return keys;
}

// toml++ 3.3.0 (Debian 12's) reaches __builtin_unreachable() in
// is_non_ascii_horizontal_whitespace() for the code points U+00A1..U+0499,
// U+2C5E..U+3057 and U+FB26..U+FEFE (but U+3000) wherever it asks whether a
// character is whitespace: between tokens, while it scans a value to find its
// type (`x = 16'\u026b`), and in multi-line strings after a line-ending
// backslash (upstream issue marzer/tomlplusplus#190). No camsim key needs
// non-ASCII there: refuse it before toml++ sees the text. Allowed: a leading
// UTF-8 byte order mark, comments, and single-line strings in a value (a quote
// right after `=`, `[`, `,` or `{`; anywhere else toml++ either starts no
// string or has stopped with an error). Quoted keys and multi-line strings
// are refused with non-ASCII / altogether.
bool CheckTomlText(const std::string& text, const std::string& source, std::string* error) {
  enum class State { kCode, kComment, kString };
  State state = State::kCode;
  bool value = false;       // after `=` on this line (else a key or a table header)
  bool key_string = false;  // the open string is (or may be) a quoted key
  char quote = 0;
  char prev = '\n';  // the last code character on this line other than blanks
  int line = 1;
  const auto fail = [&](const char* why) {
    *error = source + ":" + std::to_string(line) + ": " + why;
    return false;
  };
  const size_t start = text.compare(0, 3, "\xEF\xBB\xBF") == 0 ? 3 : 0;
  for (size_t i = start; i < text.size(); ++i) {
    const char ch = text[i];
    const bool ascii = static_cast<unsigned char>(ch) < 0x80;
    if (ch == '\n') {
      ++line;
      state = State::kCode;  // an unterminated single-line string is toml++'s error
      value = false;
      prev = '\n';
      continue;
    }
    switch (state) {
      case State::kComment:
        break;
      case State::kString:
        if (!ascii && key_string) return fail("non-ASCII character in a key");
        if (quote == '"' && ch == '\\' && i + 1 < text.size() && text[i + 1] != '\n') {
          ++i;  // an escaped character
        } else if (ch == quote) {
          state = State::kCode;
          prev = ch;
        }
        break;
      case State::kCode:
        if (!ascii) return fail("non-ASCII character outside a string value or a comment");
        if (ch == '#') {
          state = State::kComment;
        } else if ((ch == '"' || ch == '\'') &&
                   (!value || prev == '=' || prev == '[' || prev == ',' || prev == '{')) {
          if (text.compare(i, 3, std::string(3, ch)) == 0) return fail("multi-line strings are not supported");
          state = State::kString;
          quote = ch;
          key_string = !value;
        } else {
          if (ch == '=') value = true;
          if (ch != ' ' && ch != '\t') prev = ch;
        }
        break;
    }
  }
  return true;
}

namespace {

bool ParseConfigIn(const std::string& text, const std::string& source, const std::string& base_dir, RunConfig* c,
                   Origins* origins, std::string* error) {
  if (!CheckTomlText(text, source, error)) return false;
  try {
    toml::table root = toml::parse(text, source);
    return ApplyTable(root, source, base_dir, c, origins, error);
  } catch (const toml::parse_error& e) {
    *error = source + ":" + std::to_string(e.source().begin.line) + ": " + std::string(e.description());
    return false;
  }
}

}  // namespace

bool ParseConfig(const std::string& text, const std::string& source, RunConfig* c, Origins* origins,
                 std::string* error) {
  return ParseConfigIn(text, source, "", c, origins, error);
}

bool LoadConfigFile(const std::string& path, RunConfig* c, Origins* origins, std::string* error) {
  std::string text, why;
  if (!io::ReadTextFile(path, &text, &why)) {
    *error = path + ": cannot read configuration file: " + why;
    return false;
  }
  // A relative file name in the file is relative to the file's directory,
  // so that a configuration and the files it names move together: the
  // directory `path` names, or through a symbolic link (/dev/stdin
  // redirected from a file, too) the real file's. A stream (a pipe) has no
  // directory: relative to the current directory.
  struct stat st, link;
  std::string base_dir;
  if (stat(path.c_str(), &st) == 0 && S_ISREG(st.st_mode)) {
    std::string file = path;
    if (lstat(path.c_str(), &link) == 0 && S_ISLNK(link.st_mode)) {
      char* real = realpath(path.c_str(), nullptr);
      if (real != nullptr) file = real;
      std::free(real);
    }
    const size_t slash = file.find_last_of('/');
    if (slash != std::string::npos) base_dir = slash == 0 ? "/" : file.substr(0, slash);
  }
  return ParseConfigIn(text, path, base_dir, c, origins, error);
}

bool ApplyOverride(const std::string& assignment, RunConfig* c, Origins* origins, std::string* error) {
  const size_t eq = assignment.find('=');
  const size_t dot = assignment.find('.');
  if (eq == std::string::npos || dot == std::string::npos || dot > eq) {
    *error = "--set " + assignment + ": expected section.key=value";
    return false;
  }
  // One key each: a line break would let the value add lines of its own.
  if (assignment.find_first_of("\n\r") != std::string::npos) {
    *error = "--set " + assignment.substr(0, eq) + ": the value has a line break";
    return false;
  }
  const std::string section = assignment.substr(0, dot), key = assignment.substr(dot + 1, eq - dot - 1);
  std::string value = assignment.substr(eq + 1);
  const Field* f = FindField(section, key);
  if (f == nullptr) {
    *error = "--set " + assignment + ": unknown key '" + section + "." + key + "'" + SuggestKey(section, key);
    return false;
  }
  // A string (a path: /abs, ./rel, C:\x) is taken as written unless quoted;
  // an enum accepts a bare word.
  const bool quoted = !value.empty() && (value[0] == '"' || value[0] == '\'');
  const bool bare = !value.empty() && std::isalpha(static_cast<unsigned char>(value[0])) && value != "true" &&
                    value != "false" && value != "inf" && value != "nan";
  if (f->kind == Kind::kString && !quoted) value = TomlString(value);
  else if (f->kind == Kind::kEnum && bare) value = "\"" + value + "\"";
  RunConfig updated = *c;
  Origins o;
  std::string why;
  if (!ParseConfig("[" + section + "]\n" + key + " = " + value + "\n", "--set", &updated, &o, &why)) {
    *error = "--set " + assignment + ": " + why.substr(why.find(": ") + 2);
    return false;
  }
  *c = updated;
  // The whole argument, so that a later error about the key (a range the
  // core checks) echoes it, as the parse errors above do.
  (*origins)[section + "." + key] = "--set " + assignment;
  return true;
}

std::string ConfigToToml(const RunConfig& c, bool annotated) {
  std::string out;
  if (annotated)
    out += "# camsim configuration. Every key is optional; these are the defaults.\n"
           "# Stage order is [pipeline] stages; stages that would change nothing are left out\n"
           "# at run time and the report says why.\n"
           "# A relative file name in a key (defects_file, environment_map, metering_image,\n"
           "# calibration, mesh, mask) is relative to this file's directory (a symbolic\n"
           "# link's target's); given with --set, to the current directory.\n";
  std::string section;
  for (const Field& f : Fields()) {
    if (section != f.section) {
      section = f.section;
      out += "\n[" + section + "]\n";
    }
    if (annotated) out += std::string("# ") + f.doc + "\n";
    out += std::string(f.key) + " = " + ValueText(f, c) + "\n";
  }
  return out;
}

std::string DefaultConfigToml() { return ConfigToToml(RunConfig{}, true); }

// Keys a calibration file sets (ResolveDistortion, FinishConfig): refused
// beside it, and the stages' errors about them (and distortion.model) name
// the file.
constexpr const char* kCalibrationKeys[] = {
    "distortion.fx", "distortion.fy", "distortion.cx", "distortion.cy", "distortion.k1", "distortion.k2",
    "distortion.k3", "distortion.k4", "distortion.k5", "distortion.k6", "distortion.p1", "distortion.p2",
    "motion.fx_px",  "motion.fy_px",  "motion.cx_px",  "motion.cy_px",  "vignetting.focal_length_px"};

namespace {

// A core message either goes on from its field's name, starting with a verb
// ("must be in [0, 1]", "needs linear input"), or is a clause of its own
// ("the radial model folds over"), set off by a colon.
std::string FieldSays(const std::string& subject, const char* message) {
  for (const char* verb : {"must ", "needs ", "is ", "holds "})
    if (std::strncmp(message, verb, std::strlen(verb)) == 0) return subject + " " + message;
  return subject + ": " + message;
}

}  // namespace

std::string DescribeStatus(const Status& s, const Origins& origins) {
  const std::string field = s.field();
  const auto origin = [&origins](const std::string& key) {
    const auto it = origins.find(key);
    return it != origins.end() ? it->second : std::string();
  };
  std::string where;
  if (field.empty() || field.rfind("input.", 0) == 0) {
    // A message of its own, or about the input (no key sets it).
  } else if (!origin(field).empty()) {
    where = origin(field) + ": ";
  } else if (field.find('.') == std::string::npos) {
    // A stage's name: the planner refused where the stage list put it.
    const std::string stages = origin("pipeline.stages");
    where = (stages.empty() ? "the default stage order" : stages) + ": pipeline.stages: ";
  } else if (!origin("distortion.calibration").empty() &&
             (field == "distortion.model" ||
              std::find(std::begin(kCalibrationKeys), std::end(kCalibrationKeys), field) != std::end(kCalibrationKeys))) {
    // The calibration file sets the camera (keys set beside it are refused):
    // "--calibration 'c.yaml': distortion.k1 (set by the calibration file): the radial model folds ...".
    return origin("distortion.calibration") + ": " + FieldSays(field + " (set by the calibration file)", s.message());
  } else {
    where = "(not set: the default, or derived from the input's size): ";
  }
  return where + (field.empty() ? std::string(s.message()) : FieldSays(field, s.message()));
}

// The lens of [distortion]: from a calibration file, or from the keys with
// their defaults resolved (focal length from lens.focal_length_mm, principal
// point at the frame centre).
bool ResolveDistortion(RunConfig* c, double pitch_mm, const Origins& origins, std::string* error) {
  DistortionConfig& d = c->core.distortion;
  const SensorGeometry& g = c->core.geometry;
  d.mesh = DisplacementMesh();
  if (!c->mesh.empty()) {
    auto data = std::make_shared<std::vector<float>>();
    if (!LoadDisplacementMesh(c->mesh, data.get(), &d.mesh.cols, &d.mesh.rows, &d.mesh.step, error)) {
      *error = KeyWhere(origins, "distortion.mesh") + ": " + *error;
      return false;
    }
    c->mesh_data = data;
    d.mesh.dxdy = data->data();
  }
  if (!c->calibration.empty()) {
    for (const char* key : kCalibrationKeys)
      if (origins.count(key) != 0) {
        *error = origins.at(key) + ": " + key + " is set together with distortion.calibration, which sets it too";
        return false;
      }
    // distortion.model only says which model an OpenCV file's coefficients
    // are for (they do not say): brown or fisheye.
    const bool model_set = origins.count("distortion.model") != 0;
    if (model_set && d.lens.model == DistortionModel::kOff) {
      *error = origins.at("distortion.model") +
               ": distortion.model = \"off\" is set together with distortion.calibration, which distorts; "
               "with a calibration it may only say brown or fisheye (an OpenCV file's model)";
      return false;
    }
    Calibration cal;
    const bool fisheye_hint = d.lens.model == DistortionModel::kFisheye;
    if (!LoadCalibration(c->calibration, fisheye_hint, &cal, error) ||
        !FitCalibration(cal, g.width, g.height, &d.lens, error)) {
      *error = KeyWhere(origins, "distortion.calibration") + ": " + *error;
      return false;
    }
    if (model_set && cal.names_model) {
      *error = origins.at("distortion.model") +
               ": distortion.model is set together with distortion.calibration, whose file names its model "
               "(distortion_model: " + cal.model_name + ")";
      return false;
    }
    return true;
  }
  if (d.lens.fx == 0.0) d.lens.fx = c->focal_length_mm / pitch_mm;
  if (d.lens.fy == 0.0) d.lens.fy = d.lens.fx;
  if (d.lens.cx == -1.0) d.lens.cx = (g.width - 1) / 2.0;
  if (d.lens.cy == -1.0) d.lens.cy = (g.height - 1) / 2.0;
  return true;
}

// The flare environment map: loaded only when flare is on (and again only
// when its path changes), seen through the lens's pinhole fx, fy, cx, cy.
bool ResolveEnvironment(RunConfig* c, const Origins& origins, std::string* error) {
  FlareEnvironment& env = c->core.flare.environment;
  env.texels = nullptr;
  env.width = env.height = 0;
  if (!c->core.flare.enabled || c->environment_map.empty()) return true;
  if (!c->environment_data || c->environment_data->path != c->environment_map) {
    auto map = std::make_shared<io::EnvironmentMap>();
    if (!io::LoadEnvironmentMap(c->environment_map, map.get(), error)) {
      *error = KeyWhere(origins, "flare.environment_map") + ": " + *error;
      return false;
    }
    c->environment_data = map;
  }
  const io::EnvironmentMap& m = *c->environment_data;
  env.texels = m.rgb.data();
  env.width = m.width;
  env.height = m.height;
  const LensModel& lens = c->core.distortion.lens;
  env.fx = lens.fx;
  env.fy = lens.fy;
  env.cx = lens.cx;
  env.cy = lens.cy;
  return true;
}

bool FinishConfig(RunConfig* c, int input_width, int input_height, const Origins& origins, int workers,
                  std::string* error, const Pipeline* previous, std::unique_ptr<Pipeline>* configured) {
  // On failure *configured ends empty (after any use of `previous`, which may be it).
  struct EmptyOnFailure {
    std::unique_ptr<Pipeline>* configured;
    bool ok = false;
    ~EmptyOnFailure() {
      if (!ok && configured != nullptr) configured->reset();
    }
  } outcome{configured};
  PipelineConfig& p = c->core;
  if (c->width < 0 || c->height < 0) {
    *error = DescribeStatus(InvalidArgument(c->width < 0 ? "sensor.width" : "sensor.height", "must be >= 0"), origins);
    return false;
  }
  p.geometry.width = c->width > 0 ? c->width : input_width;
  p.geometry.height = c->height > 0 ? c->height : input_height;
  if (c->fit == SceneFit::kCrop && (p.geometry.width > input_width || p.geometry.height > input_height)) {
    const bool wide = p.geometry.width > input_width;  // the width, when both are too large
    const std::string why = "is " + std::to_string(wide ? p.geometry.width : p.geometry.height) +
                            ", larger than the input's " + std::to_string(wide ? input_width : input_height) +
                            "; use sensor.scene_fit = \"scale\"";
    *error = DescribeStatus(InvalidArgument(wide ? "sensor.width" : "sensor.height", why.c_str()), origins);
    return false;
  }
  if (c->output_bits != 8 && c->output_bits != 16) {
    *error = DescribeStatus(InvalidArgument("output.bits", "must be 8 or 16"), origins);
    return false;
  }
  if (!(c->pixel_pitch_um >= 0.0 && c->pixel_pitch_um <= 1000.0)) {
    *error = DescribeStatus(InvalidArgument("sensor.pixel_pitch_um", "must be in [0, 1000]"), origins);
    return false;
  }
  if (!(c->focal_length_mm > 0.0 && c->focal_length_mm <= 10000.0)) {
    *error = DescribeStatus(InvalidArgument("lens.focal_length_mm", "must be in (0, 10000]"), origins);
    return false;
  }
  const double pitch_mm = c->pixel_pitch_um > 0 ? c->pixel_pitch_um / 1000.0 : 36.0 / p.geometry.width;
  if (p.vignetting.focal_length_px == 0.0) p.vignetting.focal_length_px = c->focal_length_mm / pitch_mm;
  if (p.motion_blur.fx_px == 0.0) p.motion_blur.fx_px = c->focal_length_mm / pitch_mm;
  if (p.motion_blur.fy_px == 0.0) p.motion_blur.fy_px = c->focal_length_mm / pitch_mm;
  p.dof.focal_length_mm = c->focal_length_mm;
  p.dof.pixel_pitch_um = pitch_mm * 1000.0;
  if (!ResolveDistortion(c, pitch_mm, origins, error)) return false;
  if (!c->calibration.empty()) {
    // The calibrated camera for the other stages that project: motion blur's
    // pinhole, and cos4's one focal length (centred on the frame): sqrt(fx fy).
    const LensModel& lens = p.distortion.lens;
    p.motion_blur.fx_px = lens.fx;
    p.motion_blur.fy_px = lens.fy;
    p.motion_blur.cx_px = lens.cx;
    p.motion_blur.cy_px = lens.cy;
    p.vignetting.focal_length_px = std::sqrt(lens.fx * lens.fy);
  }
  if (!ResolveEnvironment(c, origins, error)) return false;
  p.sensor.defects = nullptr;
  p.sensor.defect_count = 0;
  if (!c->defects_file.empty()) {
    auto list = std::make_shared<std::vector<DefectPixel>>();
    if (!LoadDefectsFile(c->defects_file, p.geometry.width, p.geometry.height, p.geometry.adc_bits, list.get(),
                         error)) {
      *error = KeyWhere(origins, "sensor.defects_file") + ": " + *error;
      return false;
    }
    c->defects_data = list;
    p.sensor.defects = list->data();
    p.sensor.defect_count = static_cast<int>(list->size());
  }
  auto probe = std::make_unique<Pipeline>();
  const Status s = probe->Configure(p, workers, !c->vignetting_mask.empty(), previous);
  if (!s.ok()) {
    *error = DescribeStatus(s, origins);
    return false;
  }
  if (c->auto_exposure.mode != AutoExposureMode::kOff) {
    AutoExposure ae;
    const Status a = ae.Configure(c->auto_exposure, {p.exposure.exposure_time_us, p.sensor.gain_db, p.exposure.f_number});
    if (!a.ok()) {
      *error = DescribeStatus(a, origins);
      return false;
    }
    if (c->metering == Metering::kImage && c->metering_image.empty()) {
      *error = DescribeStatus(InvalidArgument("auto_exposure.metering_image", "metering = \"image\" needs a weight image"),
                              origins);
      return false;
    }
    // The controller may move anywhere in its range, and only configuration
    // may fail: the stages must take every setting it can reach. Their limits
    // are monotone in exposure time, gain and f-number, so its corners suffice.
    const AutoExposureConfig& range = c->auto_exposure;
    const bool aperture = range.f_number_min > 0 || range.f_number_max > 0;
    struct End {
      double value;
      const char* key;
    };
    const End times[2] = {{range.exposure_time_min_us, "auto_exposure.exposure_time_min_us"},
                          {range.exposure_time_max_us, "auto_exposure.exposure_time_max_us"}};
    const End gains[2] = {{range.gain_min_db, "auto_exposure.gain_min_db"}, {range.gain_max_db, "auto_exposure.gain_max_db"}};
    const End stops[2] = {{aperture ? range.f_number_min : p.exposure.f_number, "auto_exposure.f_number_min"},
                          {aperture ? range.f_number_max : p.exposure.f_number, "auto_exposure.f_number_max"}};
    for (const End& t : times)
      for (const End& g : gains)
        for (const End& f : stops) {
          PipelineConfig q = p;
          q.exposure.exposure_time_us = t.value;
          q.sensor.gain_db = g.value;
          q.exposure.f_number = f.value;
          Pipeline corner;  // borrows what the probe solved (the lens grid's band ranges)
          const Status cs = corner.Configure(q, workers, !c->vignetting_mask.empty(), probe.get());
          if (cs.ok()) continue;
          std::string at = std::string(t.key) + " = " + FormatNumber(t.value) + ", " + g.key + " = " +
                           FormatNumber(g.value);
          if (aperture) at += std::string(", ") + f.key + " = " + FormatNumber(f.value);
          *error = "auto_exposure: the stages refuse a setting in its range (" + at + "): " +
                   DescribeStatus(cs, origins) + "; narrow the range";
          return false;
        }
  }
  if (configured != nullptr) *configured = std::move(probe);
  outcome.ok = true;
  return true;
}

}  // namespace camsim::host
