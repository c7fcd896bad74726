#include "rankslam/robust/orientation.hpp"

#include "rankslam/parallel/cpu_features.hpp"

#include <algorithm>
#include <cmath>

#if defined(__x86_64__) && defined(__GNUC__)
#include <immintrin.h>
#define RANKSLAM_ROBUST_HAVE_AVX2_ORIENTATION 1
#endif

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

namespace {

#ifdef RANKSLAM_ROBUST_HAVE_AVX2_ORIENTATION
// OrientationModel::scaled_selection_scores 4 normals at a time (AVX2, chosen at run time):
// 1 − ((d_x·n_x + d_y·n_y) + d_z·n_z) as Eigen evaluates selection_scores' expression, without
// FMA, so the same values. Returns the count below `bound` of the whole blocks of 4; `done` is
// how many normals those covered.
__attribute__((target("avx2"))) int orientation_scores_avx2(const double* nx, const double* ny,
                                                            const double* nz,
                                                            const Eigen::Vector3d& direction,
                                                            int count, const double* inverse_variances,
                                                            double bound, double* out, int& done) {
  const __m256d dx = _mm256_set1_pd(direction.x());
  const __m256d dy = _mm256_set1_pd(direction.y());
  const __m256d dz = _mm256_set1_pd(direction.z());
  const __m256d one = _mm256_set1_pd(1.0);
  const __m256d limit = _mm256_set1_pd(bound);
  int below = 0;
  int i = 0;
  for (; i + 4 <= count; i += 4) {
    __m256d dot = _mm256_add_pd(_mm256_mul_pd(dx, _mm256_loadu_pd(nx + i)), _mm256_mul_pd(dy, _mm256_loadu_pd(ny + i)));
    dot = _mm256_add_pd(dot, _mm256_mul_pd(dz, _mm256_loadu_pd(nz + i)));
    __m256d score = _mm256_sub_pd(one, dot);
    if (inverse_variances != nullptr) score = _mm256_mul_pd(score, _mm256_loadu_pd(inverse_variances + i));
    _mm256_storeu_pd(out + i, score);
    below += __builtin_popcount(static_cast<unsigned>(_mm256_movemask_pd(_mm256_cmp_pd(score, limit, _CMP_LT_OQ))));
  }
  done = i;
  return below;
}
#endif

}  // namespace

int OrientationModel::scaled_selection_scores(const Params& direction, int begin, int count,
                                              const double* inverse_variances, double bound,
                                              double* out) const {
  int done = 0;
  int below = 0;
#ifdef RANKSLAM_ROBUST_HAVE_AVX2_ORIENTATION
  if (parallel::cpu_has_avx2()) {
    below = orientation_scores_avx2(normals_.col(0).data() + begin, normals_.col(1).data() + begin,
                                    normals_.col(2).data() + begin, direction, count,
                                    inverse_variances, bound, out, done);
  }
#endif
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
