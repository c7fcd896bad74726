#include "rankslam/robust/bearing.hpp"

#include "rankslam/robust/rigid.hpp"

#include <algorithm>
#include <cmath>

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>

namespace rankslam::robust {
namespace {

constexpr double kMinSeparationM = 1e-3;  // sample points closer than this are one point
constexpr double kMinBearingAngle = 1e-3;  // rad: bearings closer than this are one direction
constexpr int kRefitIterations = 10;

/// Real roots of c4 v⁴ + c3 v³ + c2 v² + c1 v + c0, polished by Newton's method.
int quartic_roots(const std::array<double, 5>& c, std::array<double, 4>& roots) {
  if (!(std::abs(c[4]) > 1e-14 * (std::abs(c[0]) + std::abs(c[1]) + std::abs(c[2]) + std::abs(c[3])))) return 0;
  Eigen::Matrix4d companion = Eigen::Matrix4d::Zero();
  companion(1, 0) = companion(2, 1) = companion(3, 2) = 1.0;
  for (int i = 0; i < 4; ++i) companion(i, 3) = -c[static_cast<std::size_t>(i)] / c[4];
  const Eigen::EigenSolver<Eigen::Matrix4d> solver(companion, false);
  if (solver.info() != Eigen::Success) return 0;
  const auto& values = solver.eigenvalues();
  int count = 0;
  for (int i = 0; i < 4; ++i) {
    const double re = values(i).real();
    if (std::abs(values(i).imag()) > 1e-6 * std::max(1.0, std::abs(re))) continue;
    double v = re;
    for (int it = 0; it < 3; ++it) {
      const double f = (((c[4] * v + c[3]) * v + c[2]) * v + c[1]) * v + c[0];
      const double df = ((4.0 * c[4] * v + 3.0 * c[3]) * v + 2.0 * c[2]) * v + c[1];
      if (df == 0.0) break;
      v -= f / df;
    }
    roots[static_cast<std::size_t>(count++)] = v;
  }
  return count;
}

Eigen::Matrix3d skew(const Eigen::Vector3d& v) {
  Eigen::Matrix3d m;
  m << 0.0, -v.z(), v.y(), v.z(), 0.0, -v.x(), -v.y(), v.x(), 0.0;
  return m;
}

/// Jacobian of the unit direction of p = T·x for T ← exp(ξ)·T, ξ = (translation, rotation);
/// false where p is the origin.
bool direction_jacobian(const Eigen::Vector3d& p, Eigen::Vector3d& u, Eigen::Matrix<double, 3, 6>& J) {
  const double norm = p.norm();
  if (!(norm > 0.0)) return false;
  u = p / norm;
  const Eigen::Matrix3d dn = (Eigen::Matrix3d::Identity() - u * u.transpose()) / norm;
  J.leftCols<3>() = dn;
  J.rightCols<3>() = -dn * skew(p);
  return true;
}

}  // namespace

int solve_p3p(const std::array<Eigen::Vector3d, 3>& points, const std::array<Eigen::Vector3d, 3>& bearings,
              std::array<Eigen::Isometry3d, 4>& poses) {
  // Side lengths opposite each point and the cosines of the angles between bearings.
  const double a2 = (points[1] - points[2]).squaredNorm();
  const double b2 = (points[0] - points[2]).squaredNorm();
  const double c2 = (points[0] - points[1]).squaredNorm();
  if (!(a2 > 0.0 && b2 > 0.0 && c2 > 0.0)) return 0;
  const double ca = bearings[1].dot(bearings[2]);
  const double cb = bearings[0].dot(bearings[2]);
  const double cg = bearings[0].dot(bearings[1]);
  // Grunert: depths s2 = u·s1, s3 = v·s1; v solves a quartic.
  const double p = (a2 - c2) / b2;
  const double q = (a2 + c2) / b2;
  const double r = (b2 - c2) / b2;
  const double s = (b2 - a2) / b2;
  std::array<double, 5> k{};
  k[4] = (p - 1.0) * (p - 1.0) - 4.0 * c2 / b2 * ca * ca;
  k[3] = 4.0 * (p * (1.0 - p) * cb - (1.0 - q) * ca * cg + 2.0 * c2 / b2 * ca * ca * cb);
  k[2] = 2.0 * (p * p - 1.0 + 2.0 * p * p * cb * cb + 2.0 * r * ca * ca - 4.0 * q * ca * cb * cg + 2.0 * s * cg * cg);
  k[1] = 4.0 * (-p * (1.0 + p) * cb + 2.0 * a2 / b2 * cg * cg * cb - (1.0 - q) * ca * cg);
  k[0] = (1.0 + p) * (1.0 + p) - 4.0 * a2 / b2 * cg * cg;
  std::array<double, 4> roots{};
  const int root_count = quartic_roots(k, roots);
  int count = 0;
  for (int i = 0; i < root_count; ++i) {
    const double v = roots[static_cast<std::size_t>(i)];
    const double denominator = 2.0 * (cg - v * ca);
    if (!(v > 0.0) || std::abs(denominator) < 1e-12) continue;
    const double u = ((p - 1.0) * v * v - 2.0 * p * cb * v + 1.0 + p) / denominator;
    if (!(u > 0.0)) continue;
    const double s1_sq = b2 / (1.0 + v * v - 2.0 * v * cb);
    if (!(s1_sq > 0.0)) continue;
    const double s1 = std::sqrt(s1_sq);
    Eigen::Matrix3d in_camera;
    in_camera.col(0) = s1 * bearings[0];
    in_camera.col(1) = u * s1 * bearings[1];
    in_camera.col(2) = v * s1 * bearings[2];
    Eigen::Matrix3d in_world;
    for (int j = 0; j < 3; ++j) in_world.col(j) = points[static_cast<std::size_t>(j)];
    Eigen::Isometry3d T_c_w;
    RigidSolverConfig exact;
    exact.min_separation_m = 0.0;
    exact.min_sample_aspect = 0.0;
    exact.min_thickness_ratio = 0.0;
    if (fit_rigid(in_world, in_camera, {}, T_c_w, exact) != RigidFitStatus::kOk) continue;
    poses[static_cast<std::size_t>(count++)] = T_c_w;
  }
  return count;
}

BearingModel::BearingModel(int max_points)
    : points_(3, std::max(0, max_points)), bearings_(3, std::max(0, max_points)), weights_(std::max(0, max_points)) {}

RobustStatus BearingModel::set_correspondences(const Eigen::Ref<const Eigen::Matrix3Xd>& points,
                                               const Eigen::Ref<const Eigen::Matrix3Xd>& bearings,
                                               std::span<const double> weights) {
  size_ = 0;
  const Eigen::Index n = points.cols();
  if (bearings.cols() != n || (!weights.empty() && static_cast<Eigen::Index>(weights.size()) != n)) {
    return RobustStatus::kInvalidInput;
  }
  if (n > capacity()) return RobustStatus::kCapacityExceeded;
  for (Eigen::Index i = 0; i < n; ++i) {
    const double norm = bearings.col(i).norm();
    if (!points.col(i).allFinite() || !(norm > 0.0) || !std::isfinite(norm)) return RobustStatus::kInvalidInput;
    if (!weights.empty() && !(weights[static_cast<std::size_t>(i)] >= 0.0)) return RobustStatus::kInvalidInput;
    points_.col(i) = points.col(i);
    bearings_.col(i) = bearings.col(i) / norm;
    weights_(i) = weights.empty() ? 1.0 : weights[static_cast<std::size_t>(i)];
  }
  has_weights_ = !weights.empty();
  size_ = static_cast<int>(n);
  return RobustStatus::kOk;
}

bool BearingModel::sample_degenerate(std::span<const int> sample) const {
  if (sample.size() != kSampleSize) return true;
  for (std::size_t i = 0; i < 3; ++i) {
    for (std::size_t j = i + 1; j < 3; ++j) {
      if ((point(sample[i]) - point(sample[j])).norm() < kMinSeparationM) return true;
      if (bearing(sample[i]).cross(bearing(sample[j])).norm() < kMinBearingAngle) return true;
    }
  }
  // Three points on a line leave the rotation about it free.
  const Eigen::Vector3d ab = point(sample[1]) - point(sample[0]);
  const Eigen::Vector3d ac = point(sample[2]) - point(sample[0]);
  return ab.cross(ac).norm() < 1e-2 * std::max(ab.squaredNorm(), ac.squaredNorm());
}

bool BearingModel::fit_sample(std::span<const int> sample, Params& T_c_w) const {
  if (sample.size() < 4) return false;
  std::array<Eigen::Isometry3d, 4> poses;
  const int count = solve_p3p({point(sample[0]), point(sample[1]), point(sample[2])},
                              {bearing(sample[0]), bearing(sample[1]), bearing(sample[2])}, poses);
  double best = 5.0;  // a chord is at most 2
  for (int i = 0; i < count; ++i) {
    const Eigen::Vector3d seen = poses[static_cast<std::size_t>(i)] * point(sample[3]);
    const double norm = seen.norm();
    if (!(norm > 0.0)) continue;
    const double chord = (seen / norm - bearing(sample[3])).squaredNorm();
    if (chord < best) {
      best = chord;
      T_c_w = poses[static_cast<std::size_t>(i)];
    }
  }
  return best < 5.0;
}

bool BearingModel::fit_inliers(std::span<const int> inliers, const double* point_weights, Params& T_c_w) const {
  if (inliers.size() < 3) return false;
  Eigen::Isometry3d T = T_c_w;
  for (int it = 0; it < kRefitIterations; ++it) {
    Eigen::Matrix<double, 6, 6> H = Eigen::Matrix<double, 6, 6>::Zero();
    Eigen::Matrix<double, 6, 1> g = Eigen::Matrix<double, 6, 1>::Zero();
    for (const int i : inliers) {
      const double w = (has_weights_ ? weights_(i) : 1.0) * (point_weights != nullptr ? point_weights[i] : 1.0);
      Eigen::Vector3d u;
      Eigen::Matrix<double, 3, 6> J;
      if (!(w > 0.0) || !direction_jacobian(T * point(i), u, J)) continue;
      H.noalias() += w * J.transpose() * J;
      g.noalias() += w * J.transpose() * (u - bearing(i));
    }
    const Eigen::LDLT<Eigen::Matrix<double, 6, 6>> ldlt(H);
    if (ldlt.info() != Eigen::Success) return false;
    const Eigen::Matrix<double, 6, 1> xi = ldlt.solve(-g);
    if (!xi.allFinite()) return false;
    Eigen::Isometry3d step = Eigen::Isometry3d::Identity();
    const double angle = xi.tail<3>().norm();
    if (angle > 0.0) step.linear() = Eigen::AngleAxisd(angle, xi.tail<3>() / angle).toRotationMatrix();
    step.translation() = xi.head<3>();
    T = step * T;
    if (xi.norm() < 1e-12) break;
  }
  T_c_w = T;
  return true;
}

Eigen::Matrix<double, 6, 6> BearingModel::information(const Params& T_c_w, std::span<const int> inliers) const {
  Eigen::Matrix<double, 6, 6> H = Eigen::Matrix<double, 6, 6>::Zero();
  for (const int i : inliers) {
    Eigen::Vector3d u;
    Eigen::Matrix<double, 3, 6> J;
    if (direction_jacobian(T_c_w * point(i), u, J)) H.noalias() += J.transpose() * J;
  }
  return H;
}

void BearingModel::squared_residuals(const Params& T_c_w, int begin, int count, double* out) const {
  for (int k = 0; k < count; ++k) {
    const Eigen::Vector3d p = T_c_w * point(begin + k);
    const double norm = p.norm();
    out[k] = norm > 0.0 ? (p / norm - bearing(begin + k)).squaredNorm() : 4.0;
  }
}

}  // namespace rankslam::robust
