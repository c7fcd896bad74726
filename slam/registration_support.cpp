#include "rankslam/slam/registration_support.hpp"

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>

#include <algorithm>
#include <cmath>
#include <limits>

namespace rankslam::slam {

Eigen::Vector3f rolling_shutter_corrected(const Eigen::Vector3f& point, double row, int height, double readout_s,
                                          const Eigen::Matrix<double, 6, 1>& velocity) {
  if (readout_s == 0.0) return point;
  // Row y was exposed (y/h − ½)·readout after the frame's mid-exposure time. Moving its point by
  // the camera's velocity over that time expresses it in the mid-exposure camera frame.
  const double dt_s = (row / static_cast<double>(height) - 0.5) * readout_s;
  const Eigen::Vector3d p = point.cast<double>();
  return Eigen::Vector3f((p + dt_s * (velocity.head<3>().cross(p) + velocity.tail<3>())).cast<float>());
}

namespace {

template <class Visit>
void for_each_inlier(const Eigen::Isometry3d& T_target_source, std::span<const Eigen::Vector3f> source,
                     std::span<const Eigen::Vector3f> target, std::span<const double> sigma_m, Visit&& visit) {
  const Eigen::Isometry3f T = T_target_source.cast<float>();
  const std::size_t n = std::min({source.size(), target.size(), sigma_m.size()});
  for (std::size_t i = 0; i < n; ++i) {
    const double residual_m = static_cast<double>((T * source[i] - target[i]).norm());
    if (residual_m <= kInlierSigmas * sigma_m[i]) visit(source[i].cast<double>(), sigma_m[i]);
  }
}

}  // namespace

Matrix6d step_prior_information(const Eigen::Isometry3d& T_target_prior, const Eigen::Isometry3d& T_frame_current,
                                const Eigen::Matrix<double, 6, 1>& step_information) {
  // ξ_frame = Ad(T_frame_current)·ξ and ξ = Ad(M⁻¹)·ε.
  const Matrix6d to_step = lie::adjoint(T_frame_current) * lie::adjoint(T_target_prior.inverse());
  return to_step.transpose() * step_information.asDiagonal() * to_step;
}

Matrix6d prior_information_on_target(const Eigen::Isometry3d& T_target_prior, const Matrix6d& information_xi) {
  const Matrix6d to_xi = lie::adjoint(T_target_prior.inverse());  // ξ = Ad(M⁻¹)·ε
  const Matrix6d information = to_xi.transpose() * information_xi * to_xi;
  return 0.5 * (information + information.transpose());
}

Eigen::Isometry3d drivable_step(const Eigen::Isometry3d& step_cam, const Eigen::Isometry3d& T_base_cam) {
  const Eigen::Isometry3d step_base = T_base_cam * step_cam * T_base_cam.inverse();
  const Eigen::Matrix3d R = step_base.rotation();
  Eigen::Isometry3d drivable = Eigen::Isometry3d::Identity();
  drivable.linear() = Eigen::AngleAxisd(std::atan2(R(1, 0), R(0, 0)), Eigen::Vector3d::UnitZ()).toRotationMatrix();
  drivable.translation() = Eigen::Vector3d(step_base.translation().x(), 0.0, 0.0);
  return T_base_cam.inverse() * drivable * T_base_cam;
}

PlanarConstraint planar_constraint(const Eigen::Isometry3d& T_from_to, const Eigen::Isometry3d& T_base_cam,
                                   double height_sigma_m, double tilt_sigma_rad) {
  const Eigen::Isometry3d T_cam_base = T_base_cam.inverse();
  const Eigen::Isometry3d base_motion = T_base_cam * T_from_to * T_cam_base;
  Eigen::Isometry3d planar = Eigen::Isometry3d::Identity();
  const Eigen::Vector3d forward = base_motion.linear().col(0);
  planar.linear() = Eigen::AngleAxisd(std::atan2(forward.y(), forward.x()), Eigen::Vector3d::UnitZ()).toRotationMatrix();
  planar.translation() << base_motion.translation().x(), base_motion.translation().y(), 0.0;
  // In the base frame the error is Ad(T_base_cam)·ξ of the camera's, so
  // Ω_cam = Ad(T_base_cam)ᵀ·Ω_base·Ad(T_base_cam).
  Eigen::Matrix<double, 6, 1> base_information;
  const double tilt_information = 1.0 / (tilt_sigma_rad * tilt_sigma_rad);
  base_information << tilt_information, tilt_information, 1.0, 1e-2, 1e-2, 1.0 / (height_sigma_m * height_sigma_m);
  const Matrix6d to_base = lie::adjoint(T_base_cam);
  PlanarConstraint constraint;
  constraint.T_from_to = T_cam_base * planar * T_base_cam;
  constraint.information = to_base.transpose() * base_information.asDiagonal() * to_base;
  constraint.information = 0.5 * (constraint.information + constraint.information.transpose()).eval();
  return constraint;
}

MotionBelief combine(const MotionBelief& prior, const MotionBelief& measurement) {
  const Eigen::Isometry3d offset = prior.mean.inverse() * measurement.mean;
  const Eigen::AngleAxisd rotation(offset.rotation());
  Eigen::Matrix<double, 6, 1> xi;
  xi << rotation.angle() * rotation.axis(), offset.translation();
  MotionBelief result;
  result.information = prior.information + measurement.information;
  const Eigen::Matrix<double, 6, 1> shift = result.information.ldlt().solve(measurement.information * xi);
  Eigen::Isometry3d step = Eigen::Isometry3d::Identity();
  const double angle = shift.head<3>().norm();
  if (angle > 0.0) step.linear() = Eigen::AngleAxisd(angle, shift.head<3>() / angle).toRotationMatrix();
  step.translation() = shift.tail<3>();
  result.mean = prior.mean * step;
  return result;
}

InlierSpread inlier_spread(const Eigen::Isometry3d& T_target_source, std::span<const Eigen::Vector3f> source,
                           std::span<const Eigen::Vector3f> target, std::span<const double> sigma_m) {
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  Eigen::Matrix3d sum_sq = Eigen::Matrix3d::Zero();
  InlierSpread spread;
  for_each_inlier(T_target_source, source, target, sigma_m, [&](const Eigen::Vector3d& p, double /*sigma*/) {
    sum += p;
    sum_sq += p * p.transpose();
    ++spread.inliers;
  });
  if (spread.inliers == 0) return spread;
  const Eigen::Vector3d mean = sum / spread.inliers;
  const Eigen::Matrix3d covariance = sum_sq / spread.inliers - mean * mean.transpose();
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> solver(covariance, Eigen::EigenvaluesOnly);
  spread.axes_m = solver.eigenvalues().cwiseMax(0.0).cwiseSqrt();
  return spread;
}

double inlier_thickness_m(const Eigen::Isometry3d& T_target_source, std::span<const Eigen::Vector3f> source,
                          std::span<const Eigen::Vector3f> target, std::span<const double> sigma_m) {
  const InlierSpread spread = inlier_spread(T_target_source, source, target, sigma_m);
  return spread.inliers < 4 ? 0.0 : spread.axes_m(0);
}

Matrix6d correspondence_information(const Eigen::Isometry3d& T_target_source, std::span<const Eigen::Vector3f> source,
                                    std::span<const Eigen::Vector3f> target, std::span<const double> sigma_m) {
  Matrix6d information = Matrix6d::Zero();
  for_each_inlier(T_target_source, source, target, sigma_m, [&](const Eigen::Vector3d& s, double sigma) {
    // T·exp(ξ)·s ≈ T·s + R·(ω × s + τ): B = [−[s]×  I].
    Eigen::Matrix<double, 3, 6> B;
    B << 0.0, s.z(), -s.y(), 1.0, 0.0, 0.0,  //
        -s.z(), 0.0, s.x(), 0.0, 1.0, 0.0,   //
        s.y(), -s.x(), 0.0, 0.0, 0.0, 1.0;
    information += B.transpose() * B / (sigma * sigma);
  });
  return information;
}

double rotation_sigma_rad(const Matrix6d& information) {
  const Eigen::LDLT<Matrix6d> factor(information);
  if (factor.info() != Eigen::Success || !(factor.vectorD().minCoeff() > 1e-12 * factor.vectorD().maxCoeff())) {
    return std::numeric_limits<double>::infinity();
  }
  const Matrix6d covariance = factor.solve(Matrix6d::Identity());
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> rotation(covariance.topLeftCorner<3, 3>(), Eigen::EigenvaluesOnly);
  return std::sqrt(std::max(0.0, rotation.eigenvalues()(2)));
}

double least_information_ratio(const Matrix6d& measured, const Matrix6d& reference) {
  const Eigen::LLT<Matrix6d> reference_factor(reference);
  if (reference_factor.info() != Eigen::Success) return 0.0;
  const Eigen::GeneralizedSelfAdjointEigenSolver<Matrix6d> ratios(measured, reference, Eigen::EigenvaluesOnly);
  if (ratios.info() != Eigen::Success) return 0.0;
  return std::max(0.0, ratios.eigenvalues()(0));
}

Matrix6d surface_information(std::span<const Eigen::Vector3f> points, std::span<const Eigen::Vector3f> normals) {
  Matrix6d information = Matrix6d::Zero();
  const std::size_t n = std::min(points.size(), normals.size());
  if (n == 0) return information;
  for (std::size_t i = 0; i < n; ++i) {
    const Eigen::Vector3d p = points[i].cast<double>();
    const Eigen::Vector3d normal = normals[i].cast<double>();
    Eigen::Matrix<double, 6, 1> a;
    a << p.cross(normal), normal;
    information.selfadjointView<Eigen::Lower>().rankUpdate(a);
  }
  information = information.selfadjointView<Eigen::Lower>();
  return information / static_cast<double>(n);
}

}  // namespace rankslam::slam
