#include "rankslam/dense/aligner.hpp"

#include "rankslam/robust/msse.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <optional>
#include <span>
#include <stdexcept>
#include <string>

namespace rankslam::dense {

namespace {

constexpr float kNaN = std::numeric_limits<float>::quiet_NaN();
// Squared residuals sorted for each MSSE scale: an even subsample keeps the sort cheap.
constexpr std::size_t kScaleSample = 1024;
// Neighbouring depths further apart than this (relative) straddle an occluding edge.
constexpr float kDepthEdge = 0.05F;

// Bilinear value of a CV_32F image at (x, y), inside [0, cols − 1) × [0, rows − 1).
float bilinear(const cv::Mat& image, float x, float y) {
  const int x0 = static_cast<int>(x);
  const int y0 = static_cast<int>(y);
  const float a = x - static_cast<float>(x0);
  const float b = y - static_cast<float>(y0);
  const float* r0 = image.ptr<float>(y0) + x0;
  const float* r1 = image.ptr<float>(y0 + 1) + x0;
  return (1.0F - b) * ((1.0F - a) * r0[0] + a * r0[1]) + b * ((1.0F - a) * r1[0] + a * r1[1]);
}

// Bilinear depth, or 0 where any of the four pixels has none or they straddle an edge.
float bilinear_depth(const cv::Mat& depth, float x, float y) {
  const int x0 = static_cast<int>(x);
  const int y0 = static_cast<int>(y);
  const float* r0 = depth.ptr<float>(y0) + x0;
  const float* r1 = depth.ptr<float>(y0 + 1) + x0;
  const float lo = std::min({r0[0], r0[1], r1[0], r1[1]});
  const float hi = std::max({r0[0], r0[1], r1[0], r1[1]});
  if (!(lo > 0.0F) || hi - lo > kDepthEdge * lo) return 0.0F;
  const float a = x - static_cast<float>(x0);
  const float b = y - static_cast<float>(y0);
  return (1.0F - b) * ((1.0F - a) * r0[0] + a * r0[1]) + b * ((1.0F - a) * r1[0] + a * r1[1]);
}

void gradients(const cv::Mat& image, cv::Mat& gx, cv::Mat& gy) {
  const int w = image.cols;
  const int h = image.rows;
  for (int y = 0; y < h; ++y) {
    const float* row = image.ptr<float>(y);
    const float* up = image.ptr<float>(std::max(y - 1, 0));
    const float* dn = image.ptr<float>(std::min(y + 1, h - 1));
    float* dx = gx.ptr<float>(y);
    float* dy = gy.ptr<float>(y);
    dx[0] = 0.0F;
    dx[w - 1] = 0.0F;
    for (int x = 1; x < w - 1; ++x) dx[x] = 0.5F * (row[x + 1] - row[x - 1]);
    const bool inner = y > 0 && y < h - 1;
    for (int x = 0; x < w; ++x) dy[x] = inner ? 0.5F * (dn[x] - up[x]) : 0.0F;
  }
}

void depth_gradients(const cv::Mat& depth, cv::Mat& zx, cv::Mat& zy) {
  const int w = depth.cols;
  const int h = depth.rows;
  const auto difference = [](float a, float b) {
    if (!(a > 0.0F) || !(b > 0.0F) || std::abs(a - b) > 2.0F * kDepthEdge * std::min(a, b)) return kNaN;
    return 0.5F * (a - b);
  };
  for (int y = 0; y < h; ++y) {
    const float* row = depth.ptr<float>(y);
    const float* up = depth.ptr<float>(std::max(y - 1, 0));
    const float* dn = depth.ptr<float>(std::min(y + 1, h - 1));
    float* dx = zx.ptr<float>(y);
    float* dy = zy.ptr<float>(y);
    dx[0] = kNaN;
    dx[w - 1] = kNaN;
    for (int x = 1; x < w - 1; ++x) dx[x] = difference(row[x + 1], row[x - 1]);
    const bool inner = y > 0 && y < h - 1;
    for (int x = 0; x < w; ++x) dy[x] = inner ? difference(dn[x], up[x]) : kNaN;
  }
}

}  // namespace

std::string_view DenseOptions::validate() const {
  if (levels < 1 || levels > DenseFrame::kMaxLevels) return "levels";
  if (iterations < 1 || iterations > 50) return "iterations";
  if (!(min_gradient >= 0.0 && min_gradient <= 255.0)) return "min_gradient";
  if (max_points < 100 || max_points > 100000) return "max_points";
  if (min_inliers < 10 || min_inliers > 100000) return "min_inliers";
  if (!(min_depth_m >= 0.0 && min_depth_m < 10.0)) return "min_depth_m";
  if (!(max_depth_m > min_depth_m && max_depth_m <= 20.0)) return "max_depth_m";
  if (!(depth_noise_per_m > 0.0 && depth_noise_per_m <= 0.1)) return "depth_noise_per_m";
  if (!(depth_weight >= 0.0 && depth_weight <= 10.0)) return "depth_weight";
  if (!(max_change_m > 0.0 && max_change_m <= 1.0)) return "max_change_m";
  if (!(max_change_deg > 0.0 && max_change_deg <= 30.0)) return "max_change_deg";
  if (!(min_inlier_fraction > 0.0 && min_inlier_fraction < 1.0)) return "min_inlier_fraction";
  if (!(transition_factor > 0.0 && transition_factor <= 100.0)) return "transition_factor";
  return {};
}

void DenseFrame::reserve(int width, int height, int levels) {
  levels_ = std::clamp(levels, 1, kMaxLevels);
  width_ = width;
  height_ = height;
  int w = width;
  int h = height;
  for (int l = 0; l < levels_; ++l) {
    Level& level = level_[static_cast<std::size_t>(l)];
    for (cv::Mat* m : {&level.grey, &level.gx, &level.gy, &level.depth, &level.zx, &level.zy}) m->create(h, w, CV_32F);
    w /= 2;
    h /= 2;
  }
  valid_ = false;
}

bool DenseFrame::prepare(const cv::Mat& grey, const cv::Mat& depth_raw, float metres_per_unit, float min_depth_m,
                         float max_depth_m, int source) {
  valid_ = false;
  if (levels_ == 0 || grey.type() != CV_8UC1 || depth_raw.type() != CV_16UC1 || grey.cols != width_ ||
      grey.rows != height_ || depth_raw.cols != width_ || depth_raw.rows != height_) {
    return false;
  }
  Level& base = level_[0];
  for (int y = 0; y < height_; ++y) {
    const std::uint8_t* g = grey.ptr<std::uint8_t>(y);
    const std::uint16_t* d = depth_raw.ptr<std::uint16_t>(y);
    float* gi = base.grey.ptr<float>(y);
    float* di = base.depth.ptr<float>(y);
    for (int x = 0; x < width_; ++x) {
      gi[x] = static_cast<float>(g[x]);
      const float z = static_cast<float>(d[x]) * metres_per_unit;
      di[x] = z >= min_depth_m && z <= max_depth_m ? z : 0.0F;
    }
  }
  for (int l = 1; l < levels_; ++l) {
    const Level& fine = level_[static_cast<std::size_t>(l - 1)];
    Level& coarse = level_[static_cast<std::size_t>(l)];
    for (int y = 0; y < coarse.grey.rows; ++y) {
      const float* g0 = fine.grey.ptr<float>(2 * y);
      const float* g1 = fine.grey.ptr<float>(2 * y + 1);
      const float* d0 = fine.depth.ptr<float>(2 * y);
      const float* d1 = fine.depth.ptr<float>(2 * y + 1);
      float* g = coarse.grey.ptr<float>(y);
      float* d = coarse.depth.ptr<float>(y);
      for (int x = 0; x < coarse.grey.cols; ++x) {
        g[x] = 0.25F * (g0[2 * x] + g0[2 * x + 1] + g1[2 * x] + g1[2 * x + 1]);
        // Depth: the mean of the block's valid pixels that lie on one surface (no edge inside).
        float sum = 0.0F;
        int n = 0;
        float lo = std::numeric_limits<float>::max();
        float hi = 0.0F;
        for (const float z : {d0[2 * x], d0[2 * x + 1], d1[2 * x], d1[2 * x + 1]}) {
          if (!(z > 0.0F)) continue;
          sum += z;
          ++n;
          lo = std::min(lo, z);
          hi = std::max(hi, z);
        }
        d[x] = n > 0 && hi - lo <= kDepthEdge * lo ? sum / static_cast<float>(n) : 0.0F;
      }
    }
  }
  for (int l = 0; l < levels_; ++l) {
    Level& level = level_[static_cast<std::size_t>(l)];
    gradients(level.grey, level.gx, level.gy);
    depth_gradients(level.depth, level.zx, level.zy);
  }
  source_ = source;
  valid_ = true;
  return true;
}

DenseAligner::DenseAligner(const camera::DepthCameraModel& camera, const DenseOptions& options)
    : camera_(camera), lens_(camera.calibration()), options_(options) {
  if (const auto field = options_.validate(); !field.empty()) {
    throw std::invalid_argument("dense options: " + std::string(field) + " out of range");
  }
  points_.resize(static_cast<std::size_t>(options_.max_points));
  candidates_.resize(static_cast<std::size_t>(camera.width()) * static_cast<std::size_t>(camera.height()));
  residuals_.resize(static_cast<std::size_t>(options_.max_points));
  sample_.resize(kScaleSample);
  signed_sample_.resize(kScaleSample);
}

void DenseAligner::reserve(DenseFrame& frame) const {
  frame.reserve(camera_.width(), camera_.height(), options_.levels);
}

int DenseAligner::select_points(const DenseFrame& reference, int level) {
  const DenseFrame::Level& L = reference.level(level);
  const int scale = 1 << level;
  const float min_g2 = static_cast<float>(options_.min_gradient * options_.min_gradient);
  // One pass collects the usable pixels (depth, and a gradient or a place on the 4×4 grid) ...
  int candidates = 0;
  for (int y = 1; y < L.depth.rows - 1; ++y) {
    const float* z = L.depth.ptr<float>(y);
    const float* gx = L.gx.ptr<float>(y);
    const float* gy = L.gy.ptr<float>(y);
    const bool grid_row = y % 4 == 0;
    for (int x = 1; x < L.depth.cols - 1; ++x) {
      if (!(z[x] > 0.0F)) continue;
      const bool photometric = gx[x] * gx[x] + gy[x] * gy[x] >= min_g2;
      if (!photometric && !(grid_row && x % 4 == 0)) continue;
      candidates_[static_cast<std::size_t>(candidates++)] = (y * L.depth.cols + x) * 2 + (photometric ? 1 : 0);
    }
  }
  // ... and an even subsample of them becomes the points; coarser levels seed the finer ones and
  // take fewer (a quarter of the pixels per level, half the points).
  const int max_points = std::max(100, static_cast<int>(points_.size()) >> level);
  const double step = candidates > max_points ? static_cast<double>(candidates) / max_points : 1.0;
  int n = 0;
  for (double next = 0.0; n < max_points && static_cast<int>(next) < candidates; next += step) {
    const int code = candidates_[static_cast<std::size_t>(next)];
    const int pixel = code / 2;
    const int x = pixel % L.depth.cols;
    const int y = pixel / L.depth.cols;
    const float z = L.depth.ptr<float>(y)[x];
    // The pixel's centre at full resolution, and its ray through the lens.
    const Eigen::Vector2f ray =
        level == 0 ? camera_.ray(x, y)
                   : camera_.ray(std::min(static_cast<float>(x * scale) + 0.5F * static_cast<float>(scale - 1),
                                          static_cast<float>(camera_.width() - 1)),
                                 std::min(static_cast<float>(y * scale) + 0.5F * static_cast<float>(scale - 1),
                                          static_cast<float>(camera_.height() - 1)));
    Point& point = points_[static_cast<std::size_t>(n++)];
    point.p = Eigen::Vector3f(ray.x() * z, ray.y() * z, z);
    point.intensity = L.grey.ptr<float>(y)[x];
    point.photometric = (code & 1) != 0;
  }
  return n;
}

void DenseAligner::evaluate(const DenseFrame& current, int level, const Eigen::Isometry3f& T, bool jacobians) {
  const DenseFrame::Level& L = current.level(level);
  const float scale = 1.0F / static_cast<float>(1 << level);
  const hal::CameraCalibration& c = camera_.calibration();
  const float fx = static_cast<float>(c.fx) * scale;
  const float fy = static_cast<float>(c.fy) * scale;
  const float a = static_cast<float>(options_.depth_noise_per_m);
  const bool use_depth = options_.depth_weight > 0.0;
  const float x_max = static_cast<float>(L.grey.cols - 2);
  const float y_max = static_cast<float>(L.grey.rows - 2);
  for (int i = 0; i < count_; ++i) {
    const Point& point = points_[static_cast<std::size_t>(i)];
    Residual& r = residuals_[static_cast<std::size_t>(i)];
    r.r_photo = kNaN;
    r.r_depth = kNaN;
    const Eigen::Vector3f p = T * point.p;
    if (!(p.z() > static_cast<float>(options_.min_depth_m))) continue;
    const std::optional<Eigen::Vector2d> uv = lens_.project(p.cast<double>());
    if (!uv) continue;
    const float x = (static_cast<float>(uv->x()) + 0.5F) * scale - 0.5F;
    const float y = (static_cast<float>(uv->y()) + 0.5F) * scale - 0.5F;
    if (!(x >= 1.0F && x < x_max && y >= 1.0F && y < y_max)) continue;
    const float inv_z = 1.0F / p.z();
    // ∂(pixel)/∂p of the pinhole (the lens distortion's own derivative is left out: the
    // residuals are exact, only the Gauss–Newton step is approximate).
    const float px = fx * inv_z;
    const float py = fy * inv_z;
    const float pzx = -fx * p.x() * inv_z * inv_z;
    const float pzy = -fy * p.y() * inv_z * inv_z;
    // ∂r/∂ξ for ξ = (ω, v) on the left: ∂r/∂p · [−[p]× | I] = (p × a, a) with a = ∂r/∂p.
    const auto jacobian = [&](const Eigen::Vector3f& d, Eigen::Matrix<float, 6, 1>& j) {
      j.head<3>() = p.cross(d);
      j.tail<3>() = d;
    };
    if (point.photometric) {
      r.r_photo = bilinear(L.grey, x, y) - point.intensity;
      if (jacobians) {
        const float gx = bilinear(L.gx, x, y);
        const float gy = bilinear(L.gy, x, y);
        jacobian(Eigen::Vector3f(gx * px, gy * py, gx * pzx + gy * pzy), r.j_photo);
      }
    }
    if (use_depth) {
      const float z = bilinear_depth(L.depth, x, y);
      const float zx = z > 0.0F ? bilinear(L.zx, x, y) : kNaN;
      const float zy = z > 0.0F ? bilinear(L.zy, x, y) : kNaN;
      // Only where the depth's slope is known: the same points in every evaluation.
      if (std::isfinite(zx) && std::isfinite(zy)) {
        const float inv_sigma = 1.0F / (a * p.z() * p.z());
        r.r_depth = (z - p.z()) * inv_sigma;
        if (jacobians) jacobian(Eigen::Vector3f(zx * px, zy * py, zx * pzx + zy * pzy - 1.0F) * inv_sigma, r.j_depth);
      }
    }
  }
}

DenseAligner::Scales DenseAligner::estimate_scales() {
  Scales scales;
  const std::size_t stride = std::max<std::size_t>(1, (static_cast<std::size_t>(count_) + kScaleSample - 1) / kScaleSample);
  const auto msse_sigma = [&](std::size_t n, double fallback) {
    if (n < 20) return fallback;
    std::sort(sample_.begin(), sample_.begin() + static_cast<std::ptrdiff_t>(n));
    const int k0 = robust::msse_first_order(options_.min_inlier_fraction, static_cast<int>(n), 0, 1);
    double sigma_sq = 0.0;
    (void)robust::msse_transition(std::span<const float>(sample_.data(), n), k0, 0, options_.transition_factor,
                                  &sigma_sq);
    return std::sqrt(std::max(sigma_sq, 1e-6));
  };
  // Photometric: the median residual is the brightness change between the frames.
  std::size_t n = 0;
  for (std::size_t i = 0; i < static_cast<std::size_t>(count_) && n < kScaleSample; i += stride) {
    const float r = residuals_[i].r_photo;
    if (std::isfinite(r)) signed_sample_[n++] = r;
  }
  if (n > 0) {
    const auto middle = signed_sample_.begin() + static_cast<std::ptrdiff_t>(n / 2);
    std::nth_element(signed_sample_.begin(), middle, signed_sample_.begin() + static_cast<std::ptrdiff_t>(n));
    scales.photo_bias = *middle;
    for (std::size_t i = 0; i < n; ++i) {
      const float d = signed_sample_[i] - static_cast<float>(scales.photo_bias);
      sample_[i] = d * d;
    }
  }
  scales.photo_sigma = std::max(msse_sigma(n, 255.0), 0.5);
  n = 0;
  for (std::size_t i = 0; i < static_cast<std::size_t>(count_) && n < kScaleSample; i += stride) {
    const float r = residuals_[i].r_depth;
    if (std::isfinite(r)) sample_[n++] = r * r;
  }
  scales.depth_sigma = std::max(msse_sigma(n, 1e3), 0.1);
  return scales;
}

double DenseAligner::cost(const Scales& scales, int* photo_inliers, int* depth_inliers) const {
  const double t2 = options_.transition_factor * options_.transition_factor;
  const double inv_photo = 1.0 / (scales.photo_sigma * scales.photo_sigma);
  const double inv_depth = options_.depth_weight / (scales.depth_sigma * scales.depth_sigma);
  double total = 0.0;
  int np = 0;
  int nd = 0;
  for (int i = 0; i < count_; ++i) {
    const Residual& r = residuals_[static_cast<std::size_t>(i)];
    // A point that falls outside or loses its depth costs as an outlier.
    const double rp = std::isfinite(r.r_photo) ? (static_cast<double>(r.r_photo) - scales.photo_bias) : 1e9;
    const double ep = std::min(rp * rp * inv_photo, t2);
    if (points_[static_cast<std::size_t>(i)].photometric) {
      total += ep;
      np += ep < t2 ? 1 : 0;
    }
    if (options_.depth_weight > 0.0) {
      const double rd = std::isfinite(r.r_depth) ? static_cast<double>(r.r_depth) : 1e9;
      const double ed = std::min(rd * rd * inv_depth, t2 * options_.depth_weight);
      total += ed;
      nd += ed < t2 * options_.depth_weight ? 1 : 0;
    }
  }
  if (photo_inliers != nullptr) *photo_inliers = np;
  if (depth_inliers != nullptr) *depth_inliers = nd;
  return total;
}

void DenseAligner::accumulate(const Scales& scales, Eigen::Matrix<double, 6, 6>& H, Eigen::Matrix<double, 6, 1>& g) const {
  const double t2 = options_.transition_factor * options_.transition_factor;
  H.setZero();
  g.setZero();
  const double inv_photo = 1.0 / (scales.photo_sigma * scales.photo_sigma);
  const double inv_depth = options_.depth_weight / (scales.depth_sigma * scales.depth_sigma);
  // Sums in float per block of points, then in double: float alone loses the small terms.
  Eigen::Matrix<float, 6, 6> Hf = Eigen::Matrix<float, 6, 6>::Zero();
  Eigen::Matrix<float, 6, 1> gf = Eigen::Matrix<float, 6, 1>::Zero();
  for (int i = 0; i < count_; ++i) {
    const Residual& r = residuals_[static_cast<std::size_t>(i)];
    if (std::isfinite(r.r_photo)) {
      const double e = static_cast<double>(r.r_photo) - scales.photo_bias;
      if (e * e * inv_photo < t2) {
        const float w = static_cast<float>(inv_photo);
        Hf.noalias() += w * r.j_photo * r.j_photo.transpose();
        gf.noalias() += (w * static_cast<float>(e)) * r.j_photo;
      }
    }
    if (std::isfinite(r.r_depth)) {
      const double e = static_cast<double>(r.r_depth);
      if (e * e * inv_depth < t2 * options_.depth_weight) {
        const float w = static_cast<float>(inv_depth);
        Hf.noalias() += w * r.j_depth * r.j_depth.transpose();
        gf.noalias() += (w * static_cast<float>(e)) * r.j_depth;
      }
    }
    if ((i & 255) == 255) {
      H += Hf.cast<double>();
      g += gf.cast<double>();
      Hf.setZero();
      gf.setZero();
    }
  }
  H += Hf.cast<double>();
  g += gf.cast<double>();
}

DenseResult DenseAligner::align(const DenseFrame& reference, const DenseFrame& current, Eigen::Isometry3d& T_cur_ref) {
  DenseResult result;
  if (!reference.valid() || !current.valid()) {
    result.reason = "no pyramid";
    return result;
  }
  if (reference.source() != current.source()) {
    result.reason = "images of different kinds";
    return result;
  }
  const Eigen::Isometry3d start = T_cur_ref;
  Eigen::Isometry3f T = start.cast<float>();
  Scales scales;
  for (int level = std::min(options_.levels, reference.levels()) - 1; level >= 0; --level) {
    count_ = select_points(reference, level);
    if (count_ < 6) continue;
    bool evaluated = false;  // the residuals hold T's (the last accepted step's evaluation)
    for (int iteration = 0; iteration < options_.iterations; ++iteration) {
      if (!evaluated) evaluate(current, level, T, true);
      scales = estimate_scales();
      const double before = cost(scales, nullptr, nullptr);
      Eigen::Matrix<double, 6, 6> H;
      Eigen::Matrix<double, 6, 1> g;
      accumulate(scales, H, g);
      const Eigen::LDLT<Eigen::Matrix<double, 6, 6>> ldlt(H);
      if (ldlt.info() != Eigen::Success) break;
      const Eigen::Matrix<double, 6, 1> delta = -ldlt.solve(g);
      if (!delta.allFinite()) break;
      Eigen::Isometry3d step = Eigen::Isometry3d::Identity();
      const double angle = delta.head<3>().norm();
      if (angle > 0.0) step.linear() = Eigen::AngleAxisd(angle, delta.head<3>() / angle).toRotationMatrix();
      step.translation() = delta.tail<3>();
      const Eigen::Isometry3f candidate = (step * T.cast<double>()).cast<float>();
      evaluate(current, level, candidate, true);
      if (cost(scales, nullptr, nullptr) >= before) break;
      T = candidate;
      evaluated = true;
      ++result.iterations;
      if (angle < 1e-5 && delta.tail<3>().norm() < 1e-5) break;
    }
  }
  if (count_ < 6) {
    result.reason = "too few pixels with depth";
    return result;
  }
  // The full-resolution verdict: the refined motion against the start under one set of scales.
  evaluate(current, 0, T, false);
  scales = estimate_scales();
  result.points = count_;
  result.final_cost = cost(scales, &result.photometric_inliers, &result.depth_inliers);

  result.photometric_sigma = scales.photo_sigma;
  result.depth_sigma = scales.depth_sigma;
  evaluate(current, 0, start.cast<float>(), false);
  result.initial_cost = cost(scales, nullptr, nullptr);

  const Eigen::Isometry3d refined = T.cast<double>();
  const Eigen::Isometry3d change = refined * start.inverse();
  if (result.photometric_inliers < options_.min_inliers) {
    result.reason = "too few photometric inliers";
  } else if (!(result.final_cost < result.initial_cost)) {
    result.reason = "no better than the start";

  } else if (change.translation().norm() > options_.max_change_m ||
             Eigen::AngleAxisd(change.linear()).angle() * 180.0 / M_PI > options_.max_change_deg) {
    result.reason = "too far from the start";
  } else {
    result.ok = true;
    Eigen::Isometry3d out = Eigen::Isometry3d::Identity();
    out.linear() = Eigen::Quaterniond(refined.linear()).normalized().toRotationMatrix();
    out.translation() = refined.translation();
    T_cur_ref = out;
  }
  return result;
}

}  // namespace rankslam::dense
