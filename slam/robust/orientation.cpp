#include "rankslam/robust/orientation.hpp"

#include "rankslam/parallel/cpu_features.hpp"

#include <algorithm>
#include <cmath>

#include "vector_kernels.hpp"

namespace rankslam::robust {

OrientationModel::OrientationModel(int max_points)
    : normals_(std::max(0, max_points), 3), weights_(std::max(0, max_points)) {}

RobustStatus OrientationModel::set_normals(const Eigen::Ref<const Eigen::Matrix3Xd>& normals,
                                           std::span<const double> weights) {
  size_ = 0;
  has_weights_ = false;
  const auto n = static_cast<int>(normals.cols());
  if (!weights.empty() && static_cast<int>(weights.size()) != n) return RobustStatus::kInvalidInput;
  if (n > capacity()) return RobustStatus::kCapacityExceeded;
  for (const double w : weights) {
    if (!std::isfinite(w) || w < 0.0) return RobustStatus::kInvalidInput;
  }
  for (int i = 0; i < n; ++i) {
    const Eigen::Vector3d v = normals.col(i);
    const double norm = v.norm();
    if (!std::isfinite(norm) || !(norm > 1e-12)) return RobustStatus::kInvalidInput;
    normals_.row(i) = (v / norm).transpose();
  }
  if (!weights.empty()) {
    weights_.head(n) = Eigen::Map<const Eigen::VectorXd>(weights.data(), n);
    has_weights_ = true;
  }
  size_ = n;
  return RobustStatus::kOk;
}

bool OrientationModel::sample_degenerate(std::span<const int> sample) const {
  return sample.size() != 1;  // normals are validated unit vectors at set_normals
}

bool OrientationModel::fit_sample(std::span<const int> sample, Params& direction) const {
  if (sample.size() != 1) return false;
  direction = normal(sample[0]);
  return true;
}

bool OrientationModel::fit_inliers(std::span<const int> inliers, const double* point_weights,
                                   Params& direction) const {
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  double weight_sum = 0.0;
  for (const int i : inliers) {
    const double w =
        (has_weights_ ? weights_(i) : 1.0) * (point_weights != nullptr ? point_weights[i] : 1.0);
    sum += w * normal(i);
    weight_sum += w;
  }
  const double norm = sum.norm();
  // Inlier normals that cancel out (antipodal) or zero total weight define no direction.
  if (!(weight_sum > 0.0) || !(norm > 1e-9 * weight_sum) || !std::isfinite(norm)) return false;
  direction = sum / norm;
  return true;
}

void OrientationModel::squared_residuals(const Params& direction, int begin, int count,
                                         double* out) const {
  Eigen::Map<Eigen::ArrayXd> o(out, count);
  o = (direction.x() * normals_.col(0).segment(begin, count).array() +
       direction.y() * normals_.col(1).segment(begin, count).array() +
       direction.z() * normals_.col(2).segment(begin, count).array())
          .max(-1.0)
          .min(1.0)
          .acos()
          .square();
}

void OrientationModel::selection_scores(const Params& direction, int begin, int count,
                                        double* out) const {
  Eigen::Map<Eigen::ArrayXd> o(out, count);
  o = 1.0 - (direction.x() * normals_.col(0).segment(begin, count).array() +
             direction.y() * normals_.col(1).segment(begin, count).array() +
             direction.z() * normals_.col(2).segment(begin, count).array());
}

int OrientationModel::scaled_selection_scores(const Params& direction, int begin, int count,
                                              const double* inverse_variances, double bound,
                                              double* out) const {
  int done = 0;
  int below = 0;
  if (parallel::vector_kernels_enabled()) {
    below = vector::orientation_scores(normals_.col(0).data() + begin, normals_.col(1).data() + begin,
                                       normals_.col(2).data() + begin, direction, count, inverse_variances,
                                       bound, out, done);
  }
  if (done < count) {
    const int rest = count - done;
    double* values = out + done;
    selection_scores(direction, begin + done, rest, values);
    for (int i = 0; i < rest; ++i) {
      if (inverse_variances != nullptr) values[i] *= inverse_variances[done + i];
      below += values[i] < bound ? 1 : 0;
    }
  }
  return below;
}

double OrientationModel::score_to_squared_residual(double score) {
  const double angle = std::acos(std::clamp(1.0 - score, -1.0, 1.0));
  return angle * angle;
}

}  // namespace rankslam::robust
