#include "rankslam/robust/rigid.hpp"

#include "rankslam/parallel/cpu_features.hpp"

#include <algorithm>
#include <array>
#include <cmath>

#include <Eigen/Eigenvalues>
#include <Eigen/SVD>

#include "vector_kernels.hpp"

namespace rankslam::robust {
namespace {

/// Weighted first and second moments of a correspondence set (two passes for accuracy).
struct Moments {
  double weight_sum = 0.0;
  Eigen::Vector3d mean_src = Eigen::Vector3d::Zero();
  Eigen::Vector3d mean_dst = Eigen::Vector3d::Zero();
  Eigen::Matrix3d cross = Eigen::Matrix3d::Zero();  // Σ w (d − d̄)(s − s̄)ᵀ
  Eigen::Matrix3d cov_src = Eigen::Matrix3d::Zero();
  Eigen::Matrix3d cov_dst = Eigen::Matrix3d::Zero();
};

/// get(k, s, d, w) yields the k-th correspondence, k < count.
template <class Get>
Moments accumulate(int count, const Get& get, bool second_moments_of_points) {
  Moments m;
  Eigen::Vector3d s;
  Eigen::Vector3d d;
  double w = 0.0;
  for (int k = 0; k < count; ++k) {
    get(k, s, d, w);
    m.weight_sum += w;
    m.mean_src += w * s;
    m.mean_dst += w * d;
  }
  if (!(m.weight_sum > 0.0)) return m;
  m.mean_src /= m.weight_sum;
  m.mean_dst /= m.weight_sum;
  for (int k = 0; k < count; ++k) {
    get(k, s, d, w);
    const Eigen::Vector3d sc = s - m.mean_src;
    const Eigen::Vector3d dc = d - m.mean_dst;
    m.cross.noalias() += (w * dc) * sc.transpose();
    if (second_moments_of_points) {
      m.cov_src.noalias() += (w * sc) * sc.transpose();
      m.cov_dst.noalias() += (w * dc) * dc.transpose();
    }
  }
  return m;
}

RigidFitStatus check_spread(const Eigen::Matrix3d& cov, double weight_sum,
                            const RigidSolverConfig& config) {
  const double mean_sq_spread = cov.trace() / weight_sum;
  if (!(mean_sq_spread >= config.min_separation_m * config.min_separation_m) ||
      mean_sq_spread == 0.0) {
    return RigidFitStatus::kCoincident;
  }
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eigen;
  eigen.computeDirect(cov, Eigen::EigenvaluesOnly);
  const Eigen::Vector3d& lambda = eigen.eigenvalues();  // ascending
  const double thickness_sq = std::max(lambda(1), 0.0) / lambda(2);
  if (!(thickness_sq >= config.min_thickness_ratio * config.min_thickness_ratio) ||
      thickness_sq == 0.0) {
    return RigidFitStatus::kCollinear;
  }
  return RigidFitStatus::kOk;
}

/// Umeyama (1991) eq. 39–41 without scale: cross = U S Vᵀ, R = U diag(1, 1, ±1) Vᵀ.
RigidFitStatus solve(const Moments& m, Eigen::Isometry3d& T_t_s) {
  const Eigen::JacobiSVD<Eigen::Matrix3d> svd(m.cross, Eigen::ComputeFullU | Eigen::ComputeFullV);
  const Eigen::Matrix3d& u = svd.matrixU();
  const Eigen::Matrix3d& v = svd.matrixV();
  Eigen::Matrix3d r = u * v.transpose();
  if (r.determinant() < 0.0) {  // reflection: flip the axis of the smallest singular value
    Eigen::Matrix3d u_flipped = u;
    u_flipped.col(2) = -u_flipped.col(2);
    r = u_flipped * v.transpose();
  }
  const Eigen::Vector3d t = m.mean_dst - r * m.mean_src;
  if (!r.allFinite() || !t.allFinite()) {
    T_t_s.setIdentity();
    return RigidFitStatus::kNonFinite;
  }
  T_t_s.linear() = r;
  T_t_s.translation() = t;
  T_t_s.makeAffine();
  return RigidFitStatus::kOk;
}

/// The least-squares rigid motion of exactly three correspondences, in closed form (the SVD of
/// solve() costs about half of a minimal-sample MSSE). Three centred points span a plane, so
/// the cross-covariance has rank 2 and its null vectors are the two triangles' normals: the
/// Umeyama rotation maps the source plane onto the target plane, and within it is the best 2D
/// rotation — or, where a mirrored in-plane map fits better (a wrong match), that map with the
/// normal turned over, which is what diag(1, 1, ±1) picks. Same motion as solve() to rounding
/// (test/unit/robust, rigid_test). False for a degenerate triangle.
bool solve_triangle(const std::array<Eigen::Vector3d, 3>& src, const std::array<Eigen::Vector3d, 3>& dst,
                    Eigen::Isometry3d& T_t_s) {
  const Eigen::Vector3d mean_src = (src[0] + src[1] + src[2]) / 3.0;
  const Eigen::Vector3d mean_dst = (dst[0] + dst[1] + dst[2]) / 3.0;
  const Eigen::Vector3d normal_src = (src[1] - src[0]).cross(src[2] - src[0]);
  const Eigen::Vector3d normal_dst = (dst[1] - dst[0]).cross(dst[2] - dst[0]);
  const double area_src = normal_src.norm();
  const double area_dst = normal_dst.norm();
  const double side_src = (src[1] - src[0]).norm();
  const double side_dst = (dst[1] - dst[0]).norm();
  if (!(area_src > 0.0) || !(area_dst > 0.0) || !(side_src > 0.0) || !(side_dst > 0.0)) return false;
  // Orthonormal frames (in-plane axis, in-plane axis, normal) of both triangles.
  const Eigen::Vector3d n_s = normal_src / area_src;
  const Eigen::Vector3d n_t = normal_dst / area_dst;
  const Eigen::Vector3d e1_s = (src[1] - src[0]) / side_src;
  const Eigen::Vector3d e1_t = (dst[1] - dst[0]) / side_dst;
  const Eigen::Vector3d e2_s = n_s.cross(e1_s);
  const Eigen::Vector3d e2_t = n_t.cross(e1_t);
  // 2D Procrustes: a = Σ x·x' + y·y', b = Σ x·y' − y·x' for the rotation; c, d likewise for
  // the mirrored source (y → −y).
  double a = 0.0, b = 0.0, c = 0.0, d = 0.0;
  for (std::size_t k = 0; k < 3; ++k) {
    const Eigen::Vector3d sc = src[k] - mean_src;
    const Eigen::Vector3d dc = dst[k] - mean_dst;
    const double x = sc.dot(e1_s), y = sc.dot(e2_s);
    const double xt = dc.dot(e1_t), yt = dc.dot(e2_t);
    a += x * xt + y * yt;
    b += x * yt - y * xt;
    c += x * xt - y * yt;
    d += x * yt + y * xt;
  }
  const bool mirrored = c * c + d * d > a * a + b * b;
  const double angle = mirrored ? std::atan2(d, c) : std::atan2(b, a);
  const double cos_a = std::cos(angle);
  const double sin_a = std::sin(angle);
  Eigen::Matrix3d to;  // where the source frame's axes go
  to.col(0) = cos_a * e1_t + sin_a * e2_t;
  to.col(1) = -sin_a * e1_t + cos_a * e2_t;
  to.col(2) = n_t;
  Eigen::Matrix3d from;
  from.col(0) = e1_s;
  from.col(1) = mirrored ? Eigen::Vector3d(-e2_s) : e2_s;
  from.col(2) = mirrored ? Eigen::Vector3d(-n_s) : n_s;
  const Eigen::Matrix3d r = to * from.transpose();
  const Eigen::Vector3d t = mean_dst - r * mean_src;
  if (!r.allFinite() || !t.allFinite()) return false;
  T_t_s.linear() = r;
  T_t_s.translation() = t;
  T_t_s.makeAffine();
  return true;
}

template <class Get>
RigidFitStatus fit_checked(int count, const Get& get, const RigidSolverConfig& config,
                           Eigen::Isometry3d& T_t_s) {
  T_t_s.setIdentity();
  if (count < 3) return RigidFitStatus::kTooFewPoints;
  const Moments m = accumulate(count, get, true);
  if (!std::isfinite(m.weight_sum) || !m.cross.allFinite()) return RigidFitStatus::kNonFinite;
  if (!(m.weight_sum > 0.0)) return RigidFitStatus::kZeroWeight;
  if (const RigidFitStatus s = check_spread(m.cov_src, m.weight_sum, config);
      s != RigidFitStatus::kOk) {
    return s;
  }
  if (const RigidFitStatus s = check_spread(m.cov_dst, m.weight_sum, config);
      s != RigidFitStatus::kOk) {
    return s;
  }
  return solve(m, T_t_s);
}

}  // namespace

RigidFitStatus fit_rigid(const Eigen::Ref<const Eigen::Matrix3Xd>& src,
                         const Eigen::Ref<const Eigen::Matrix3Xd>& dst,
                         std::span<const double> weights, Eigen::Isometry3d& T_t_s,
                         const RigidSolverConfig& config) {
  T_t_s.setIdentity();
  const auto n = static_cast<int>(src.cols());
  if (dst.cols() != src.cols() || (!weights.empty() && static_cast<int>(weights.size()) != n)) {
    return RigidFitStatus::kTooFewPoints;
  }
  for (const double w : weights) {
    if (!std::isfinite(w) || w < 0.0) return RigidFitStatus::kNonFinite;
  }
  if (!src.allFinite() || !dst.allFinite()) return RigidFitStatus::kNonFinite;
  const auto get = [&](int k, Eigen::Vector3d& s, Eigen::Vector3d& d, double& w) {
    s = src.col(k);
    d = dst.col(k);
    w = weights.empty() ? 1.0 : weights[static_cast<std::size_t>(k)];
  };
  return fit_checked(n, get, config, T_t_s);
}

RigidFitStatus check_minimal_sample(const Eigen::Vector3d& a, const Eigen::Vector3d& b,
                                    const Eigen::Vector3d& c, const RigidSolverConfig& config) {
  const Eigen::Vector3d ab = b - a;
  const Eigen::Vector3d ac = c - a;
  const Eigen::Vector3d bc = c - b;
  const double ab2 = ab.squaredNorm();
  const double ac2 = ac.squaredNorm();
  const double bc2 = bc.squaredNorm();
  const double min_sep2 = config.min_separation_m * config.min_separation_m;
  const double shortest2 = std::min({ab2, ac2, bc2});
  if (!(shortest2 >= min_sep2) || shortest2 == 0.0) return RigidFitStatus::kCoincident;
  const double longest2 = std::max({ab2, ac2, bc2});
  const double twice_area = ab.cross(ac).norm();
  if (!(twice_area >= config.min_sample_aspect * longest2) || twice_area == 0.0) {
    return RigidFitStatus::kCollinear;
  }
  return RigidFitStatus::kOk;
}

RobustStatus correspondence_sigmas_m(const Eigen::Ref<const Eigen::Matrix3Xd>& src,
                                     const Eigen::Ref<const Eigen::Matrix3Xd>& dst,
                                     const DepthNoiseModel& noise, std::span<double> out) {
  const auto n = static_cast<std::size_t>(src.cols());
  if (static_cast<std::size_t>(dst.cols()) != n || out.size() != n) {
    return RobustStatus::kInvalidInput;
  }
  const double a = noise.axial_coefficient_per_m;
  const double lateral_sq = 4.0 * noise.lateral_sigma_m * noise.lateral_sigma_m;
  for (std::size_t i = 0; i < n; ++i) {
    const auto col = static_cast<Eigen::Index>(i);
    const double zs = src(2, col);
    const double zd = dst(2, col);
    if (!(zs > 0.0) || !(zd > 0.0) || !std::isfinite(zs) || !std::isfinite(zd)) {
      return RobustStatus::kInvalidInput;
    }
    const double ss = a * zs * zs;
    const double sd = a * zd * zd;
    out[i] = std::sqrt(ss * ss + sd * sd + lateral_sq);
    if (!(out[i] > 0.0)) return RobustStatus::kInvalidInput;
  }
  return RobustStatus::kOk;
}

RigidModel::RigidModel(int max_points, const RigidSolverConfig& config)
    : config_(config),
      src_(std::max(0, max_points), 3),
      dst_(std::max(0, max_points), 3),
      src_f_(std::max(0, max_points), 3),
      dst_f_(std::max(0, max_points), 3),
      weights_(std::max(0, max_points)) {}

RobustStatus RigidModel::set_correspondences(const Eigen::Ref<const Eigen::Matrix3Xd>& src,
                                             const Eigen::Ref<const Eigen::Matrix3Xd>& dst,
                                             std::span<const double> weights) {
  size_ = 0;
  has_weights_ = false;
  if (!config_.validate().empty()) return RobustStatus::kInvalidConfig;
  const auto n = static_cast<int>(src.cols());
  if (dst.cols() != src.cols() || (!weights.empty() && static_cast<int>(weights.size()) != n)) {
    return RobustStatus::kInvalidInput;
  }
  if (n > capacity()) return RobustStatus::kCapacityExceeded;
  if (!src.allFinite() || !dst.allFinite()) return RobustStatus::kInvalidInput;
  for (const double w : weights) {
    if (!std::isfinite(w) || w < 0.0) return RobustStatus::kInvalidInput;
  }
  src_.topRows(n) = src.transpose();
  dst_.topRows(n) = dst.transpose();
  src_f_.topRows(n) = src_.topRows(n).cast<float>();
  dst_f_.topRows(n) = dst_.topRows(n).cast<float>();
  if (!weights.empty()) {
    weights_.head(n) = Eigen::Map<const Eigen::VectorXd>(weights.data(), n);
    has_weights_ = true;
  }
  size_ = n;
  return RobustStatus::kOk;
}

bool RigidModel::sample_degenerate(std::span<const int> sample) const {
  if (sample.size() != 3) return true;
  const Eigen::Vector3d s0 = src(sample[0]);
  const Eigen::Vector3d s1 = src(sample[1]);
  const Eigen::Vector3d s2 = src(sample[2]);
  if (check_minimal_sample(s0, s1, s2, config_) != RigidFitStatus::kOk) return true;
  const Eigen::Vector3d d0 = dst(sample[0]);
  const Eigen::Vector3d d1 = dst(sample[1]);
  const Eigen::Vector3d d2 = dst(sample[2]);
  return check_minimal_sample(d0, d1, d2, config_) != RigidFitStatus::kOk;
}

bool RigidModel::fit_sample(std::span<const int> sample, Params& T_t_s) const {
  if (sample.size() < 3) return false;
  if (sample.size() == 3) {
    const std::array<Eigen::Vector3d, 3> s{src(sample[0]), src(sample[1]), src(sample[2])};
    const std::array<Eigen::Vector3d, 3> d{dst(sample[0]), dst(sample[1]), dst(sample[2])};
    if (solve_triangle(s, d, T_t_s)) return true;
  }
  // Unweighted: a minimal sample is fitted (almost) exactly, weights would change nothing.
  const auto get = [&](int k, Eigen::Vector3d& s, Eigen::Vector3d& d, double& w) {
    const int i = sample[static_cast<std::size_t>(k)];
    s = src(i);
    d = dst(i);
    w = 1.0;
  };
  const Moments m = accumulate(static_cast<int>(sample.size()), get, false);
  return solve(m, T_t_s) == RigidFitStatus::kOk;
}

bool RigidModel::fit_inliers(std::span<const int> inliers, const double* point_weights,
                             Params& T_t_s) const {
  const auto get = [&](int k, Eigen::Vector3d& s, Eigen::Vector3d& d, double& w) {
    const int i = inliers[static_cast<std::size_t>(k)];
    s = src(i);
    d = dst(i);
    w = (has_weights_ ? weights_(i) : 1.0) * (point_weights != nullptr ? point_weights[i] : 1.0);
  };
  Params fitted;
  if (fit_checked(static_cast<int>(inliers.size()), get, config_, fitted) != RigidFitStatus::kOk) {
    return false;
  }
  T_t_s = fitted;
  return true;
}

void RigidModel::squared_residuals(const Params& T_t_s, int begin, int count, double* out) const {
  const Eigen::Matrix3d& r = T_t_s.linear();
  const Eigen::Vector3d& t = T_t_s.translation();
  const auto sx = src_.col(0).segment(begin, count).array();
  const auto sy = src_.col(1).segment(begin, count).array();
  const auto sz = src_.col(2).segment(begin, count).array();
  const auto dx = dst_.col(0).segment(begin, count).array();
  const auto dy = dst_.col(1).segment(begin, count).array();
  const auto dz = dst_.col(2).segment(begin, count).array();
  Eigen::Map<Eigen::ArrayXd> o(out, count);
  o = (r(0, 0) * sx + r(0, 1) * sy + r(0, 2) * sz + (t.x()) - dx).square() +
      (r(1, 0) * sx + r(1, 1) * sy + r(1, 2) * sz + (t.y()) - dy).square() +
      (r(2, 0) * sx + r(2, 1) * sy + r(2, 2) * sz + (t.z()) - dz).square();
}

void RigidModel::selection_scores(const Params& T_t_s, int begin, int count, double* out) const {
  const Eigen::Matrix3f r = T_t_s.linear().cast<float>();
  const Eigen::Vector3f t = T_t_s.translation().cast<float>();
  // Float results go through a stack chunk: Eigen vectorises the float expression and the
  // float-to-double copy separately, but not the two fused.
  constexpr int kChunk = 128;
  alignas(16) std::array<float, kChunk> chunk{};
  for (int b = begin; b < begin + count; b += kChunk) {
    const int m = std::min(kChunk, begin + count - b);
    const auto sx = src_f_.col(0).segment(b, m).array();
    const auto sy = src_f_.col(1).segment(b, m).array();
    const auto sz = src_f_.col(2).segment(b, m).array();
    const auto dx = dst_f_.col(0).segment(b, m).array();
    const auto dy = dst_f_.col(1).segment(b, m).array();
    const auto dz = dst_f_.col(2).segment(b, m).array();
    Eigen::Map<Eigen::ArrayXf> f(chunk.data(), m);
    f = (r(0, 0) * sx + r(0, 1) * sy + r(0, 2) * sz + t.x() - dx).square() +
        (r(1, 0) * sx + r(1, 1) * sy + r(1, 2) * sz + t.y() - dy).square() +
        (r(2, 0) * sx + r(2, 1) * sy + r(2, 2) * sz + t.z() - dz).square();
    Eigen::Map<Eigen::ArrayXd>(out + (b - begin), m) = f.cast<double>();
  }
}

int RigidModel::scaled_selection_scores(const Params& T_t_s, int begin, int count,
                                        const double* inverse_variances, double bound,
                                        double* out) const {
  int done = 0;
  int below = 0;
  if (parallel::vector_kernels_enabled()) {
    const Eigen::Matrix3f r = T_t_s.linear().cast<float>();
    const Eigen::Vector3f t = T_t_s.translation().cast<float>();
    below = vector::rigid_scores(src_f_.col(0).data() + begin, src_f_.col(1).data() + begin,
                                 src_f_.col(2).data() + begin, dst_f_.col(0).data() + begin,
                                 dst_f_.col(1).data() + begin, dst_f_.col(2).data() + begin, r, t, count,
                                 inverse_variances, bound, out, done);
  }
  if (done < count) {
    const int rest = count - done;
    double* values = out + done;
    selection_scores(T_t_s, begin + done, rest, values);
    for (int i = 0; i < rest; ++i) {
      if (inverse_variances != nullptr) values[i] *= inverse_variances[done + i];
      below += values[i] < bound ? 1 : 0;
    }
  }
  return below;
}

bool RigidMotionGate::operator()(const Eigen::Isometry3d& T_t_s) const {
  return translation_difference_m(T_t_s_predicted, T_t_s) <= max_translation_m &&
         rotation_difference_rad(T_t_s_predicted, T_t_s) <= max_rotation_rad;
}

double rotation_difference_rad(const Eigen::Isometry3d& a, const Eigen::Isometry3d& b) {
  const Eigen::Matrix3d delta = a.linear().transpose() * b.linear();
  // atan2 of (|axis·sin|, cos) stays accurate near 0 where acos((tr − 1)/2) is not.
  const Eigen::Vector3d skew(delta(2, 1) - delta(1, 2), delta(0, 2) - delta(2, 0),
                             delta(1, 0) - delta(0, 1));
  return std::atan2(0.5 * skew.norm(), 0.5 * (delta.trace() - 1.0));
}

double translation_difference_m(const Eigen::Isometry3d& a, const Eigen::Isometry3d& b) {
  return (a.translation() - b.translation()).norm();
}

}  // namespace rankslam::robust
