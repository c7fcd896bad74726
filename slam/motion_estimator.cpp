#include "rankslam/slam/motion_estimator.hpp"

#include "rankslam/robust/msse.hpp"
#include "rankslam/robust/ransac.hpp"
#include "rankslam/robust/rigid.hpp"
#include "rankslam/robust/workspace.hpp"

namespace rankslam::slam {

struct MotionEstimator::Impl {
  Impl(const SlamConfig& config, std::size_t max_points)
      : mode(config.mode),
        capacity(static_cast<int>(max_points)),
        model(capacity),
        workspace(capacity),
        source(3, capacity),
        target(3, capacity) {
    ransac.inlier_threshold = config.ransac_threshold_m;
    ransac.hypotheses = config.ransac_iterations;
    ransac.seed = static_cast<std::uint64_t>(config.seed);
    msse.seed = static_cast<std::uint64_t>(config.seed);
  }

  Mode mode;
  int capacity;
  robust::RigidModel model;
  robust::RobustWorkspace workspace;
  robust::RansacConfig ransac;
  robust::MsseConfig msse;
  Eigen::Matrix3Xd source;
  Eigen::Matrix3Xd target;
};

MotionEstimator::MotionEstimator(const SlamConfig& config, std::size_t max_points)
    : impl_(std::make_unique<Impl>(config, max_points)) {}

MotionEstimator::~MotionEstimator() = default;

MotionEstimate MotionEstimator::estimate(std::span<const Eigen::Vector3f> source,
                                         std::span<const Eigen::Vector3f> target,
                                         std::span<const double> sigma_m) {
  MotionEstimate estimate;
  const auto n = static_cast<int>(std::min(source.size(), target.size()));
  if (n > impl_->capacity) {
    estimate.failure_reason = "more matches than the estimator was set up for";
    return estimate;
  }
  for (int i = 0; i < n; ++i) {
    impl_->source.col(i) = source[static_cast<std::size_t>(i)].cast<double>();
    impl_->target.col(i) = target[static_cast<std::size_t>(i)].cast<double>();
  }
  if (impl_->model.set_correspondences(impl_->source.leftCols(n), impl_->target.leftCols(n)) !=
      robust::RobustStatus::kOk) {
    estimate.failure_reason = "invalid correspondences";
    return estimate;
  }
  const auto result = impl_->mode == Mode::kBaseline
                          ? robust::estimate_ransac(impl_->model, impl_->ransac, impl_->workspace)
                          : robust::estimate_msse(impl_->model, impl_->msse, impl_->workspace, sigma_m);
  if (!result.ok()) {
    estimate.failure_reason = robust::to_string(result.status);
    return estimate;
  }
  estimate.ok = true;
  estimate.T_target_source = result.model;
  estimate.inliers = result.inlier_count;
  return estimate;
}

}  // namespace rankslam::slam
