#include "renderer.hpp"
#include "rankslam/core/units.hpp"

#include "random.hpp"

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstring>
#include <limits>
#include <numbers>
#include <thread>

namespace rankslam::sim::detail {
namespace {

constexpr float kNoHit = std::numeric_limits<float>::infinity();
// Seam tolerance: neighbouring pieces of one surface and box edges must not leave cracks.
constexpr float kSeamTolerance_m = 1e-4f;
// Lightmap sample spacing; Lambertian lighting from lamps is smooth at this scale.
constexpr double kLightmapStep_m = 0.08;

// Kinect depth: disparity from the IR camera (focal ≈ 580 px) and the projector 7.5 cm away,
// measured to 1/8 px; σ_z ≈ 1.425e-3·z² (Khoshelham & Elberink 2012) is the disparity noise
// σ_d = 1.425e-3·f·b.
constexpr float kDepthFocal_px = 580.0f;
constexpr float kProjectorBaseline_m = 0.075f;
constexpr float kDepthFb = kDepthFocal_px * kProjectorBaseline_m;
constexpr float kDisparitySigma_px = 1.425e-3f * kDepthFb;
constexpr float kDisparitySteps = 8.0f;
// Below this |cos(incidence)| the Kinect returns nothing; up to kGrazingSoft it drops out at
// random with rising probability.
constexpr float kGrazingHard = 0.08f;
constexpr float kGrazingSoft = 0.16f;
constexpr float kRandomDropout = 0.002f;

// IR image: the projector lights the scene mostly through its dots.
constexpr float kSpeckleFill = 0.35f;
constexpr float kSpeckleGain = 1.3f;
constexpr int kSpeckleMargin_px = 176;  // largest dot shift kept: f·b/z at z ≈ 0.22 m

// Noise streams.
constexpr std::uint64_t kStreamRgb = 1;
constexpr std::uint64_t kStreamDepth = 2;
constexpr std::uint64_t kStreamIr = 3;
constexpr std::uint64_t kStreamFisheye = 4;

// Four-lane vectors (GCC vector extensions: SSE2 on x86-64, NEON on aarch64) for the caster's
// inner loop and for shading the colour channels together.
using F4 = float __attribute__((vector_size(16)));
using I4 = std::int32_t __attribute__((vector_size(16)));
inline F4 load4(const float* p) {
  F4 v;
  std::memcpy(&v, p, sizeof v);
  return v;
}
inline I4 load4(const std::int32_t* p) {
  I4 v;
  std::memcpy(&v, p, sizeof v);
  return v;
}
inline void store4(float* p, F4 v) { std::memcpy(p, &v, sizeof v); }
inline void store4(std::int32_t* p, I4 v) { std::memcpy(p, &v, sizeof v); }

// floor(log2(x)) for positive normal floats.
int floor_log2(float x) { return static_cast<int>((std::bit_cast<std::uint32_t>(x) >> 23U) & 0xFFU) - 127; }

double inverse_normal_cdf(double p) {
  double lo = -10.0;
  double hi = 10.0;
  for (int i = 0; i < 200; ++i) {
    const double mid = 0.5 * (lo + hi);
    if (0.5 * std::erfc(-mid / std::numbers::sqrt2) < p) {
      lo = mid;
    } else {
      hi = mid;
    }
  }
  return 0.5 * (lo + hi);
}

// A BGRA texel as floats B, G·256, R·65536, 0 (masking a broadcast is four SSE2
// instructions); the lane scales are undone once after filtering, exactly (powers of two).
inline F4 texel(const std::uint8_t* row, int u) {
  std::int32_t bits;
  std::memcpy(&bits, row + 4 * u, sizeof bits);
  const I4 broadcast = {bits, bits, bits, bits};
  const I4 mask = {0xFF, 0xFF00, 0xFF0000, 0};
  return __builtin_convertvector(broadcast & mask, F4);
}

// Bilinear, wrapping lookup in one mip level (power-of-two sides); tu, tv in texels, ≥ 0.5
// (texture origins are shifted by whole periods to keep them positive, so truncation is
// floor). Returns B, G, R in 0..1 and 0.
inline F4 sample_texture(const TextureLevel& level, float tu, float tv) {
  tu -= 0.5f;
  tv -= 0.5f;
  const int fu = static_cast<int>(tu);
  const int fv = static_cast<int>(tv);
  const float au = tu - static_cast<float>(fu);
  const float av = tv - static_cast<float>(fv);
  const int u0 = fu & level.mask_u;
  const int u1 = (fu + 1) & level.mask_u;
  const std::uint8_t* row0 = level.texels + static_cast<std::ptrdiff_t>(4 * (fv & level.mask_v) * level.stride);
  const std::uint8_t* row1 = level.texels + static_cast<std::ptrdiff_t>(4 * ((fv + 1) & level.mask_v) * level.stride);
  const F4 t00 = texel(row0, u0);
  const F4 t10 = texel(row1, u0);
  const F4 top = t00 + (texel(row0, u1) - t00) * au;
  const F4 bottom = t10 + (texel(row1, u1) - t10) * au;
  const F4 scale = {1.0f / 255.0f, 1.0f / (255.0f * 256.0f), 1.0f / (255.0f * 65536.0f), 0.0f};
  return (top + (bottom - top) * av) * scale;
}

template <typename Fn>
void parallel_for(int threads, int count, Fn&& fn) {
  threads = std::max(1, std::min(threads, count));
  if (threads == 1) {
    for (int i = 0; i < count; ++i) fn(i);
    return;
  }
  std::vector<std::thread> pool;
  for (int t = 0; t < threads; ++t) {
    pool.emplace_back([&, t] {
      for (int i = t; i < count; i += threads) fn(i);
    });
  }
  for (auto& thread : pool) thread.join();
}

}  // namespace

BandWorkspace::BandWorkspace(int max_width, std::size_t max_quads) {
  const std::size_t n = static_cast<std::size_t>(max_width) * CameraRays::kTile;
  t.assign(n, 0.0f);
  s.assign(n, 0.0f);
  r.assign(n, 0.0f);
  hit.assign(n, -1);
  acc.assign(4 * n, 0.0f);
  shadowed.assign(n, 0);
  candidates.assign(std::max<std::size_t>(max_quads, 1), 0);
}

Renderer::Renderer(const SceneModel& scene, const Settings& settings)
    : scene_(scene), settings_(settings), rgb_rays_(scene.calibration.rgb, std::numbers::pi / 2) {
  if (scene.calibration.fisheye) {
    fisheye_rays_.emplace_back(*scene.calibration.fisheye, deg_to_rad(95.0));
  }
  // Flattened mip levels of every texture.
  std::vector<std::size_t> first_level;
  for (const auto& texture : scene.textures) {
    first_level.push_back(texture_levels_.size());
    for (const auto& level : texture.levels) {
      TextureLevel flat;
      flat.texels = level.ptr<std::uint8_t>(0);
      flat.mask_u = level.cols - 1;
      flat.mask_v = level.rows - 1;
      flat.stride = static_cast<int>(level.step[0] / sizeof(std::uint32_t));
      texture_levels_.push_back(flat);
    }
  }
  shading_.resize(scene.surfaces.size());
  for (std::size_t i = 0; i < scene.surfaces.size(); ++i) {
    const SurfaceQuad& quad = scene.surfaces[i];
    const Material& material = scene.materials[static_cast<std::size_t>(quad.material)];
    QuadShading& sh = shading_[i];
    sh.texture = material.texture >= 0 ? &scene.textures[static_cast<std::size_t>(material.texture)] : nullptr;
    sh.levels = sh.texture ? texture_levels_.data() + first_level[static_cast<std::size_t>(material.texture)] : nullptr;
    // Texture coordinates at s = 0, r = 0; shifted by whole texture periods (which changes
    // nothing on a tiling texture) so every coordinate on the quad is at least one period.
    double origin_u = quad.texture_origin_m.x() + quad.half_u_m;
    double origin_v = quad.texture_origin_m.y() + quad.half_v_m;
    if (sh.texture) {
      const cv::Mat& level0 = sh.texture->levels.front();
      const double period_u = level0.cols * sh.texture->texel_m;
      const double period_v = level0.rows * sh.texture->texel_m;
      origin_u += period_u * (std::ceil((quad.half_u_m + 1e-3 - origin_u) / period_u) + 1.0);
      origin_v += period_v * (std::ceil((quad.half_v_m + 1e-3 - origin_v) / period_v) + 1.0);
    }
    sh.origin_u = static_cast<float>(origin_u);
    sh.origin_v = static_cast<float>(origin_v);
    sh.albedo = {material.albedo_bgr[0], material.albedo_bgr[1], material.albedo_bgr[2], 0.0f};
    sh.emission = {material.emission, material.emission, material.emission, 0.0f};
    sh.ir_reflectance = material.ir_reflectance;
    sh.ir_contrast = sh.texture ? material.ir_texture_contrast : 0.0f;
    sh.inv_mean_gray = sh.texture ? 1.0f / std::max(sh.texture->mean_gray, 0.02f) : 1.0f;
    if (sh.texture) {
      sh.inv_texel = static_cast<float>(1.0 / sh.texture->texel_m);
      sh.inv_texel2 = sh.inv_texel * sh.inv_texel;
      sh.max_level = static_cast<int>(sh.texture->levels.size()) - 1;
    }
    sh.half_u = static_cast<float>(quad.half_u_m);
    sh.half_v = static_cast<float>(quad.half_v_m);
  }
  bake_lightmaps(settings.threads);

  // Fixed exposure: the area-weighted mean reflected radiance reads photometry.exposure_key.
  double weighted = 0.0;
  double area = 0.0;
  for (std::size_t i = 0; i < scene.surfaces.size(); ++i) {
    const SurfaceQuad& quad = scene.surfaces[i];
    const Material& material = scene.materials[static_cast<std::size_t>(quad.material)];
    if (material.emission > 0.0f) continue;
    const QuadShading& sh = shading_[i];
    double mean_e = 0.0;
    const std::size_t n = static_cast<std::size_t>(sh.lm_nu) * static_cast<std::size_t>(sh.lm_nv);
    for (std::size_t k = 0; k < n; ++k) mean_e += static_cast<double>(lightmap_[sh.lightmap + k]);
    mean_e /= static_cast<double>(n);
    const Eigen::Vector3d albedo = material.albedo_bgr.cast<double>();
    const double gray = (0.114 * albedo[0] + 0.587 * albedo[1] + 0.299 * albedo[2]) *
                        static_cast<double>(sh.texture ? sh.texture->mean_gray : 1.0f);
    const double a = 4.0 * quad.half_u_m * quad.half_v_m;
    weighted += a * gray * mean_e;
    area += a;
  }
  exposure_ = static_cast<float>(scene.photometry.exposure_key / std::max(weighted / std::max(area, 1e-9), 1e-9));
  fisheye_exposure_ = exposure_ * static_cast<float>(scene.photometry.fisheye_exposure);

  // Colour output: linear value → gamma 1/2.2 → 8-bit level, plus Gaussian read noise and
  // shot noise (variance growing with the signal), all folded into one table.
  std::array<double, kNoiseSteps> quantiles{};
  double variance = 0.0;
  for (int j = 0; j < kNoiseSteps; ++j) {
    quantiles[static_cast<std::size_t>(j)] = inverse_normal_cdf((j + 0.5) / kNoiseSteps);
    variance += quantiles[static_cast<std::size_t>(j)] * quantiles[static_cast<std::size_t>(j)] / kNoiseSteps;
  }
  for (auto& q : quantiles) q /= std::sqrt(variance);  // unit variance despite the cut tails
  color_lut_.resize(static_cast<std::size_t>(kLinearSteps) * kNoiseSteps);
  const double read2 = scene.photometry.read_noise_levels * scene.photometry.read_noise_levels;
  for (int i = 0; i < kLinearSteps; ++i) {
    const double level = 255.0 * std::pow(static_cast<double>(i) / (kLinearSteps - 1), 1.0 / 2.2);
    clean_lut_[static_cast<std::size_t>(i)] = static_cast<std::uint8_t>(std::clamp(std::floor(level + 0.5), 0.0, 255.0));
    const double sigma = std::sqrt(read2 + scene.photometry.shot_noise_gain * level);
    for (int j = 0; j < kNoiseSteps; ++j) {
      const double noisy = level + sigma * quantiles[static_cast<std::size_t>(j)];
      color_lut_[static_cast<std::size_t>(i * kNoiseSteps + j)] =
          static_cast<std::uint8_t>(std::clamp(std::floor(noisy + 0.5), 0.0, 255.0));
    }
  }
  for (std::size_t i = 0; i < gaussian_.size(); ++i) {
    gaussian_[i] = static_cast<float>(inverse_normal_cdf((static_cast<double>(i) + 0.5) / static_cast<double>(gaussian_.size())));
  }
  fb_projector_px_ = static_cast<float>(scene.calibration.rgb.fx) * kProjectorBaseline_m;
  if (scene.has_ir) build_speckle_pattern();
}

void Renderer::bake_lightmaps(int threads) {
  const auto& quads = scene_.surfaces;
  std::uint32_t total = 0;
  for (std::size_t i = 0; i < quads.size(); ++i) {
    QuadShading& sh = shading_[i];
    sh.lm_nu = std::max(2, static_cast<int>(std::ceil(2.0 * quads[i].half_u_m / kLightmapStep_m)) + 1);
    sh.lm_nv = std::max(2, static_cast<int>(std::ceil(2.0 * quads[i].half_v_m / kLightmapStep_m)) + 1);
    sh.lm_inv_step_u = static_cast<float>((sh.lm_nu - 1) / (2.0 * quads[i].half_u_m));
    sh.lm_inv_step_v = static_cast<float>((sh.lm_nv - 1) / (2.0 * quads[i].half_v_m));
    sh.lightmap = total;
    total += static_cast<std::uint32_t>(sh.lm_nu * sh.lm_nv);
  }
  lightmap_.assign(total, 0.0f);

  // Occluders for shadow rays: every non-emissive quad, both sides.
  struct Occluder {
    Eigen::Vector3d c, n, u, v;
    double hu, hv;
    std::size_t index;
  };
  std::vector<Occluder> occluders;
  for (std::size_t i = 0; i < quads.size(); ++i) {
    if (scene_.materials[static_cast<std::size_t>(quads[i].material)].emission > 0.0f) continue;
    occluders.push_back({quads[i].center_m, quads[i].normal(), quads[i].axis_u, quads[i].axis_v, quads[i].half_u_m,
                         quads[i].half_v_m, i});
  }
  const double soft2 = scene_.photometry.light_softening_m * scene_.photometry.light_softening_m;
  const double ambient = scene_.photometry.ambient;
  parallel_for(threads, static_cast<int>(quads.size()), [&](int qi) {
    const SurfaceQuad& quad = quads[static_cast<std::size_t>(qi)];
    const QuadShading& sh = shading_[static_cast<std::size_t>(qi)];
    const Eigen::Vector3d n = quad.normal();
    for (int j = 0; j < sh.lm_nv; ++j) {
      for (int i = 0; i < sh.lm_nu; ++i) {
        const Eigen::Vector3d p = quad.center_m + (-quad.half_u_m + i / static_cast<double>(sh.lm_inv_step_u)) * quad.axis_u +
                                  (-quad.half_v_m + j / static_cast<double>(sh.lm_inv_step_v)) * quad.axis_v;
        double e = ambient;
        for (const auto& light : scene_.lights) {
          const Eigen::Vector3d to_light = light.position_m - p;
          const double d2 = to_light.squaredNorm();
          const double cos_incidence = n.dot(to_light) / std::sqrt(d2);
          if (cos_incidence <= 0.0) continue;
          const Eigen::Vector3d origin = p + 1e-3 * n;
          const Eigen::Vector3d dir = light.position_m - origin;
          bool blocked = false;
          for (const auto& o : occluders) {
            if (o.index == static_cast<std::size_t>(qi)) continue;
            const double denom = dir.dot(o.n);
            if (std::abs(denom) < 1e-12) continue;
            const double t = (o.c - origin).dot(o.n) / denom;
            if (t <= 1e-6 || t >= 1.0 - 1e-6) continue;
            const Eigen::Vector3d h = origin + t * dir - o.c;
            if (std::abs(h.dot(o.u)) <= o.hu && std::abs(h.dot(o.v)) <= o.hv) {
              blocked = true;
              break;
            }
          }
          // Lamps hang from the ceiling and shine mostly downwards: (1 + cos)/2 of the angle
          // from straight down, so the ceiling above a lamp stays dim.
          const double downward = 0.5 * (1.0 + to_light.z() / std::sqrt(d2));
          if (!blocked) e += light.intensity * downward * cos_incidence / (d2 + soft2);
        }
        lightmap_[sh.lightmap + static_cast<std::uint32_t>(j * sh.lm_nu + i)] = static_cast<float>(e);
      }
    }
  });
}

void Renderer::build_speckle_pattern() {
  speckle_offset_ = kSpeckleMargin_px;
  speckle_width_ = rgb_rays_.width + kSpeckleMargin_px + 2;
  const int height = rgb_rays_.height;
  speckle_.assign(static_cast<std::size_t>(speckle_width_) * static_cast<std::size_t>(height), 0.0f);
  // A fixed pseudo-random dot pattern in projector pixels, about one dot per 9 px².
  Rng rng(settings_.seed ^ 0x5bec1e5ULL);
  const int dots = speckle_width_ * height / 9;
  constexpr double kSigma_px = 0.55;
  for (int k = 0; k < dots; ++k) {
    const double x = rng.uniform(0.0, speckle_width_);
    const double y = rng.uniform(0.0, height);
    const double amplitude = rng.uniform(0.6, 1.0);
    const int cx = static_cast<int>(x);
    const int cy = static_cast<int>(y);
    for (int v = std::max(0, cy - 1); v <= std::min(height - 1, cy + 1); ++v) {
      for (int u = std::max(0, cx - 1); u <= std::min(speckle_width_ - 1, cx + 1); ++u) {
        const double d2 = (u + 0.5 - x) * (u + 0.5 - x) + (v + 0.5 - y) * (v + 0.5 - y);
        float& cell = speckle_[static_cast<std::size_t>(v) * static_cast<std::size_t>(speckle_width_) + static_cast<std::size_t>(u)];
        cell = std::min(1.5f, cell + static_cast<float>(amplitude * std::exp(-d2 / (2 * kSigma_px * kSigma_px))));
      }
    }
  }
}

void Renderer::prepare_view(const CameraRays& rays, const Eigen::Isometry3d& T_world_cam, View& view) const {
  const Eigen::Matrix3d R = T_world_cam.linear().transpose();
  const Eigen::Vector3d p = T_world_cam.translation();
  view.quads.clear();
  for (std::size_t i = 0; i < scene_.surfaces.size(); ++i) {
    const SurfaceQuad& quad = scene_.surfaces[i];
    const Eigen::Vector3d c = R * (quad.center_m - p);
    const Eigen::Vector3d n = R * quad.normal();
    const double plane = c.dot(n);
    if (plane >= -1e-6) continue;  // seen from behind or edge-on
    const double radius = std::hypot(quad.half_u_m, quad.half_v_m);
    const double dist = c.norm();
    if (dist > radius) {
      const double phi = std::acos(std::clamp(c.z() / dist, -1.0, 1.0));
      if (phi > rays.frame_half_angle_rad + std::asin(radius / dist)) continue;
    }
    const Eigen::Vector3d u = R * quad.axis_u;
    const Eigen::Vector3d v = R * quad.axis_v;
    ViewQuad q{};
    q.nx = static_cast<float>(n.x());
    q.ny = static_cast<float>(n.y());
    q.nz = static_cast<float>(n.z());
    q.plane = static_cast<float>(plane);
    q.ux = static_cast<float>(u.x());
    q.uy = static_cast<float>(u.y());
    q.uz = static_cast<float>(u.z());
    q.cu = static_cast<float>(c.dot(u));
    q.vx = static_cast<float>(v.x());
    q.vy = static_cast<float>(v.y());
    q.vz = static_cast<float>(v.z());
    q.cv = static_cast<float>(c.dot(v));
    q.hu = static_cast<float>(quad.half_u_m) + kSeamTolerance_m;
    q.hv = static_cast<float>(quad.half_v_m) + kSeamTolerance_m;
    q.cx = static_cast<float>(c.x());
    q.cy = static_cast<float>(c.y());
    q.cz = static_cast<float>(c.z());
    q.radius = static_cast<float>(radius) + 2.0f * kSeamTolerance_m;
    for (int k = 0; k < 4; ++k) {
      const double su = (k == 0 || k == 3) ? -1.0 : 1.0;
      const double sv = k < 2 ? -1.0 : 1.0;
      const Eigen::Vector3d corner = c + su * (quad.half_u_m + 1e-3) * u + sv * (quad.half_v_m + 1e-3) * v;
      for (int a = 0; a < 3; ++a) q.corners[static_cast<std::size_t>(k)][static_cast<std::size_t>(a)] = static_cast<float>(corner[a]);
    }
    q.quad = static_cast<int>(i);
    view.quads.push_back(q);
  }
}

void Renderer::cast_band(const CameraRays& rays, const View& view, int y0, int rows, BandWorkspace& ws) const {
  const int width = rays.width;
  const int ty = y0 / CameraRays::kTile;
  const ViewQuad* quads = view.quads.data();
  const auto quad_count = static_cast<int>(view.quads.size());
  constexpr int kPixels = CameraRays::kTilePixels;
  for (int tx = 0; tx < rays.tiles_x; ++tx) {
    const std::size_t tile = static_cast<std::size_t>(ty * rays.tiles_x + tx);
    const CameraRays::Cone& cone = rays.tiles[tile];
    int candidates = 0;
    if (cone.any_valid) {
      for (int k = 0; k < quad_count; ++k) {
        const ViewQuad& q = quads[k];
        const float dist2 = q.cx * q.cx + q.cy * q.cy + q.cz * q.cz;
        if (dist2 > q.radius * q.radius) {
          // Bounding sphere against the tile's cone: angle to centre ≤ half angle + sphere radius.
          const float dist = std::sqrt(dist2);
          const float sin_b = q.radius / dist;
          const float cos_b = std::sqrt(1.0f - sin_b * sin_b);
          const float cos_phi = (cone.ax * q.cx + cone.ay * q.cy + cone.az * q.cz) / dist;
          if (cos_phi < cone.cos_half * cos_b - cone.sin_half * sin_b) continue;
        }
        if (cone.has_planes) {
          bool outside = false;
          for (const auto& n : cone.planes) {
            bool all_behind = true;
            for (const auto& c : q.corners) all_behind = all_behind && (n[0] * c[0] + n[1] * c[1] + n[2] * c[2] < 0.0f);
            if (all_behind) {
              outside = true;
              break;
            }
          }
          if (outside) continue;
        }
        ws.candidates[static_cast<std::size_t>(candidates++)] = static_cast<std::uint16_t>(k);
      }
    }
    // Nearest hit for the tile's pixels, one candidate at a time over contiguous arrays
    // (branch-free so the compiler can vectorise it).
    float* __restrict best_t = ws.tile_t.data();
    float* __restrict best_s = ws.tile_s.data();
    float* __restrict best_r = ws.tile_r.data();
    std::int32_t* __restrict best_hit = ws.tile_hit.data();
    const float* __restrict tdx = rays.tile_dx.data() + tile * kPixels;
    const float* __restrict tdy = rays.tile_dy.data() + tile * kPixels;
    const float* __restrict tdz = rays.tile_dz.data() + tile * kPixels;
    for (int j = 0; j < kPixels; ++j) {
      best_t[j] = kNoHit;
      best_s[j] = 0.0f;
      best_r[j] = 0.0f;
      best_hit[j] = -1;
    }
    for (int c = 0; c < candidates; ++c) {
      const int k = ws.candidates[static_cast<std::size_t>(c)];
      const ViewQuad& q = quads[k];
      for (int j = 0; j < kPixels; j += 4) {
        const F4 x = load4(tdx + j);
        const F4 y = load4(tdy + j);
        const F4 z = load4(tdz + j);
        F4 bt = load4(best_t + j);
        const F4 denom = x * q.nx + y * q.ny + z * q.nz;
        // Rays leaving the visible side (denom ≥ 0) and zero padding rays never hit.
        const F4 t = q.plane / (denom < -1e-12f ? denom : -1e-12f);
        const F4 s = t * (x * q.ux + y * q.uy + z * q.uz) - q.cu;
        const F4 r = t * (x * q.vx + y * q.vy + z * q.vz) - q.cv;
        const I4 hit = (denom < -1e-7f) & (t < bt) & (s <= q.hu) & (s >= -q.hu) & (r <= q.hv) & (r >= -q.hv);
        bt = hit ? t : bt;
        store4(best_t + j, bt);
        store4(best_s + j, hit ? s : load4(best_s + j));
        store4(best_r + j, hit ? r : load4(best_r + j));
        store4(best_hit + j, hit ? k : load4(best_hit + j));
      }
    }
    // Scatter into the band's row-major arrays.
    const int x0 = tx * CameraRays::kTile;
    const int columns = std::min(CameraRays::kTile, width - x0);
    for (int y = 0; y < rows; ++y) {
      const std::size_t w = static_cast<std::size_t>(y) * static_cast<std::size_t>(width) + static_cast<std::size_t>(x0);
      const std::size_t j = static_cast<std::size_t>(y * CameraRays::kTile);
      std::copy_n(best_t + j, columns, ws.t.data() + w);
      std::copy_n(best_s + j, columns, ws.s.data() + w);
      std::copy_n(best_r + j, columns, ws.r.data() + w);
      std::copy_n(best_hit + j, columns, ws.hit.data() + w);
    }
  }
}

void Renderer::projector_shadow(const CameraRays& rays, int y0, int rows, BandWorkspace& ws) const {
  // The projector sits 7.5 cm to the right of the camera, so a surface point at pixel u and
  // depth z is at projector column u − f·b/z. Scanning right to left, a point is in shadow
  // when something further right already reached a smaller projector column: that nearer
  // surface blocks the projector's ray.
  const int width = rays.width;
  for (int y = 0; y < rows; ++y) {
    const std::size_t ws_row = static_cast<std::size_t>(y) * static_cast<std::size_t>(width);
    const std::size_t row = static_cast<std::size_t>(y + y0) * static_cast<std::size_t>(width);
    float min_column = std::numeric_limits<float>::infinity();
    for (int x = width - 1; x >= 0; --x) {
      const std::size_t w = ws_row + static_cast<std::size_t>(x);
      if (ws.hit[w] < 0) {
        ws.shadowed[w] = 0;
        continue;
      }
      const float z = ws.t[w] * rays.dz[row + static_cast<std::size_t>(x)];
      const float column = static_cast<float>(x) - fb_projector_px_ / z;
      ws.shadowed[w] = column > min_column + 0.05f ? 1 : 0;
      min_column = std::min(min_column, column);
    }
  }
}

void Renderer::shade_band(const CameraRays& rays, const View& view, int y0, int rows, bool first, bool with_ir,
                          BandWorkspace& ws) const {
  const int width = rays.width;
  const Photometry& ph = scene_.photometry;
  const auto ir_ambient = static_cast<float>(ph.ir_ambient);
  const auto ir_power = static_cast<float>(ph.ir_projector_power);
  const float pixel_angle2 = rays.pixel_angle_rad * rays.pixel_angle_rad;
  const F4 ones = {1.0f, 1.0f, 1.0f, 1.0f};
  const F4 zeros = {0.0f, 0.0f, 0.0f, 0.0f};
  for (int y = 0; y < rows; ++y) {
    const std::size_t ws_row = static_cast<std::size_t>(y) * static_cast<std::size_t>(width);
    const std::size_t row = static_cast<std::size_t>(y + y0) * static_cast<std::size_t>(width);
    const float* speckle_row =
        with_ir ? speckle_.data() + static_cast<std::size_t>(y + y0) * static_cast<std::size_t>(speckle_width_) : nullptr;
    for (int x = 0; x < width; ++x) {
      const std::size_t w = ws_row + static_cast<std::size_t>(x);
      const std::size_t i = row + static_cast<std::size_t>(x);
      // B, G, R in lanes 0..2 and IR in lane 3.
      F4 color = zeros;
      const int k = ws.hit[w];
      if (k >= 0) {
        const ViewQuad& q = view.quads[static_cast<std::size_t>(k)];
        const QuadShading& sh = shading_[static_cast<std::size_t>(q.quad)];
        const float t = ws.t[w];
        const float s = ws.s[w];
        const float rr = ws.r[w];
        const float range = t / rays.inv_norm[i];
        const float cos_incidence =
            std::abs(rays.dx[i] * q.nx + rays.dy[i] * q.ny + rays.dz[i] * q.nz) * rays.inv_norm[i];
        F4 texture = ones;
        if (sh.texture) {
          // Mip level from the pixel's footprint on the surface (geometric mean of the two
          // axes): level = floor(log2(footprint / texel)), from the squared ratio.
          const float ratio2 = range * range * pixel_angle2 * sh.inv_texel2 / std::max(cos_incidence, 0.05f);
          const int level = ratio2 >= 1.0f ? std::min(floor_log2(ratio2) >> 1, sh.max_level) : 0;
          const float scale = sh.inv_texel / static_cast<float>(1 << level);
          texture = sample_texture(sh.levels[level], (sh.origin_u + s) * scale, (sh.origin_v - rr) * scale);
        }
        // Irradiance from the baked lightmap, bilinear.
        const float fu = std::clamp((s + sh.half_u) * sh.lm_inv_step_u, 0.0f, static_cast<float>(sh.lm_nu - 1) - 1e-3f);
        const float fv = std::clamp((rr + sh.half_v) * sh.lm_inv_step_v, 0.0f, static_cast<float>(sh.lm_nv - 1) - 1e-3f);
        const int iu = static_cast<int>(fu);
        const int iv = static_cast<int>(fv);
        const float au = fu - static_cast<float>(iu);
        const float av = fv - static_cast<float>(iv);
        const float* lm = lightmap_.data() + sh.lightmap + static_cast<std::size_t>(iv * sh.lm_nu + iu);
        const float e = (1.0f - av) * ((1.0f - au) * lm[0] + au * lm[1]) +
                        av * ((1.0f - au) * lm[sh.lm_nu] + au * lm[sh.lm_nu + 1]);
        color = load4(sh.albedo.data()) * texture * e + load4(sh.emission.data());
        if (with_ir) {
          float ir_albedo = sh.ir_reflectance;
          if (sh.texture) {
            const float lum = 0.114f * texture[0] + 0.587f * texture[1] + 0.299f * texture[2];
            ir_albedo *= std::clamp(1.0f + sh.ir_contrast * (lum * sh.inv_mean_gray - 1.0f), 0.03f, 2.0f);
          }
          float projector = 0.0f;
          if (!ws.shadowed[w]) {
            const float z = t * rays.dz[i];
            const float column = static_cast<float>(x) - fb_projector_px_ / z + static_cast<float>(speckle_offset_);
            float dots = 0.0f;
            if (column >= 0.0f && column < static_cast<float>(speckle_width_ - 1)) {
              const int c0 = static_cast<int>(column);
              const float a = column - static_cast<float>(c0);
              dots = (1.0f - a) * speckle_row[c0] + a * speckle_row[c0 + 1];
            }
            projector = ir_power * cos_incidence / (range * range) * (kSpeckleFill + kSpeckleGain * dots);
          }
          color[3] = ir_albedo * (ir_ambient + projector);
        }
      }
      float* acc = ws.acc.data() + 4 * w;
      store4(acc, first ? color : load4(acc) + color);
    }
  }
}

void Renderer::write_depth(const CameraRays& rays, const View& view, int y0, int rows, std::uint64_t frame,
                           cv::Mat& depth, const BandWorkspace& ws) const {
  const int width = rays.width;
  const std::uint64_t key = stream_key(settings_.seed, kStreamDepth, frame);
  const auto min_z = static_cast<float>(settings_.min_depth_m);
  const auto max_z = static_cast<float>(settings_.max_depth_m);
  const auto scale = static_cast<float>(scene_.calibration.depth_scale);
  for (int y = 0; y < rows; ++y) {
    auto* out = depth.ptr<std::uint16_t>(y0 + y);
    const std::size_t ws_row = static_cast<std::size_t>(y) * static_cast<std::size_t>(width);
    const std::size_t row = static_cast<std::size_t>(y + y0) * static_cast<std::size_t>(width);
    for (int x = 0; x < width; ++x) {
      const std::size_t w = ws_row + static_cast<std::size_t>(x);
      const std::size_t i = row + static_cast<std::size_t>(x);
      out[x] = 0;
      const int k = ws.hit[w];
      if (k < 0 || ws.shadowed[w]) continue;
      const ViewQuad& q = view.quads[static_cast<std::size_t>(k)];
      float z = ws.t[w] * rays.dz[i];
      const float cos_incidence = std::abs(rays.dx[i] * q.nx + rays.dy[i] * q.ny + rays.dz[i] * q.nz) * rays.inv_norm[i];
      if (z < min_z || z > max_z || cos_incidence < kGrazingHard) continue;
      if (settings_.sensor_noise) {
        const std::uint64_t h = element_hash(key, i);
        const float u1 = static_cast<float>((h >> 12U) & 0xFFFFFU) * 0x1.0p-20f;
        const float u2 = static_cast<float>((h >> 32U) & 0xFFFFFU) * 0x1.0p-20f;
        if (cos_incidence < kGrazingSoft && u1 < (kGrazingSoft - cos_incidence) / (kGrazingSoft - kGrazingHard)) continue;
        if (u2 < kRandomDropout) continue;
        float disparity = kDepthFb / z + kDisparitySigma_px * gaussian_[h & 0xFFFU];
        if (disparity <= 0.0f) continue;
        disparity = static_cast<float>(static_cast<int>(disparity * kDisparitySteps + 0.5f)) / kDisparitySteps;
        if (disparity <= 0.0f) continue;
        z = kDepthFb / disparity;
      }
      out[x] = static_cast<std::uint16_t>(std::min(std::max(z * scale + 0.5f, 1.0f), 65535.0f));
    }
  }
}

void Renderer::write_color(int width, int y0, int rows, float scale, std::uint64_t key, cv::Mat& image,
                           const BandWorkspace& ws) const {
  constexpr auto kMax = static_cast<float>(kLinearSteps - 1);
  for (int y = 0; y < rows; ++y) {
    auto* out = image.ptr<std::uint8_t>(y0 + y);
    const std::size_t ws_row = static_cast<std::size_t>(y) * static_cast<std::size_t>(width);
    const std::size_t row = static_cast<std::size_t>(y + y0) * static_cast<std::size_t>(width);
    const float* acc = ws.acc.data() + 4 * ws_row;
    if (settings_.sensor_noise) {
      const std::uint8_t* lut = color_lut_.data();
      const F4 gain = {scale * kMax, scale * kMax, scale * kMax, 0.0f};
      const F4 limit = {kMax, kMax, kMax, kMax};
      for (int x = 0; x < width; ++x) {
        const std::uint64_t h = element_hash(key, row + static_cast<std::size_t>(x));
        // Row of the table per channel (linear step), column from 8 bits of the hash.
        const F4 linear = load4(acc + 4 * x) * gain + 0.5f;
        const I4 index = __builtin_convertvector(linear < limit ? linear : limit, I4) * kNoiseSteps;
        out[3 * x + 0] = lut[index[0] + static_cast<int>(h & 0xFFU)];
        out[3 * x + 1] = lut[index[1] + static_cast<int>((h >> 8U) & 0xFFU)];
        out[3 * x + 2] = lut[index[2] + static_cast<int>((h >> 16U) & 0xFFU)];
      }
    } else {
      for (int x = 0; x < width; ++x) {
        for (int c = 0; c < 3; ++c) {
          out[3 * x + c] = clean_lut_[static_cast<std::size_t>(static_cast<int>(std::min(acc[4 * x + c] * scale * kMax + 0.5f, kMax)))];
        }
      }
    }
  }
}

void Renderer::render_rgbd_band(const std::vector<View>& views, int band, std::uint64_t frame, RgbdImages& out,
                                BandWorkspace& ws) const {
  const CameraRays& rays = rgb_rays_;
  const int y0 = band * CameraRays::kTile;
  const int rows = std::min(CameraRays::kTile, rays.height - y0);
  const bool with_ir = scene_.has_ir && !out.ir.empty();
  const std::size_t centre = views.size() / 2;
  for (std::size_t k = 0; k < views.size(); ++k) {
    cast_band(rays, views[k], y0, rows, ws);
    if (with_ir || k == centre) projector_shadow(rays, y0, rows, ws);
    if (k == centre) write_depth(rays, views[k], y0, rows, frame, out.depth, ws);
    shade_band(rays, views[k], y0, rows, k == 0, with_ir, ws);
  }
  const float inv_samples = 1.0f / static_cast<float>(views.size());
  write_color(rays.width, y0, rows, exposure_ * inv_samples, stream_key(settings_.seed, kStreamRgb, frame), out.rgb, ws);
  if (with_ir) {
    const std::uint64_t key = stream_key(settings_.seed, kStreamIr, frame);
    const float gain = static_cast<float>(scene_.photometry.ir_gain) * inv_samples;
    const auto sigma = static_cast<float>(scene_.photometry.ir_read_noise_levels);
    for (int y = 0; y < rows; ++y) {
      auto* dst = out.ir.ptr<std::uint8_t>(y0 + y);
      const std::size_t ws_row = static_cast<std::size_t>(y) * static_cast<std::size_t>(rays.width);
      const std::size_t row = static_cast<std::size_t>(y + y0) * static_cast<std::size_t>(rays.width);
      for (int x = 0; x < rays.width; ++x) {
        float level = gain * ws.acc[4 * (ws_row + static_cast<std::size_t>(x)) + 3];
        if (settings_.sensor_noise) level += sigma * gaussian_[element_hash(key, row + static_cast<std::size_t>(x)) & 0xFFFU];
        dst[x] = static_cast<std::uint8_t>(std::min(std::max(level + 0.5f, 0.0f), 255.0f));
      }
    }
  }
}

void Renderer::render_fisheye_band(const std::vector<View>& views, int band, std::uint64_t frame, cv::Mat& out,
                                   BandWorkspace& ws) const {
  const CameraRays& rays = fisheye_rays_.at(0);
  const int y0 = band * CameraRays::kTile;
  const int rows = std::min(CameraRays::kTile, rays.height - y0);
  for (std::size_t k = 0; k < views.size(); ++k) {
    cast_band(rays, views[k], y0, rows, ws);
    shade_band(rays, views[k], y0, rows, k == 0, false, ws);
  }
  write_color(rays.width, y0, rows, fisheye_exposure_ / static_cast<float>(views.size()),
              stream_key(settings_.seed, kStreamFisheye, frame), out, ws);
}

}  // namespace rankslam::sim::detail
