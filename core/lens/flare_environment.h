// Lens flare from an environment map (the paper's third flare input): bright
// light OUTSIDE the field of view still enters the lens and adds glare, ghosts
// and veiling haze. Configure-time only: the map is turned once into a
// bounded list of point sources, which the flare stage then treats like the
// bright tiles of the frame (core/lens/flare.h); per-pixel work stays integer.
//
// Map: a lat-long (equirectangular) RGB radiance image, in the scene's
// radiance units (1.0 ~ white paper), times `gain`. Texel (i, j) of a
// W x H map (W = 2 H) has its centre at longitude lambda = 2 pi (i + 0.5) / W - pi
// and latitude phi = pi / 2 - pi (j + 0.5) / H (row 0 is the zenith), i.e. the
// world direction (cos phi sin lambda, sin phi, cos phi cos lambda) with
// y up; the map's centre is straight ahead, its right half to the right.
// The environment is at infinity (no parallax).
//
// Camera orientation in the map (camera-to-world): yaw turns the camera to
// the right (towards larger longitude), then pitch tilts it up, then roll
// turns it clockwise about its viewing axis as seen from behind it (so the
// picture turns anticlockwise). With all three 0 the camera looks at the map's
// centre, image x along +lambda, image y downwards.
//
// Projection: ideal pinhole with the lens's fx, fy, cx, cy (pixels): a
// direction with camera coordinates (X right, Y down, Z forward), Z > 0, lands
// at u = cx + fx X / Z, v = cy + fy Y / Z. Lens distortion is ignored for
// these sources (they are outside the distortion's calibrated field anyway).
//
// Per texel above the threshold (any channel of radiance * gain above
// flare.threshold, the same Q16.16 threshold as the frame's pixels):
//   excess_c = (L_c * gain - threshold) * Omega_texel * fx * fy
// in radiance x pixels: the texel's solid angle
//   Omega_texel = (2 pi / W) (sin phi_top - sin phi_bottom)   (exact, sums to 4 pi)
// counted in on-axis pixel solid angles 1 / (fx fy). (Obliquity factors, the
// cos^3 of off-axis pixel solid angles and the cos of the aperture seen
// obliquely, are neglected, as the frame's flare neglects them.)
// Then by where its centre direction projects:
//   inside the frame ([-0.5, W - 0.5) x [-0.5, H - 0.5)): skipped, the
//       renderer drew it and the frame pre-pass counts it (no double count);
//   in front of the camera (Z > 0), within kMaxFlareOffset pixels of the
//       principal point on both axes, and close enough that its glare
//       (within glare_radius of the frame) or one of its ghosts (within its
//       ghost_radius_px) can reach the frame: a source candidate at the
//       rounded position;
//   otherwise (behind the camera, too far off-axis, or no effect in the
//       frame): veiling haze only.
// Every texel outside the frame adds its excess to the haze:
//   haze per pixel += flare.haze * sum(excess) / (width * height),
// as the frame's bright tiles do. The `max_sources` strongest candidates
// (by excess summed over R, G, B; ties: smaller y, then smaller x, then larger
// R, then larger G excess, so equal keys are identical sources) become
// FlareSources with glare = glare_fraction x excess (the exact fraction, not
// its Q0.16 share; added light: the texel is not in the frame to lose it;
// but glare is on only when that share is not 0, as for the frame) and
// ghosts as for frame sources; weaker
// candidates count as haze only.
//
// Formats: excess Q16.16 radiance x pixels in uint64, rounded to nearest and
// clamped to kMaxEnvironmentExcess per channel; the haze sum saturates at
// 2^64 - 1; positions int32 pixels, rounded ties up, |pos - principal point| <=
// kMaxFlareOffset (so the stage's integer ghost and glare arithmetic cannot
// overflow). Deterministic: IEEE + - * / and core/base/detmath.h only; cost
// follows the number of bright texels (2 detmath calls each) plus 4 per row.
#pragma once

#include <cstdint>

#include "core/base/span.h"
#include "core/base/status.h"
#include "core/pipeline/stage.h"

namespace camsim {

struct FlareConfig;
struct FlareSource;

inline constexpr int kMaxEnvironmentSources = 1024;
inline constexpr int kMaxEnvironmentWidth = 16384;
inline constexpr int64_t kMaxEnvironmentTexels = int64_t{1} << 25;  // the EXR loader's limit
inline constexpr int32_t kMaxFlareOffset = 1 << 20;               // pixels from the principal point
inline constexpr uint64_t kMaxEnvironmentExcess = uint64_t{1} << 46;  // Q16.16: 2^30 radiance x pixels

struct FlareEnvironment {
  const float* texels = nullptr;  // R, G, B interleaved, width * height * 3; null = no map
  int width = 0, height = 0;      // width = 2 * height, 4 .. 16384 wide
  double yaw_deg = 0.0;           // [-360, 360]
  double pitch_deg = 0.0;         // [-90, 90]
  double roll_deg = 0.0;          // [-360, 360]
  double gain = 1.0;              // radiance scale of the map, [0, 1e6]
  int max_sources = 64;           // 1 .. kMaxEnvironmentSources
  // Pinhole camera, pixels (the host fills them from the lens model).
  double fx = 0.0, fy = 0.0, cx = 0.0, cy = 0.0;
};

// What the map gave (for the run report).
struct FlareEnvironmentSummary {
  int sources = 0;              // FlareSources kept
  int64_t bright_texels = 0;    // texels above the threshold
  int64_t in_frame = 0;         // of those: inside the frame (skipped)
  int64_t haze_only = 0;        // of those: veiling haze only (behind, far off-axis, no reach, or over the cap)
  uint64_t haze_excess[3] = {}; // Q16.16 radiance x pixels, all bright texels outside the frame
};

// Validates flare.environment_* (a map, when given, must be 2:1 and hold finite
// texels >= 0; errors name the key). Called by FlareStage::Configure.
Status ValidateFlareEnvironment(const FlareEnvironment& env, const SensorGeometry& geometry);

// Sources the stage keeps for the map: 0 without a map or with flare off.
int FlareEnvironmentCapacity(const FlareConfig& config);

// Builds the map's sources, strongest first, into `storage` (capacity
// FlareEnvironmentCapacity; smaller storage keeps fewer). The config must have
// passed FlareStage::Configure.
void ComputeFlareEnvironment(const FlareConfig& config, const SensorGeometry& geometry, Span<FlareSource> storage,
                             FlareEnvironmentSummary* out);

}  // namespace camsim
