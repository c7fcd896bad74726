#include "rankslam/slam/motion_estimator.hpp"

#include "rankslam/robust/msse.hpp"
#include "rankslam/robust/ransac.hpp"
#include "rankslam/robust/rigid.hpp"
#include "rankslam/robust/workspace.hpp"

#include <algorithm>
#include <cmath>
#include <vector>

namespace rankslam::slam {
namespace {

// Below this inlier fraction the noise-normalised MSSE gets a second opinion (see estimate()).
// Its own result is then often the trap described there; above it, never in the recordings
// measured.
constexpr double kSecondOpinionBelow = 0.75;

}  // namespace

struct MotionEstimator::Impl {
  Impl(const SlamConfig& config, RobustEstimator robust_estimator, std::size_t max_points)
      : estimator(robust_estimator),
        capacity(static_cast<int>(max_points)),
        model(capacity),
        workspace(capacity),
        source(3, capacity),
        target(3, capacity),
        refit_weights(max_points),
        normalised_sq(max_points) {
    ransac.inlier_threshold = config.ransac_threshold_m;
    ransac.hypotheses = config.ransac_iterations;
    ransac.seed = static_cast<std::uint64_t>(config.seed);
    msse.hypotheses = config.msse_hypotheses;
    msse.min_inlier_fraction = config.msse_min_inlier_fraction;
    msse.refine_iterations = config.msse_refine_iterations;
    msse.seed = static_cast<std::uint64_t>(config.seed);
  }

  /// RMS over the k smallest of the residuals under T in units of their noise σ_i (n points).
  [[nodiscard]] double noise_scale(const Eigen::Isometry3d& T, std::span<const double> sigma_m, int n, int k) {
    if (sigma_m.empty() || k < 1 || k > n) return 1.0;
    for (int i = 0; i < n; ++i) {
      const double sigma = sigma_m[static_cast<std::size_t>(i)];
      normalised_sq[static_cast<std::size_t>(i)] = (T * source.col(i) - target.col(i)).squaredNorm() / (sigma * sigma);
    }
    const auto begin = normalised_sq.begin();
    std::nth_element(begin, begin + (k - 1), begin + n);
    double sum = 0.0;
    for (int i = 0; i < k; ++i) sum += normalised_sq[static_cast<std::size_t>(i)];
    return std::sqrt(sum / k);
  }

  /// Mean distance between where `a` and `b` put the source points.
  [[nodiscard]] double disagreement(const Eigen::Isometry3d& a, const Eigen::Isometry3d& b, int n) const {
    double sum = 0.0;
    for (int i = 0; i < n; ++i) sum += (a * source.col(i) - b * source.col(i)).norm();
    return n > 0 ? sum / n : 0.0;
  }

  RobustEstimator estimator;
  int capacity;
  robust::RigidModel model;
  robust::RobustWorkspace workspace;
  robust::RansacConfig ransac;
  robust::MsseConfig msse;
  Eigen::Matrix3Xd source;
  Eigen::Matrix3Xd target;
  std::vector<double> refit_weights;
  std::vector<double> normalised_sq;
  robust::MsseTeamScratch<robust::RigidModel::Params> team;
};

MotionEstimator::MotionEstimator(const SlamConfig& config, RobustEstimator estimator, std::size_t max_points)
    : impl_(std::make_unique<Impl>(config, estimator, max_points)) {}

MotionEstimator::~MotionEstimator() = default;

void MotionEstimator::share_with(parallel::ThreadTeam* team) {
  impl_->team.reserve(team, impl_->msse.hypotheses, robust::RigidModel::kSampleSize, impl_->capacity);
}

MotionEstimate MotionEstimator::estimate(std::span<const Eigen::Vector3f> source,
                                         std::span<const Eigen::Vector3f> target, std::span<const double> sigma_m,
                                         const Eigen::Isometry3d* T_target_source_predicted,
                                         std::span<const double> weights) {
  Impl& impl = *impl_;
  MotionEstimate estimate;
  const auto n = static_cast<int>(std::min(source.size(), target.size()));
  if (n > impl.capacity) {
    estimate.failure_reason = "more matches than the estimator was set up for";
    return estimate;
  }
  if (!sigma_m.empty() && static_cast<int>(sigma_m.size()) != n) {
    estimate.failure_reason = "noise scales do not match the correspondences";
    return estimate;
  }
  if (!weights.empty() && static_cast<int>(weights.size()) != n) {
    estimate.failure_reason = "weights do not match the correspondences";
    return estimate;
  }
  for (int i = 0; i < n; ++i) {
    impl.source.col(i) = source[static_cast<std::size_t>(i)].cast<double>();
    impl.target.col(i) = target[static_cast<std::size_t>(i)].cast<double>();
  }
  if (impl.model.set_correspondences(impl.source.leftCols(n), impl.target.leftCols(n), weights) !=
      robust::RobustStatus::kOk) {
    estimate.failure_reason = "invalid correspondences";
    return estimate;
  }
  if (impl.estimator == RobustEstimator::kRansac) {
    const auto result = robust::estimate_ransac(impl.model, impl.ransac, impl.workspace);
    if (!result.ok()) {
      estimate.failure_reason = robust::to_string(result.status);
      return estimate;
    }
    estimate.ok = true;
    estimate.T_target_source = result.model;
    estimate.inliers = result.inlier_count;
    return estimate;
  }

  const auto result = robust::estimate_msse(impl.model, impl.msse, impl.workspace, sigma_m,
                                            robust::AcceptAllHypotheses{}, &impl.team);
  if (!result.ok()) {
    estimate.failure_reason = robust::to_string(result.status);
    return estimate;
  }
  estimate.ok = true;
  estimate.T_target_source = result.model;
  estimate.inliers = result.inlier_count;

  // Ranking residuals in units of their noise makes far points (large σ) cheap inliers of almost
  // any motion. Where many of them sit on one quantised depth level in both frames, a motion
  // that shifts them in the image without changing their depth fits them near-exactly: the
  // least-k-th-order fit picks it from a fraction of the matches and segmentation stops near k0.
  // When the inlier fraction is low, MSSE ranks again in metres (noise weights in the refit
  // only), and of the two motions the one closer to the constant-velocity prediction is kept.
  if (!sigma_m.empty() && T_target_source_predicted != nullptr && result.inlier_count < kSecondOpinionBelow * n) {
    const Eigen::Isometry3d first = result.model;
    const int first_inliers = result.inlier_count;
    for (int i = 0; i < n; ++i) {
      const double sigma = sigma_m[static_cast<std::size_t>(i)];
      const double kind_weight = weights.empty() ? 1.0 : weights[static_cast<std::size_t>(i)];
      impl.refit_weights[static_cast<std::size_t>(i)] = kind_weight / (sigma * sigma);
    }
    if (impl.model.set_correspondences(
            impl.source.leftCols(n), impl.target.leftCols(n),
            std::span<const double>(impl.refit_weights.data(), static_cast<std::size_t>(n))) == robust::RobustStatus::kOk) {
      const auto metric = robust::estimate_msse(impl.model, impl.msse, impl.workspace, {},
                                                robust::AcceptAllHypotheses{}, &impl.team);
      if (metric.ok() && impl.disagreement(metric.model, *T_target_source_predicted, n) <
                             impl.disagreement(first, *T_target_source_predicted, n)) {
        estimate.T_target_source = metric.model;
        estimate.inliers = std::max(first_inliers, metric.inlier_count);
      }
    }
  }
  estimate.noise_scale = impl.noise_scale(estimate.T_target_source, sigma_m, n, estimate.inliers);
  return estimate;
}

}  // namespace rankslam::slam
