#include "rankslam/geometry/shot.hpp"

#include "rankslam/parallel/cpu_features.hpp"

#include <algorithm>
#include <array>
#include <cmath>

#include <Eigen/Eigenvalues>

#include "fast_math.hpp"
#include "vector_kernels.hpp"

namespace rankslam::geometry {

namespace {

using vector::VoteArrays;
using vector::VoteConstants;
using vector::VoteFrame;
// PCL's sign tie-break looks at this many neighbours around the median distance.
constexpr int kTieBreakPoints = 5;

// Neighbours processed together: the vector kernel takes blocks of up to 8.
constexpr int kLanes = 8;
using Lanes = Eigen::Array<float, kLanes, 1>;
using LaneMap = Eigen::Map<Lanes>;
using ConstLaneMap = Eigen::Map<const Lanes>;

// The bins and weights of every neighbour's five votes, branch-free (PCL's branches
// as selects: a neighbour that PCL does not let vote for an adjacent volume votes 0 into its own
// bin instead). Portable version, one neighbour at a time.
void vote_bins_portable(const VoteArrays& v, const VoteFrame& f, int end) {
  using C = VoteConstants;
  const Eigen::Vector3f& frame_x = f.x;
  const Eigen::Vector3f& frame_y = f.y;
  const Eigen::Vector3f& frame_z = f.z;
  const float radius_1_4 = f.radius_1_4;
  const float radius_1_2 = f.radius_1_2;
  const float radius_3_4 = f.radius_3_4;
  const float inverse_radius_1_2 = 1.0F / radius_1_2;
  const float* const dx_data = v.dx;
  const float* const dy_data = v.dy;
  const float* const dz_data = v.dz;
  const float* const nx_data = v.nx;
  const float* const ny_data = v.ny;
  const float* const nz_data = v.nz;
  const float* const distance_data = v.distance;
  std::int32_t* const own_data = v.own;
  float* const own_weight_data = v.own_weight;
  std::int32_t* const cosine_data = v.cosine;
  float* const cosine_weight_data = v.cosine_weight;
  std::int32_t* const radial_data = v.radial;
  float* const radial_weight_data = v.radial_weight;
  std::int32_t* const elevation_data = v.elevation;
  float* const elevation_weight_data = v.elevation_weight;
  std::int32_t* const azimuth_data = v.azimuth;
  float* const azimuth_weight_data = v.azimuth_weight;
  for (int k = 0; k < end; ++k) {
    const float dx = dx_data[k], dy = dy_data[k], dz = dz_data[k];
    const float distance = distance_data[k];
    const float x = dx * frame_x.x() + dy * frame_x.y() + dz * frame_x.z();
    const float y = dx * frame_y.x() + dy * frame_y.y() + dz * frame_y.z();
    const float z = dx * frame_z.x() + dy * frame_z.y() + dz * frame_z.z();
    float cosine = nx_data[k] * frame_z.x() + ny_data[k] * frame_z.y() + nz_data[k] * frame_z.z();
    cosine = cosine < -1.0F ? -1.0F : (cosine > 1.0F ? 1.0F : cosine);

    // Volume: azimuth octant (bits 4, 3 and the diagonal split), elevation (z > 0), radius.
    const float bit4 = (y > 0.0F || (y == 0.0F && x < 0.0F)) ? 1.0F : 0.0F;
    const float bit3 = (x > 0.0F || (x == 0.0F && y > 0.0F)) ? 1.0F - bit4 : bit4;
    const float ax = std::abs(x);
    const float ay = std::abs(y);
    const float diagonal = (x * y > 0.0F || x == 0.0F) ? (ax < ay ? 1.0F : 0.0F) : (ax > ay ? 1.0F : 0.0F);
    const float sector = 4.0F * bit4 + 2.0F * bit3 + diagonal;  // desc_index >> 2
    const float outer = distance > radius_1_2 ? 1.0F : 0.0F;
    const float volume = 4.0F * sector + (z > 0.0F ? 1.0F : 0.0F) + 2.0F * outer;

    // Cosine bin (PCL createBinDistanceShape): (1 + cos) · bins / 2 in [0, bins]; ≥ 0, so
    // truncation is PCL's floor(bin + 0.5).
    const float bin = (1.0F + cosine) * (0.5F * C::kBins);
    const auto step = static_cast<float>(static_cast<int>(bin + 0.5F));
    const float own = volume * C::kStride + step;
    // Adjacent cosine bin, circular over the 10 bins as in PCL: (s + 1) % 10 or (s − 1 + 10) % 10.
    const float bin_distance = bin - step;
    float weight = 1.0F - std::abs(bin_distance);
    const float next = step + 1.0F >= C::kBins ? step + 1.0F - C::kBins : step + 1.0F;
    const float previous = step + (C::kBins - 1.0F) >= C::kBins ? step - 1.0F : step + (C::kBins - 1.0F);
    cosine_data[k] = static_cast<std::int32_t>(volume * C::kStride + (bin_distance > 0.0F ? next : previous));
    cosine_weight_data[k] = std::abs(bin_distance);

    // Distance (adjacent radial shells at R/2): the outer shell votes inward below 3R/4, the
    // inner one outward above R/4.
    const float radius_distance = (distance - (outer > 0.0F ? radius_3_4 : radius_1_4)) * inverse_radius_1_2;
    weight += 1.0F - std::abs(radius_distance);
    const float radial_vote = (outer > 0.0F ? radius_distance <= 0.0F : radius_distance >= 0.0F) ? 1.0F : 0.0F;
    radial_data[k] = static_cast<std::int32_t>(own + radial_vote * (2.0F * C::kStride - 4.0F * C::kStride * outer));
    radial_weight_data[k] = radial_vote * std::abs(radius_distance);

    // Inclination (adjacent elevation volumes at 90°): the lower one votes up below 135°, the
    // upper one down above 45°. Arc cosine as detail::fast_acos.
    float c = z / distance;
    c = c < -1.0F ? -1.0F : (c > 1.0F ? 1.0F : c);
    const float ac = std::abs(c);
    const float poly =
        1.5707963050F +
        ac * (-0.2145988016F +
              ac * (0.0889789874F +
                    ac * (-0.0501743046F +
                          ac * (0.0308918810F +
                                ac * (-0.0170881256F + ac * (0.0066700901F + ac * -0.0012624911F))))));
    const float arc = std::sqrt(1.0F - ac) * poly;
    const float inclination = c >= 0.0F ? arc : C::kPi - arc;
    const float lower = (inclination > C::kRad90 || (inclination == C::kRad90 && z <= 0.0F)) ? 1.0F : 0.0F;
    const float inclination_distance = (inclination - (lower > 0.0F ? C::kRad135 : C::kRad45)) * C::kInverseRad90;
    weight += 1.0F - std::abs(inclination_distance);
    const float elevation_vote = (lower > 0.0F ? inclination_distance <= 0.0F : inclination_distance >= 0.0F) ? 1.0F : 0.0F;
    elevation_data[k] = static_cast<std::int32_t>(own + elevation_vote * (2.0F * C::kStride * lower - C::kStride));
    elevation_weight_data[k] = elevation_vote * std::abs(inclination_distance);

    // Azimuth (adjacent sectors, circular); undefined on the LRF's z axis. Arc tangent as
    // detail::fast_atan2.
    const float defined = (y != 0.0F || x != 0.0F) ? 1.0F : 0.0F;
    const float big = ax > ay ? ax : ay;
    const float t = (ax > ay ? ay : ax) / (defined > 0.0F ? big : 1.0F);
    const float t2 = t * t;
    float azimuth = t * (0.99997726F +
                         t2 * (-0.33262347F +
                               t2 * (0.19354346F +
                                     t2 * (-0.11643287F + t2 * (0.05265332F + t2 * -0.01172120F)))));
    azimuth = ay > ax ? 0.5F * C::kPi - azimuth : azimuth;
    azimuth = x < 0.0F ? C::kPi - azimuth : azimuth;
    azimuth = y < 0.0F ? -azimuth : azimuth;
    float azimuth_distance = (azimuth - (-C::kRadPi78 + C::kRad45 * sector)) * C::kInverseRad45;
    azimuth_distance = azimuth_distance < -0.5F ? -0.5F : (azimuth_distance > 0.5F ? 0.5F : azimuth_distance);
    weight += defined * (1.0F - std::abs(azimuth_distance));
    float adjacent = volume + (azimuth_distance > 0.0F ? 4.0F : C::kVolumes - 4.0F);
    adjacent = adjacent >= C::kVolumes ? adjacent - C::kVolumes : adjacent;
    azimuth_data[k] = static_cast<std::int32_t>(adjacent * C::kStride + step);
    azimuth_weight_data[k] = defined * std::abs(azimuth_distance);

    own_data[k] = static_cast<std::int32_t>(own);
    own_weight_data[k] = weight;
  }

}

}  // namespace

bool ShotEstimator::has_vector_kernel() { return parallel::vector_kernels_enabled(); }

void ShotEstimator::reserve(int max_support) {
  capacity_ = std::max(0, max_support);
  const auto padded = static_cast<std::size_t>(capacity_ + kLanes);
  for (std::vector<float>* v : {&dx_, &dy_, &dz_, &d2_, &nx_, &ny_, &nz_, &distance_, &own_weight_,
                                &cosine_weight_, &radial_weight_, &elevation_weight_, &azimuth_weight_}) {
    v->assign(padded, 0.0F);
  }
  for (std::vector<std::int32_t>* v : {&own_, &cosine_, &radial_, &elevation_, &azimuth_}) {
    v->assign(padded, 0);
  }
  neighbours_.assign(padded, 0);
  sorted_.assign(static_cast<std::size_t>(capacity_), {0.0F, 0});
  count_ = 0;
}

bool ShotEstimator::local_reference_frame(float radius_m, Eigen::Matrix3f& rf) {
  // Weighted covariance about the keypoint, weight R − d (Tombari et al. 2010, eq. 3); the
  // keypoint itself (d = 0) is not in the support arrays, as in PCL. The padding lanes past
  // count_ have d = R: weight 0.
  Lanes c00 = Lanes::Zero(), c01 = Lanes::Zero(), c02 = Lanes::Zero(), c11 = Lanes::Zero(),
        c12 = Lanes::Zero(), c22 = Lanes::Zero(), weights = Lanes::Zero();
  for (int k = 0; k < count_; k += kLanes) {
    const ConstLaneMap x(dx_.data() + k), y(dy_.data() + k), z(dz_.data() + k);
    const Lanes w = radius_m - ConstLaneMap(distance_.data() + k);
    const Lanes wx = w * x;
    const Lanes wy = w * y;
    c00 += wx * x;
    c01 += wx * y;
    c02 += wx * z;
    c11 += wy * y;
    c12 += wy * z;
    c22 += w * z * z;
    weights += w;
  }
  const int valid = count_;
  const float weight_sum = weights.sum();
  if (valid < 5 || !(weight_sum > 0.0F)) return false;
  Eigen::Matrix3d cov;
  const double s00 = c00.sum(), s01 = c01.sum(), s02 = c02.sum(), s11 = c11.sum(),
               s12 = c12.sum(), s22 = c22.sum();
  cov << s00, s01, s02, s01, s11, s12, s02, s12, s22;
  cov /= static_cast<double>(weight_sum);
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> solver;
  solver.computeDirect(cov);
  if (!solver.eigenvalues().allFinite() || !solver.eigenvectors().allFinite()) return false;
  Eigen::Vector3f x_axis = solver.eigenvectors().col(2).cast<float>();  // largest spread
  Eigen::Vector3f z_axis = solver.eigenvectors().col(0).cast<float>();  // smallest spread

  // Sign disambiguation: each axis points toward the majority of the support points.
  int votes_x = 0;
  int votes_z = 0;
  for (int k = 0; k < count_; ++k) {
    const auto i = static_cast<std::size_t>(k);
    votes_x += dx_[i] * x_axis.x() + dy_[i] * x_axis.y() + dz_[i] * x_axis.z() >= 0.0F ? 1 : 0;
    votes_z += dx_[i] * z_axis.x() + dy_[i] * z_axis.y() + dz_[i] * z_axis.z() >= 0.0F ? 1 : 0;
  }
  const int plus_x = 2 * votes_x - valid;
  const int plus_z = 2 * votes_z - valid;
  if (plus_x == 0 || plus_z == 0) {
    // A tie: decide on the 5 neighbours around the median distance (PCL's rule).
    const int n = count_;
    for (int k = 0; k < n; ++k) {
      sorted_[static_cast<std::size_t>(k)] = {d2_[static_cast<std::size_t>(k)], k};
    }
    std::sort(sorted_.begin(), sorted_.begin() + n, [](const auto& a, const auto& b) {
      return a.first < b.first || (a.first == b.first && a.second < b.second);
    });
    const int median = n / 2;
    const auto tie_break = [&](Eigen::Vector3f& axis) {
      int votes = 0;
      for (int i = -kTieBreakPoints / 2; i <= kTieBreakPoints / 2; ++i) {
        const auto k = static_cast<std::size_t>(sorted_[static_cast<std::size_t>(median - i)].second);
        votes += Eigen::Vector3f(dx_[k], dy_[k], dz_[k]).dot(axis) > 0.0F ? 1 : 0;
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
  if (static_cast<std::size_t>(grid.size()) != points.size() || normals.size() < points.size()) {
    return ShotResult::kTooFewNeighbours;  // not the grid over these points
  }
  // The support's offsets and squared distances come from the grid side by side; the keypoint
  // itself (and any point on it) has no direction, so neither the LRF nor the histogram takes it
  // (PCL skips it in both), but it counts toward the support, as PCL counts it.
  const PointGrid::RadiusGather gather{dx_.data(), dy_.data(), dz_.data(), d2_.data(),
                                       neighbours_.data(), capacity_};
  const int support = grid.gather_in_radius(center, radius_m, gather, count_);
  const int* const neighbours = neighbours_.data();
  float* const nx = nx_.data();
  float* const ny = ny_.data();
  float* const nz = nz_.data();
  for (int k = 0; k < count_; ++k) {
    const Eigen::Vector3f& n = normals[static_cast<std::size_t>(neighbours[k])];
    nx[k] = n.x();
    ny[k] = n.y();
    nz[k] = n.z();
  }
  if (support < std::max(min_neighbours, 1)) return ShotResult::kTooFewNeighbours;
  // Padding up to a whole block: at the keypoint with distance R, so weight R − d = 0 in the LRF.
  const int padded_end = (count_ + kLanes - 1) / kLanes * kLanes;
  for (int k = count_; k < padded_end; ++k) {
    const auto i = static_cast<std::size_t>(k);
    dx_[i] = dy_[i] = dz_[i] = 0.0F;
    nx_[i] = ny_[i] = nz_[i] = 0.0F;
    d2_[i] = radius_m * radius_m;
  }
  for (int k = 0; k < padded_end; k += kLanes) {
    LaneMap(distance_.data() + k) = ConstLaneMap(d2_.data() + k).sqrt();
  }
  Eigen::Matrix3f rf;
  if (!local_reference_frame(radius_m, rf)) return ShotResult::kTooFewNeighbours;
  if (lrf != nullptr) *lrf = rf;
  const Eigen::Vector3f frame_x = rf.row(0).transpose();
  const Eigen::Vector3f frame_y = rf.row(1).transpose();
  const Eigen::Vector3f frame_z = rf.row(2).transpose();
  const float radius_1_4 = radius_m / 4.0F;
  const float radius_1_2 = radius_m / 2.0F;
  const float radius_3_4 = radius_m * 3.0F / 4.0F;
  // Float throughout: PCL computes in double, but the votes go into float bins and the results
  // agree to a cosine similarity above 0.9999 (test/unit/geometry, shot_pcl_test).
  //
  // Every neighbour casts five weighted votes: its own volume and cosine bin, and the adjacent
  // cosine bin, radial shell, elevation volume and azimuth sector (quadrilinear interpolation).
  // Their bins and weights are computed a block of neighbours at a time, without branches (PCL's
  // branches, as selects: a neighbour that PCL does not let vote for an adjacent volume votes 0
  // into its own bin instead); only the scattered additions stay one neighbour at a time. The
  // vector kernel where the CPU has one, the portable loop otherwise: the same values.
  const VoteArrays arrays{dx_.data(), dy_.data(), dz_.data(), nx_.data(), ny_.data(), nz_.data(),
                          distance_.data(), own_.data(), own_weight_.data(), cosine_.data(),
                          cosine_weight_.data(), radial_.data(), radial_weight_.data(),
                          elevation_.data(), elevation_weight_.data(), azimuth_.data(),
                          azimuth_weight_.data()};
  const VoteFrame vote_frame{frame_x, frame_y, frame_z, radius_1_4, radius_1_2, radius_3_4};
  if (best_kernel_ && has_vector_kernel()) {
    vector::shot_vote_bins(arrays, vote_frame, padded_end);
  } else {
    vote_bins_portable(arrays, vote_frame, padded_end);
  }

  // The scattered votes, one neighbour at a time. The arrays are read through local pointers:
  // the compiler cannot tell that the descriptor's stores leave the vectors' own pointers alone,
  // and would reload them at every vote.
  const float* const distance = distance_.data();
  const std::int32_t* const cosine_bin = cosine_.data();
  const float* const cosine_weight = cosine_weight_.data();
  const std::int32_t* const radial_bin = radial_.data();
  const float* const radial_weight = radial_weight_.data();
  const std::int32_t* const elevation_bin = elevation_.data();
  const float* const elevation_weight = elevation_weight_.data();
  const std::int32_t* const azimuth_bin = azimuth_.data();
  const float* const azimuth_weight = azimuth_weight_.data();
  const std::int32_t* const own_bin = own_.data();
  const float* const own_weight = own_weight_.data();
  for (int k = 0; k < count_; ++k) {
    if (distance[k] < 1e-15F) continue;
    descriptor[cosine_bin[k]] += cosine_weight[k];
    descriptor[radial_bin[k]] += radial_weight[k];
    descriptor[elevation_bin[k]] += elevation_weight[k];
    descriptor[azimuth_bin[k]] += azimuth_weight[k];
    descriptor[own_bin[k]] += own_weight[k];
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
