#include "core/pipeline/pipeline_ref.h"

#include "core/lens/dof_ref.h"
#include "core/lens/flare_ref.h"
#include "core/sensor/blooming_ref.h"

#include <algorithm>
#include <cmath>

#include "core/lens/motion_blur_ref.h"
#include "core/lens/distortion_ref.h"

namespace camsim::ref {
namespace {

// The largest value a Q24.8 photon sample holds (the stages saturate there).
constexpr double kMaxPhotons = 4294967295.0 / 256.0;

RefImage Like(const RefImage& in, size_t planes) {
  RefImage out;
  out.width = in.width;
  out.height = in.height;
  out.planes.assign(planes, std::vector<double>(static_cast<size_t>(in.width) * in.height, 0.0));
  return out;
}

}  // namespace

double SampleToReal(Domain d, uint32_t sample) {
  switch (d) {
    case Domain::kRadiance:
    case Domain::kPhotons: return std::ldexp(static_cast<double>(sample), -DomainFracBits(d));
    case Domain::kDigital:
    case Domain::kLinear:
    case Domain::kEncoded: return static_cast<double>(sample);
  }
  return 0.0;
}

std::vector<uint8_t> FillDisagreement(const Pipeline& p, int index) {
  StageId id = StageId::kCount;
  StageFromName(p.running_stage(index).name(), &id);
  if (id != StageId::kDistortion) return {};
  const PipelineConfig& c = p.config();
  const SensorGeometry& g = c.geometry;
  const auto& stage = static_cast<const DistortionStage&>(p.running_stage(index));
  const ReferenceDistortion d(c.distortion, g);
  const int w = g.width, h = g.height;
  std::vector<uint8_t> out(static_cast<size_t>(w) * h, 0);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x)
      for (int k = 0; k < 3; ++k) {
        if (stage.site_only() && k != CfaColour(g.cfa, x, y)) continue;
        // Both sides' whole fill rule: no source, or a source off the image.
        int64_t fx, fy;
        const int64_t half = int64_t{1} << 15;  // 0.5 px in Q.16
        const bool fixed_fills = !stage.SourcePosition(x, y, k, &fx, &fy) || fx < -half || fy < -half ||
                                 fx > (int64_t{w} << 16) - half || fy > (int64_t{h} << 16) - half;
        double rx, ry;
        const bool ref_fills =
            !d.Source(x, y, k, &rx, &ry) || rx < -0.5 || ry < -0.5 || rx > w - 0.5 || ry > h - 0.5;
        if (fixed_fills != ref_fills) out[static_cast<size_t>(y) * w + x] = 1;
      }
  return out;
}

RefImage SceneRadiance(const FrameInput& input, int w, int h) {
  RefImage out;
  out.width = w;
  out.height = h;
  out.planes.assign(3, std::vector<double>(static_cast<size_t>(w) * h));
  for (int c = 0; c < 3; ++c)
    for (int y = 0; y < h; ++y)
      for (int x = 0; x < w; ++x)
        out.planes[c][static_cast<size_t>(y) * w + x] = SampleToReal(Domain::kRadiance, input.radiance[c].row(y)[x]);
  return out;
}

