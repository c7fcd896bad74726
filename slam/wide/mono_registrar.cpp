#include "rankslam/wide/mono_registrar.hpp"

#include <Eigen/Eigenvalues>
#include <Eigen/QR>

#include <algorithm>
#include <cmath>

namespace rankslam::wide {

MonoRegistrar::MonoRegistrar(const MonoRegistrationOptions& options)
    : options_(options),
      matcher_(cv::NORM_L2),
      model_(options.max_matches),
      workspace_(options.max_matches),
      points_(3, options.max_matches),
      rays_(3, options.max_matches) {}

MonoRegistration MonoRegistrar::register_frames(const RgbdFeatures& rgbd, const WideFeatures& wide) {
  MonoRegistration result;
  if (rgbd.count < options_.min_inliers || wide.count < options_.min_inliers) return result;
  // OpenCV's matchers append to their output.
  forward_.clear();
  backward_.clear();
  matcher_.knnMatch(rgbd.descriptors, wide.descriptors, forward_, 2);
  if (options_.mutual) matcher_.match(wide.descriptors, rgbd.descriptors, backward_);
  int n = 0;
  for (const auto& pair : forward_) {
    if (pair.empty() || n >= options_.max_matches) continue;
    const cv::DMatch& best = pair[0];
    if (pair.size() > 1 && !(best.distance < options_.ratio * pair[1].distance)) continue;
    if (options_.mutual && backward_[static_cast<std::size_t>(best.trainIdx)].trainIdx != best.queryIdx) continue;
    points_.col(n) = rgbd.points.col(best.queryIdx);
    rays_.col(n) = wide.rays.col(best.trainIdx);
    ++n;
  }
  result.matches = n;
  if (n < options_.min_inliers) return result;
  if (model_.set_correspondences(points_.leftCols(n), rays_.leftCols(n)) != robust::RobustStatus::kOk) return result;
  const auto estimate = robust::estimate_msse(model_, options_.msse, workspace_);
  if (!estimate.ok()) return result;
  result.T_wide_rgbd = estimate.model;
  // Covariance of ξ = (translation, rotation) for T ← exp(ξ)·T; the translation t of T (the RGB-D
  // camera's centre in the wide frame) moves by ρ + φ × t.
  const Eigen::Matrix<double, 6, 6> H = model_.information(estimate.model, estimate.inliers);
  result.information = H / std::max(estimate.scale * estimate.scale, 1e-12);
  const Eigen::Matrix<double, 6, 6> covariance =
      estimate.scale * estimate.scale * H.completeOrthogonalDecomposition().pseudoInverse();
  const Eigen::Vector3d t = estimate.model.translation();
  Eigen::Matrix<double, 3, 6> dposition;
  dposition.leftCols<3>() = Eigen::Matrix3d::Identity();
  dposition.rightCols<3>() << 0.0, t.z(), -t.y(), -t.z(), 0.0, t.x(), t.y(), -t.x(), 0.0;
  const Eigen::Matrix3d position_covariance = dposition * covariance * dposition.transpose();
  result.position_sigma_m =
      std::sqrt(std::max(0.0, Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(position_covariance).eigenvalues()(2)));
  result.inliers = estimate.inlier_count;
  result.scale = estimate.scale;
  result.ok = estimate.inlier_count >= options_.min_inliers && result.position_sigma_m <= options_.max_position_sigma_m;
  return result;
}

}  // namespace rankslam::wide
