#pragma once

// SE(3) helpers for every part, on fixed-size Eigen types only (no allocation). Tangent vectors
// are ξ = (ω, v): rotation vector first, then translation; the log is the SO(3)×R³ one (the
// translation is the motion's own, not V(ω)⁻¹·t), which agrees with SE(3)'s to first order.

#include <cmath>
#include <utility>

#include <Eigen/Cholesky>
#include <Eigen/Core>
#include <Eigen/Geometry>

#include "rankslam/core/units.hpp"

namespace rankslam::lie {

using Matrix6d = Eigen::Matrix<double, 6, 6>;
using Vector6d = Eigen::Matrix<double, 6, 1>;

// Rotations this far from orthonormal are rejected as not rigid; accumulated rounding in a
// SLAM loop's poses stays orders of magnitude below it.
inline constexpr double kRigidTolerance = 1e-6;

inline bool is_finite_rigid(const Eigen::Isometry3d& T) {
  if (!T.matrix().allFinite()) return false;
  const Eigen::Matrix3d R = T.linear();
  if ((R.transpose() * R - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff() > kRigidTolerance) {
    return false;
  }
  if (R.determinant() <= 0.0) return false;
  return T.matrix().row(3).isApprox(Eigen::RowVector4d(0.0, 0.0, 0.0, 1.0), kRigidTolerance);
}

inline Eigen::Matrix3d hat(const Eigen::Vector3d& v) {
  Eigen::Matrix3d m;
  m << 0.0, -v.z(), v.y(), v.z(), 0.0, -v.x(), -v.y(), v.x(), 0.0;
  return m;
}

// Ad(T) for ξ = (ω, v): [[R, 0], [t^·R, R]].
inline Matrix6d adjoint(const Eigen::Isometry3d& T) {
  const Eigen::Matrix3d R = T.linear();
  Matrix6d ad = Matrix6d::Zero();
  ad.topLeftCorner<3, 3>() = R;
  ad.bottomRightCorner<3, 3>() = R;
  ad.bottomLeftCorner<3, 3>() = hat(T.translation()) * R;
  return ad;
}

// √Ω as the upper-triangular Lᵀ of Ω = L·Lᵀ, so that ‖Lᵀ·ξ‖² = ξᵀ·Ω·ξ, and log det Ω. False
// when Ω is not positive definite.
inline bool sqrt_information(const Matrix6d& information, Matrix6d& sqrt_info, double& log_det) {
  const Eigen::LLT<Matrix6d> llt(information);
  if (llt.info() != Eigen::Success) return false;
  const Matrix6d L = llt.matrixL();
  const Vector6d diagonal = L.diagonal();
  if (!diagonal.allFinite() || (diagonal.array() <= 0.0).any()) return false;
  sqrt_info = L.transpose();
  log_det = 2.0 * diagonal.array().log().sum();
  return std::isfinite(log_det);
}

// Inverse of a symmetric positive definite 6×6 (information ↔ covariance).
inline Matrix6d covariance(const Matrix6d& information) {
  return Eigen::LLT<Matrix6d>(information).solve(Matrix6d::Identity());
}

// Inverse of a symmetric positive-definite 6×6 (an information or covariance matrix), symmetric
// to the last bit so that it can be inverted back and added up.
inline Matrix6d symmetric_inverse(const Matrix6d& matrix) {
  const Matrix6d inverse = covariance(matrix);
  return 0.5 * (inverse + inverse.transpose());
}

// Z⁻¹ and its covariance: (Z·Exp(δ))⁻¹ = Z⁻¹·Exp(−Ad(Z)·δ).
inline std::pair<Eigen::Isometry3d, Matrix6d> invert(const Eigen::Isometry3d& Z,
                                                      const Matrix6d& covariance_z) {
  const Matrix6d ad = adjoint(Z);
  return {Z.inverse(), ad * covariance_z * ad.transpose()};
}

// Projects the rotation back onto SO(3) after a product of poses: composing thousands of motions
// lets rounding pull a rotation away from orthonormal, and a scaled rotation makes poses grow.
inline Eigen::Isometry3d renormalised(const Eigen::Isometry3d& T) {
  Eigen::Isometry3d out = Eigen::Isometry3d::Identity();
  out.linear() = Eigen::Quaterniond(T.linear()).normalized().toRotationMatrix();
  out.translation() = T.translation();
  return out;
}

// ξ = (rotation vector of R_E, t_E): the SO(3)×R³ log the residual uses.
inline Vector6d log_so3_r3(const Eigen::Isometry3d& E) {
  const Eigen::AngleAxisd rotation(Eigen::Quaterniond(E.linear()).normalized());
  Vector6d xi;
  xi.head<3>() = rotation.angle() * rotation.axis();
  xi.tail<3>() = E.translation();
  return xi;
}

// The rotation angle of a motion in degrees, through the quaternion (atan2): accurate near zero,
// where acos((trace - 1) / 2) is not.
inline double rotation_deg(const Eigen::Isometry3d& T) { return rad_to_deg(Eigen::AngleAxisd(T.linear()).angle()); }

}  // namespace rankslam::lie