RefImage RunStageReference(const Pipeline& p, int index, const RefImage& in, const FrameInput& input) {
  const PipelineConfig& c = p.config();
  const SensorGeometry& g = c.geometry;
  const int w = in.width, h = in.height;
  const char* name = p.running_stage(index).name();
  StageId id = StageId::kCount;
  StageFromName(name, &id);
  const auto at = [w](int x, int y) { return static_cast<size_t>(y) * w + x; };
  switch (id) {
    case StageId::kDofGather:
    case StageId::kDofRows:
    case StageId::kDofColumns: {
      // Radiance in physical units: the passes are linear, so units do not matter.
      RefImage out = Like(in, in.planes.size());
      const uint32_t* iz = input.inverse_depth.data;
      const bool depth = c.dof.method == DofMethod::kDiffusion && !c.dof.structural_only;
      for (size_t k = 0; k < in.planes.size(); ++k) {
        if (id == StageId::kDofGather) {
          DofConfig uncapped = c.dof;  // the model's disc: radius coc / 2, not capped by the knob
          uncapped.max_radius_px = DofGatherStage::kMaxRadius;
          out.planes[k] = ReferenceGather(in.planes[k], ReferenceGatherRadius(uncapped, c.exposure.f_number, iz, w, h), w, h);
        } else {
          const std::vector<double> cc2 = ReferenceCc2(c.dof, c.exposure.f_number, iz, w, h, depth);
          out.planes[k] = id == StageId::kDofRows ? ReferenceDiffusionRows(in.planes[k], cc2, w, h)
                                                  : ReferenceDiffusionColumns(in.planes[k], cc2, w, h, -1);
        }
      }
      return out;
    }
    case StageId::kDistortion: {
      const auto& stage = static_cast<const DistortionStage&>(p.running_stage(index));
      const ReferenceDistortion d(c.distortion, g);
      // Before a Bayer CFA the stage computes only each site's colour, into a mosaic.
      RefImage out = Like(in, stage.site_only() ? 1 : in.planes.size());
      for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x)
          for (int k = 0; k < static_cast<int>(in.planes.size()); ++k) {
            if (stage.site_only() && k != CfaColour(g.cfa, x, y)) continue;
            out.planes[stage.site_only() ? 0 : k][at(x, y)] = d.Sample(in.planes[k].data(), x, y, k);
          }
      return out;
    }
    case StageId::kFlare: return RefFlare(c.flare, g, in);
    case StageId::kExposure: {
      RefImage out = Like(in, in.planes.size());
      for (size_t k = 0; k < in.planes.size(); ++k)
        for (size_t i = 0; i < in.planes[k].size(); ++i)
          out.planes[k][i] = std::min(ReferenceExposure(c.exposure, in.planes[k][i]), kMaxPhotons);
      return out;
    }
    case StageId::kMotionBlur: {
      // Inverse depth Q12.20 (invalid: far, 0) and vectors Q16.16 as doubles, when present.
      std::vector<double> iz, vec[2];
      MotionRefInput mi;
      mi.width = w;
      mi.height = h;
      for (int k = 0; k < 3; ++k) mi.plane[k] = &in.planes[static_cast<size_t>(k)];
      if (input.inverse_depth.data != nullptr) {
        iz.resize(static_cast<size_t>(w) * h);
        for (int y = 0; y < h; ++y)
          for (int x = 0; x < w; ++x) {
            const uint32_t v = input.inverse_depth.row(y)[x];
            iz[at(x, y)] = v == kInvalidInverseDepth ? 0.0 : std::ldexp(v, -kInverseDepthFracBits);
          }
        mi.inverse_depth = &iz;
      }
      for (int k = 0; k < 2; ++k)
        if (input.motion_vectors[k].data != nullptr) {
          vec[k].resize(static_cast<size_t>(w) * h);
          for (int y = 0; y < h; ++y)
            for (int x = 0; x < w; ++x) vec[k][at(x, y)] = std::ldexp(input.motion_vectors[k].row(y)[x], -16);
          mi.vectors[k] = &vec[k];
        }
      RefImage out = Like(in, 3);
      // The continuous time integral: the error includes max_samples' sampling.
      out.planes = RefMotionBlur(c.motion_blur, mi, c.exposure.exposure_time_us, true);
      return out;
    }
    case StageId::kVignetting: {
      RefImage out = Like(in, in.planes.size());
      for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x) {
          const double gain = c.vignetting.mode == VignettingMode::kMask
                                  ? input.vignetting_mask.row(y)[x] / 16384.0  // Q2.14
                                  : ReferenceVignettingGain(c.vignetting, g, x, y);
          for (size_t k = 0; k < in.planes.size(); ++k)
            out.planes[k][at(x, y)] = std::min(in.planes[k][at(x, y)] * gain, kMaxPhotons);
        }
      return out;
    }
    case StageId::kCfa: {
      RefImage out = Like(in, 1);
      double weight[3] = {0, 0, 0};
      const double sum = c.cfa.mono_weights[0] + c.cfa.mono_weights[1] + c.cfa.mono_weights[2];
      for (int k = 0; k < 3; ++k) weight[k] = c.cfa.mono_weights[k] / sum;
      for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x) {
          const size_t i = at(x, y);
          out.planes[0][i] = g.cfa == Cfa::kMono
                                 ? weight[0] * in.planes[0][i] + weight[1] * in.planes[1][i] + weight[2] * in.planes[2][i]
                                 : in.planes[CfaColour(g.cfa, x, y)][i];
        }
      return out;
    }
    case StageId::kBlooming: {
      // The whole-column model on each plane's charge (photons * QE of the site's colour).
      RefImage out = Like(in, in.planes.size());
      for (size_t k = 0; k < in.planes.size(); ++k)
        for (int x = 0; x < w; ++x) {
          std::vector<double> charge(static_cast<size_t>(h)), qe(static_cast<size_t>(h));
          for (int y = 0; y < h; ++y) {
            const Colour col = in.planes.size() == 3 ? static_cast<Colour>(k) : CfaColour(g.cfa, x, y);
            qe[y] = c.sensor.quantum_efficiency[col];
            charge[y] = in.planes[k][at(x, y)] * qe[y];
          }
          const std::vector<double> bloomed = RefBloomColumn(charge, c.sensor.full_well_e);
          for (int y = 0; y < h; ++y) {
            double& o = out.planes[k][at(x, y)];
            if (qe[y] <= 0)
              o = in.planes[k][at(x, y)];
            else if (bloomed[y] >= c.sensor.full_well_e && bloomed[y] != charge[y])
              o = kFullWellPhotons / 256.0;  // a well blooming left full reads saturated (blooming.h)
            else
              o = bloomed[y] / qe[y];
          }
        }
      return out;
    }
    case StageId::kSensor: {
      // A mosaic (one plane, each site's colour) or one sensor per colour
      // (three planes, without a CFA stage before it).
      RefImage out = Like(in, in.planes.size());
      const int planes = static_cast<int>(in.planes.size());
      for (int k = 0; k < planes; ++k)
        for (int y = 0; y < h; ++y)
          for (int x = 0; x < w; ++x) {
            const Colour col = planes == 3 ? static_cast<Colour>(k) : CfaColour(g.cfa, x, y);
            out.planes[k][at(x, y)] = ReferenceSensorMeanDn(c.sensor, g, c.exposure.exposure_time_us, col,
                                                            in.planes[k][at(x, y)]);
          }
      return out;
    }
    case StageId::kBlackLevel: return RefBlackLevel(in, BlackLevelInUse(c.black_level, c.sensor.black_level_dn), g.adc_bits);
    case StageId::kWhiteBalance: return RefWhiteBalance(in, g.cfa, c.white_balance, PipelineWhiteLevel(c));
    case StageId::kDemosaic:
      return c.demosaic.method == DemosaicMethod::kMalvar ? RefDemosaicMalvar(in, g.cfa) : RefDemosaicBilinear(in, g.cfa);
    case StageId::kColorMatrix: return RefColorMatrix(in, c.color_matrix.m);
    case StageId::kGamma: return RefGamma(in, c.gamma);
    case StageId::kCount: break;
  }
  return in;
}

}  // namespace camsim::ref
