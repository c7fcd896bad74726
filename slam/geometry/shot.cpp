#include "rankslam/geometry/shot.hpp"

#include <algorithm>
#include <array>
#include <cmath>

#include <Eigen/Eigenvalues>

#include "fast_math.hpp"

namespace rankslam::geometry {

namespace {

constexpr double kRad45 = 0.78539816339744830961566084581988;
constexpr double kRad90 = 1.5707963267948966192313216916398;
constexpr double kRad135 = 2.3561944901923449288469825374596;
constexpr double kRadPi78 = 2.7488935718910690836548129603691;
constexpr int kStride = kShotCosineBins + 1;  // values per volume
// PCL's sign tie-break looks at this many neighbours around the median distance.
constexpr int kTieBreakPoints = 5;

}  // namespace

void ShotEstimator::reserve(int max_support) {
  capacity_ = std::max(0, max_support);
  indices_.assign(static_cast<std::size_t>(capacity_), 0);
  squared_distances_.assign(static_cast<std::size_t>(capacity_), 0.0F);
  deltas_.assign(static_cast<std::size_t>(capacity_), Eigen::Vector3f::Zero());
  sorted_.assign(static_cast<std::size_t>(capacity_), {0.0F, 0});
  count_ = 0;
}

bool ShotEstimator::local_reference_frame(float radius_m, Eigen::Matrix3f& rf) {
  // Weighted covariance about the keypoint, weight R − d (Tombari et al. 2010, eq. 3); the
  // keypoint itself (d = 0) is left out as in PCL.
  float c00 = 0.0F, c01 = 0.0F, c02 = 0.0F, c11 = 0.0F, c12 = 0.0F, c22 = 0.0F;
  float weight_sum = 0.0F;
  int valid = 0;
  for (int k = 0; k < count_; ++k) {
    const float d2 = squared_distances_[static_cast<std::size_t>(k)];
    if (d2 == 0.0F) continue;
    const Eigen::Vector3f& d = deltas_[static_cast<std::size_t>(k)];
    const float w = radius_m - std::sqrt(d2);
    c00 += w * d.x() * d.x();
    c01 += w * d.x() * d.y();
    c02 += w * d.x() * d.z();
    c11 += w * d.y() * d.y();
    c12 += w * d.y() * d.z();
    c22 += w * d.z() * d.z();
    weight_sum += w;
    ++valid;
  }
  if (valid < 5 || !(weight_sum > 0.0F)) return false;
  Eigen::Matrix3d cov;
  cov << c00, c01, c02, c01, c11, c12, c02, c12, c22;
  cov /= static_cast<double>(weight_sum);
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> solver;
  solver.computeDirect(cov);
  if (!solver.eigenvalues().allFinite() || !solver.eigenvectors().allFinite()) return false;
  Eigen::Vector3f x_axis = solver.eigenvectors().col(2).cast<float>();  // largest spread
  Eigen::Vector3f z_axis = solver.eigenvectors().col(0).cast<float>();  // smallest spread

  // Sign disambiguation: each axis points toward the majority of the support points.
  int plus_x = 0;
  int plus_z = 0;
  for (int k = 0; k < count_; ++k) {
    if (squared_distances_[static_cast<std::size_t>(k)] == 0.0F) continue;
    const Eigen::Vector3f& d = deltas_[static_cast<std::size_t>(k)];
    plus_x += d.dot(x_axis) >= 0.0F ? 1 : 0;
    plus_z += d.dot(z_axis) >= 0.0F ? 1 : 0;
  }
  plus_x = 2 * plus_x - valid;
  plus_z = 2 * plus_z - valid;
  if (plus_x == 0 || plus_z == 0) {
    // A tie: decide on the 5 neighbours around the median distance (PCL's rule).
    int n = 0;
    for (int k = 0; k < count_; ++k) {
      const float d2 = squared_distances_[static_cast<std::size_t>(k)];
      if (d2 == 0.0F) continue;
      sorted_[static_cast<std::size_t>(n++)] = {d2, k};
    }
    std::sort(sorted_.begin(), sorted_.begin() + n, [](const auto& a, const auto& b) {
      return a.first < b.first || (a.first == b.first && a.second < b.second);
    });
    const int median = n / 2;
    const auto tie_break = [&](Eigen::Vector3f& axis) {
      int votes = 0;
      for (int i = -kTieBreakPoints / 2; i <= kTieBreakPoints / 2; ++i) {
        const int k = sorted_[static_cast<std::size_t>(median - i)].second;
        votes += deltas_[static_cast<std::size_t>(k)].dot(axis) > 0.0F ? 1 : 0;
      }
      if (votes < kTieBreakPoints / 2 + 1) axis = -axis;
    };
    if (plus_x == 0) tie_break(x_axis);
    if (plus_z == 0) tie_break(z_axis);
  }
  if (plus_x < 0) x_axis = -x_axis;
  if (plus_z < 0) z_axis = -z_axis;
  rf.row(0) = x_axis.transpose();
  rf.row(2) = z_axis.transpose();
  rf.row(1) = rf.row(2).cross(rf.row(0));
  return true;
}

ShotResult ShotEstimator::compute(const Eigen::Vector3f& center,
                                  std::span<const Eigen::Vector3f> points,
                                  std::span<const Eigen::Vector3f> normals, const PointGrid& grid,
                                  float radius_m, int min_neighbours, float* descriptor,
                                  Eigen::Matrix3f* lrf) {
  std::fill(descriptor, descriptor + kShotSize, 0.0F);
  count_ = 0;
  bool overflow = false;
  grid.for_each_in_radius(center, radius_m, [&](int index, float d2) {
    if (count_ == capacity_) {
      overflow = true;
      return;
    }
    indices_[static_cast<std::size_t>(count_)] = index;
    squared_distances_[static_cast<std::size_t>(count_)] = d2;
    deltas_[static_cast<std::size_t>(count_)] = points[static_cast<std::size_t>(index)] - center;
    ++count_;
  });
  (void)overflow;  // capacity is the whole cloud: cannot happen when reserved for it
  if (count_ < std::max(min_neighbours, 1)) return ShotResult::kTooFewNeighbours;
  Eigen::Matrix3f rf;
  if (!local_reference_frame(radius_m, rf)) return ShotResult::kTooFewNeighbours;
  if (lrf != nullptr) *lrf = rf;
  const Eigen::Vector3f frame_x = rf.row(0).transpose();
  const Eigen::Vector3f frame_y = rf.row(1).transpose();
  const Eigen::Vector3f frame_z = rf.row(2).transpose();
  const float radius_1_4 = radius_m / 4.0F;
  const float radius_1_2 = radius_m / 2.0F;
  const float radius_3_4 = radius_m * 3.0F / 4.0F;
  constexpr auto kRad45f = static_cast<float>(kRad45);
  constexpr auto kRad90f = static_cast<float>(kRad90);
  constexpr auto kRad135f = static_cast<float>(kRad135);
  constexpr auto kRadPi78f = static_cast<float>(kRadPi78);
  constexpr float kInverseRad45 = 1.0F / kRad45f;
  constexpr float kInverseRad90 = 1.0F / kRad90f;
  // PCL's circular neighbours of cosine bin s ∈ [0, 10] over 10 bins: (s + 1) % 10, (s − 1 + 10) % 10.
  constexpr std::array<int, kShotCosineBins + 1> kNextBin = {1, 2, 3, 4, 5, 6, 7, 8, 9, 0, 1};
  constexpr std::array<int, kShotCosineBins + 1> kPreviousBin = {9, 0, 1, 2, 3, 4, 5, 6, 7, 8, 9};

  // Float throughout: PCL computes in double, but the votes go into float bins and the results
  // agree to a cosine similarity above 0.9999 (test/unit/geometry, shot_pcl_test).
  for (int k = 0; k < count_; ++k) {
    const int index = indices_[static_cast<std::size_t>(k)];
    const float distance = std::sqrt(squared_distances_[static_cast<std::size_t>(k)]);
    if (distance < 1e-15F) continue;  // the keypoint itself
    // Cosine bin (PCL createBinDistanceShape): (1 + cos) · bins / 2 in [0, bins].
    const float cosine =
        std::clamp(normals[static_cast<std::size_t>(index)].dot(frame_z), -1.0F, 1.0F);
    float bin_distance = (1.0F + cosine) * (0.5F * static_cast<float>(kShotCosineBins));

    const Eigen::Vector3f& delta = deltas_[static_cast<std::size_t>(k)];
    const float x = delta.dot(frame_x);
    const float y = delta.dot(frame_y);
    const float z = delta.dot(frame_z);

    // Volume: azimuth octant (bits 4, 3 and the diagonal split), elevation (z > 0), radius.
    const int bit4 = ((y > 0) || ((y == 0.0F) && (x < 0))) ? 1 : 0;
    const int bit3 = ((x > 0) || ((x == 0.0F) && (y > 0))) ? 1 - bit4 : bit4;
    int desc_index = ((bit4 << 3) + (bit3 << 2)) << 1;
    if ((x * y > 0) || (x == 0.0F)) {
      desc_index += (std::abs(x) >= std::abs(y)) ? 0 : 4;
    } else {
      desc_index += (std::abs(x) > std::abs(y)) ? 4 : 0;
    }
    desc_index += z > 0 ? 1 : 0;
    const bool outer = distance > radius_1_2;
    desc_index += outer ? 2 : 0;

    // bin_distance ≥ 0: truncation is PCL's floor(bin_distance + 0.5).
    const int step_index = static_cast<int>(bin_distance + 0.5F);
    float* volume = descriptor + desc_index * kStride;

    // Each interpolation below gives the own volume 1 − |d| and a neighbour |d|, or nothing when
    // PCL's branch does not vote for a neighbour; written without branches (|d| goes to the own
    // bin with weight 0 instead) because the branches are unpredictable and dominated the time.
    // Cosine (adjacent bins, circular over the 10 bins as in PCL):
    bin_distance -= static_cast<float>(step_index);
    float weight = 1.0F - std::abs(bin_distance);
    volume[bin_distance > 0 ? kNextBin[static_cast<std::size_t>(step_index)]
                            : kPreviousBin[static_cast<std::size_t>(step_index)]] += std::abs(bin_distance);

    // Distance (adjacent radial shells at R/2): the outer shell votes inward below 3R/4, the
    // inner one outward above R/4.
    const float radius_distance = (distance - (outer ? radius_3_4 : radius_1_4)) / radius_1_2;
    weight += 1.0F - std::abs(radius_distance);
    const bool radial_vote = outer ? radius_distance <= 0.0F : radius_distance >= 0.0F;
    volume[(radial_vote ? (outer ? -2 : 2) * kStride : 0) + step_index] +=
        radial_vote ? std::abs(radius_distance) : 0.0F;

    // Inclination (adjacent elevation volumes at 90°): the lower one votes up below 135°, the
    // upper one down above 45°.
    const float inclination = detail::fast_acos(std::clamp(z / distance, -1.0F, 1.0F));
    const bool lower = inclination > kRad90f || (inclination == kRad90f && z <= 0);
    const float inclination_distance = (inclination - (lower ? kRad135f : kRad45f)) * kInverseRad90;
    weight += 1.0F - std::abs(inclination_distance);
    const bool elevation_vote = lower ? inclination_distance <= 0.0F : inclination_distance >= 0.0F;
    volume[(elevation_vote ? (lower ? 1 : -1) * kStride : 0) + step_index] +=
        elevation_vote ? std::abs(inclination_distance) : 0.0F;

    // Azimuth (adjacent sectors, circular); undefined on the LRF's z axis.
    if (y != 0.0F || x != 0.0F) {
      const float azimuth = detail::fast_atan2(y, x);
      const int sel = desc_index >> 2;
      const float azimuth_distance = std::clamp(
          (azimuth - (-kRadPi78f + kRad45f * static_cast<float>(sel))) * kInverseRad45, -0.5F, 0.5F);
      weight += 1.0F - std::abs(azimuth_distance);
      const int interp = (desc_index + (azimuth_distance > 0 ? 4 : kShotVolumes - 4)) & (kShotVolumes - 1);
      descriptor[interp * kStride + step_index] += std::abs(azimuth_distance);
    }
    volume[step_index] += weight;
  }

  double norm = 0.0;
  for (int j = 0; j < kShotSize; ++j) norm += static_cast<double>(descriptor[j]) * static_cast<double>(descriptor[j]);
  norm = std::sqrt(norm);
  if (!(norm > 0.0) || !std::isfinite(norm)) return ShotResult::kDegenerate;
  const auto inverse = static_cast<float>(1.0 / norm);
  for (int j = 0; j < kShotSize; ++j) descriptor[j] *= inverse;
  return ShotResult::kOk;
}

}  // namespace rankslam::geometry
