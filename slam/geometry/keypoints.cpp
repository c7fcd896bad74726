#include "rankslam/geometry/keypoints.hpp"
#include "rankslam/core/units.hpp"

#include <algorithm>
#include <bit>
#include <cstdint>
#include <cmath>
#include <utility>

#include "fast_math.hpp"
#include "rankslam/robust/msse.hpp"

namespace rankslam::geometry {

namespace {

// Shells of 2ρ cells searched for the ROS neighbours when the 27 cells around a point do not
// hold them all (sparse, isolated points).
constexpr int kNeighbourRings = 3;

int gross_error_count(int candidates, double fraction) {
  return static_cast<int>(std::ceil(fraction * static_cast<double>(candidates)));
}

}  // namespace

std::string KeypointDetector::configure(const GeometryConfig& config, int max_points,
                                        parallel::ThreadTeam* team) {
  max_points_ = 0;
  team_ = team;
  if (const std::string_view bad = config.validate(); !bad.empty()) {
    return "geometry config: " + std::string(bad) + " is out of range";
  }
  if (max_points < 3) return "geometry: keypoint detector needs room for at least 3 points";
  if (config.ros_neighbours > PointGrid::kMaxNeighbours) {
    return "geometry config: ros_neighbours exceeds " + std::to_string(PointGrid::kMaxNeighbours);
  }
  config_ = config;
  grid_.reserve(max_points);
  workspace_.reserve(max_points);
  orientation_model_ = robust::OrientationModel(max_points);
  normals_.resize(3, max_points);
  saliency_.assign(static_cast<std::size_t>(max_points), 0.0);
  remaining_.assign(static_cast<std::size_t>(max_points), 0);
  next_remaining_.assign(static_cast<std::size_t>(max_points), 0);
  assigned_.assign(static_cast<std::size_t>(max_points), 0);
  const int threads = parallel::team_size(team);
  const std::size_t per_thread = static_cast<std::size_t>(max_points) * static_cast<std::size_t>(threads);
  candidates_.assign(per_thread, 0);
  candidate_ranks_.assign(per_thread, 0);
  for (std::vector<float>* v : {&candidate_x_, &candidate_y_, &candidate_z_, &candidate_d2_}) {
    v->assign(per_thread, 0.0F);
  }
  orientation_team_.reserve(team, config.is3d_hypotheses, robust::OrientationModel::kSampleSize, max_points);
  ranked_.assign(static_cast<std::size_t>(max_points), {0.0F, 0});
  max_points_ = max_points;
  return {};
}

void KeypointDetector::group_orientations(const SampledCloud& cloud) {
  grouped_for_ = nullptr;
  if (!configured() || cloud.size > max_points_ || cloud.size < 3) return;
  group(cloud, nullptr);
  grouped_for_ = &cloud;
}

void KeypointDetector::prepare(KeypointMethod method, const SampledCloud& cloud) {
  prepared_for_ = nullptr;
  if (!configured() || cloud.size > max_points_ || cloud.size < 3) return;
  if (method != KeypointMethod::kRos && method != KeypointMethod::kIs3d) return;
  if (grid_.build(cloud.point_span(), 2.0F * cloud.voxel_leaf_m)) prepared_for_ = &cloud;
}

int KeypointDetector::detect(KeypointMethod method, const SampledCloud& cloud, std::span<int> out,
                             GeometryStatus& status) {
  // A grid prepared for another cloud (or method) is not used; this one is used once.
  const SampledCloud* prepared = std::exchange(prepared_for_, nullptr);
  if (prepared != &cloud || (method != KeypointMethod::kRos && method != KeypointMethod::kIs3d)) {
    prepared = nullptr;
  }
  grid_prepared_ = prepared != nullptr;
  grouped_ = std::exchange(grouped_for_, nullptr) == &cloud && method == KeypointMethod::kIs3d;
  stats_ = KeypointStats{};
  if (!configured()) {
    status = GeometryStatus::kNotConfigured;
    return 0;
  }
  if (cloud.size > max_points_ || static_cast<int>(out.size()) < config_.max_keypoints) {
    status = GeometryStatus::kCapacityExceeded;
    return 0;
  }
  if (cloud.size < 3) {
    status = GeometryStatus::kTooFewPoints;
    return 0;
  }
  int count = 0;
  switch (method) {
    case KeypointMethod::kRos: count = detect_ros(cloud, out, status); break;
    case KeypointMethod::kIs3d: count = detect_is3d(cloud, out, status); break;
    case KeypointMethod::kUniform: count = detect_uniform(cloud, out, status); break;
  }
  if (status == GeometryStatus::kOk && count < 3) status = GeometryStatus::kTooFewKeypoints;
  return status == GeometryStatus::kOk ? count : 0;
}

namespace {

// The 27 cells around a cell, nearest first (the cell itself, then those sharing a face, an
// edge, a corner): scanning near candidates first leaves most far ones rejected at once.
struct CellOffset {
  std::int8_t dx, dy, dz;
  std::int8_t scan_index;  // position in the dx, dy, dz loop order of the scan that ranks ties
};
constexpr std::array<CellOffset, 27> nearest_cells_first() {
  std::array<CellOffset, 27> offsets{};
  int n = 0;
  for (int shell = 0; shell <= 3; ++shell) {
    for (int dx = -1; dx <= 1; ++dx) {
      for (int dy = -1; dy <= 1; ++dy) {
        for (int dz = -1; dz <= 1; ++dz) {
          if ((dx != 0) + (dy != 0) + (dz != 0) != shell) continue;
          offsets[static_cast<std::size_t>(n++)] = {static_cast<std::int8_t>(dx), static_cast<std::int8_t>(dy),
                                                    static_cast<std::int8_t>(dz),
                                                    static_cast<std::int8_t>((dx + 1) * 9 + (dy + 1) * 3 + dz + 1)};
        }
      }
    }
  }
  return offsets;
}
constexpr std::array<CellOffset, 27> kNearestCellsFirst = nearest_cells_first();

}  // namespace

void KeypointDetector::compute_saliency(const SampledCloud& cloud, const std::uint8_t* wanted) {
  // θ_i = (1/N) Σ_j arccos(n_i · n_j)² over the N nearest sampled neighbours (thesis eq. 4.1–4.2).
  // Cells of 2ρ hold a few sampled points each; the 27 cells around a point's cell contain every
  // point within 2ρ of it, which covers the N nearest on a surface, so the candidates are gathered
  // once per cell and shared by its points. A point whose N-th neighbour lies beyond the block
  // falls back to an exact ring search.
  const int n = cloud.size;
  const int k = config_.ros_neighbours;
  const float cell_m = 2.0F * cloud.voxel_leaf_m;
  if (!std::exchange(grid_prepared_, false)) (void)grid_.build(cloud.point_span(), cell_m);
  const auto sorted = grid_.sorted_indices();
  // Cells on whichever thread of the team, each writing the saliency of its own points.
  const auto cells = grid_.cells();
  const auto saliency_of_cells = [&](int first_cell, int end_cell, int thread) {
    const std::ptrdiff_t scratch = static_cast<std::ptrdiff_t>(thread) * max_points_;
    int* candidate_index = candidates_.data() + scratch;
    int* candidate_rank = candidate_ranks_.data() + scratch;
    float* cx = candidate_x_.data() + scratch;
    float* cy = candidate_y_.data() + scratch;
    float* cz = candidate_z_.data() + scratch;
    float* cd2 = candidate_d2_.data() + scratch;
    std::array<int, PointGrid::kMaxNeighbours> neighbours{};
    std::array<float, PointGrid::kMaxNeighbours> distances{};
    std::array<std::uint64_t, PointGrid::kMaxNeighbours> keys{};
    std::array<int, 27> cell_of_scan{};
    std::array<int, 27> first_rank_of_scan{};
    for (int cell_index = first_cell; cell_index < end_cell; ++cell_index) {
      const PointGrid::Cell& cell = cells[static_cast<std::size_t>(cell_index)];
      if (wanted != nullptr) {
        bool any = false;
        for (int m = cell.start; m < cell.start + cell.count && !any; ++m) {
          any = wanted[static_cast<std::size_t>(sorted[static_cast<std::size_t>(m)])] != 0;
        }
        if (!any) continue;
      }
      // The candidates' ranks are their positions in the dx, dy, dz scan of the 27 cells; they
      // are gathered nearest cells first.
      int scanned = 0;
      for (int s = 0; s < 27; ++s) {
        const int c = grid_.find_cell(cell.x + s / 9 - 1, cell.y + (s / 3) % 3 - 1, cell.z + s % 3 - 1);
        cell_of_scan[static_cast<std::size_t>(s)] = c;
        first_rank_of_scan[static_cast<std::size_t>(s)] = scanned;
        if (c >= 0) scanned += cells[static_cast<std::size_t>(c)].count;
      }
      int candidates = 0;
      for (const CellOffset& offset : kNearestCellsFirst) {
        const auto s = static_cast<std::size_t>(offset.scan_index);
        const int c = cell_of_scan[s];
        if (c < 0) continue;
        const PointGrid::Cell& other = cells[static_cast<std::size_t>(c)];
        for (int m = 0; m < other.count; ++m) {
          const int j = sorted[static_cast<std::size_t>(other.start + m)];
          const Eigen::Vector3f& q = cloud.points[static_cast<std::size_t>(j)];
          candidate_index[candidates] = j;
          candidate_rank[candidates] = first_rank_of_scan[s] + m;
          cx[candidates] = q.x();
          cy[candidates] = q.y();
          cz[candidates] = q.z();
          ++candidates;
        }
      }
      const Eigen::Vector3f lo = Eigen::Vector3f(static_cast<float>(cell.x - 1), static_cast<float>(cell.y - 1),
                                                 static_cast<float>(cell.z - 1)) * cell_m;
      const Eigen::Vector3f hi = Eigen::Vector3f(static_cast<float>(cell.x + 2), static_cast<float>(cell.y + 2),
                                                 static_cast<float>(cell.z + 2)) * cell_m;
      for (int m = cell.start; m < cell.start + cell.count; ++m) {
        const int i = sorted[static_cast<std::size_t>(m)];
        if (wanted != nullptr && wanted[static_cast<std::size_t>(i)] == 0) continue;
        const Eigen::Vector3f& p = cloud.points[static_cast<std::size_t>(i)];
        // Squared distances of all candidates at once, each as (q − p).squaredNorm() sums it:
        // x² + (y² + z²).
        {
          using Values = Eigen::Map<Eigen::ArrayXf>;
          const Values x(cx, candidates), y(cy, candidates), z(cz, candidates);
          Values(cd2, candidates) = (x - p.x()).square() + ((y - p.y()).square() + (z - p.z()).square());
        }
        // The k least (squared distance, rank) pairs: with the ranks of the 27 cells' scan, the
        // same neighbours, in the same order, as keeping the k nearest over that scan (which keeps
        // the first-scanned of equal distances). Each pair is one integer: a non-negative float
        // orders as its bits, so (bits << 32 | rank) orders as the pair, in one compare.
        int found = 0;
        for (int c = 0; c < candidates; ++c) {
          const std::uint64_t key = (static_cast<std::uint64_t>(std::bit_cast<std::uint32_t>(cd2[c])) << 32) |
                                    static_cast<std::uint32_t>(candidate_rank[c]);
          if (found == k && key >= keys[static_cast<std::size_t>(k - 1)]) continue;
          const int j = candidate_index[c];
          if (j == i) continue;
          int pos = found < k ? found++ : k - 1;
          while (pos > 0 && key < keys[static_cast<std::size_t>(pos - 1)]) {
            keys[static_cast<std::size_t>(pos)] = keys[static_cast<std::size_t>(pos - 1)];
            neighbours[static_cast<std::size_t>(pos)] = neighbours[static_cast<std::size_t>(pos - 1)];
            --pos;
          }
          keys[static_cast<std::size_t>(pos)] = key;
          neighbours[static_cast<std::size_t>(pos)] = j;
        }
        for (int q = 0; q < found; ++q) {
          distances[static_cast<std::size_t>(q)] =
              std::bit_cast<float>(static_cast<std::uint32_t>(keys[static_cast<std::size_t>(q)] >> 32));
        }
        const float margin = std::min((p - lo).minCoeff(), (hi - p).minCoeff());
        if (found < k || distances[static_cast<std::size_t>(k - 1)] > margin * margin) {
          found = grid_.nearest(p, k, i, kNeighbourRings, neighbours.data(), distances.data());
        }
        const Eigen::Vector3f& normal = cloud.normals[static_cast<std::size_t>(i)];
        float sum = 0.0F;
        for (int q = 0; q < found; ++q) {
          const float angle = detail::fast_acos(
              normal.dot(cloud.normals[static_cast<std::size_t>(neighbours[static_cast<std::size_t>(q)])]));
          sum += angle * angle;
        }
        saliency_[static_cast<std::size_t>(i)] = found > 0 ? static_cast<double>(sum) / found : 0.0;
      }
    }
  };
  constexpr int kCellsPerChunk = 32;
  const auto cell_count = static_cast<int>(cells.size());
  parallel::for_chunks(team_, cell_count, kCellsPerChunk, saliency_of_cells);
  saliency_count_ = n;
}

int KeypointDetector::detect_ros(const SampledCloud& cloud, std::span<int> out,
                                 GeometryStatus& status) {
  const int n = cloud.size;
  compute_saliency(cloud);
  robust::ScalarModel model(robust::ScalarKind::kSquaredResidual);
  if (model.set_values(saliency()) != robust::RobustStatus::kOk) {
    status = GeometryStatus::kTooFewPoints;
    return 0;
  }
  robust::MsseConfig msse;
  msse.min_inlier_fraction = config_.ros_min_inlier_fraction;
  msse.refit = false;  // nothing to refit: the values are the residuals
  const auto result = robust::estimate_msse(model, msse, workspace_);
  if (!result.ok()) {
    status = GeometryStatus::kTooFewPoints;
    return 0;
  }
  // Group 2 (past k*) in ascending θ; its largest values are gross errors (thesis §4.3.3).
  const int k_star = result.inlier_count;
  const int group2 = n - k_star;
  const int usable = std::max(0, group2 - gross_error_count(group2, config_.gross_error_fraction));
  const int count = std::min(usable, config_.max_keypoints);
  // RosSelection: the most salient of the usable range (its top end, downwards) or, as the
  // thesis words it, its first values past the transition.
  const bool most_salient = config_.ros_selection == RosSelection::kMostSalient;
  for (int i = 0; i < count; ++i) {
    const int rank = most_salient ? k_star + usable - 1 - i : k_star + i;
    out[static_cast<std::size_t>(i)] = result.ordered[static_cast<std::size_t>(rank)];
  }
  stats_.candidates = group2;
  stats_.transition = k_star;
  status = GeometryStatus::kOk;
  return count;
}

void KeypointDetector::group(const SampledCloud& cloud,
                             robust::MsseTeamScratch<robust::OrientationModel::Params>* shared) {
  const int n = cloud.size;
  grouping_ = KeypointStats{};
  int remaining = n;
  for (int i = 0; i < n; ++i) {
    remaining_[static_cast<std::size_t>(i)] = i;
    assigned_[static_cast<std::size_t>(i)] = 0;
  }
  const int min_group = static_cast<int>(std::ceil(config_.is3d_min_group_fraction * n));
  robust::MsseConfig msse;
  msse.hypotheses = config_.is3d_hypotheses;
  msse.min_inlier_fraction = config_.is3d_min_inlier_fraction;
  msse.refine_iterations = 0;  // the thesis' single refit on the group
  const double max_scale_rad = deg_to_rad(config_.is3d_max_group_scale_deg);
  const int max_orientations =
      std::min(config_.is3d_max_orientations, KeypointStats::kMaxOrientations);
  while (grouping_.orientations < max_orientations && remaining >= min_group && remaining >= 3) {
    for (int k = 0; k < remaining; ++k) {
      normals_.col(k) =
          cloud.normals[static_cast<std::size_t>(remaining_[static_cast<std::size_t>(k)])].cast<double>();
    }
    if (orientation_model_.set_normals(normals_.leftCols(remaining)) != robust::RobustStatus::kOk) {
      break;
    }
    msse.seed = static_cast<std::uint64_t>(config_.seed) * 0x9e3779b97f4a7c15ULL +
                static_cast<std::uint64_t>(grouping_.orientations);
    const auto result = robust::estimate_msse(orientation_model_, msse, workspace_, {},
                                              robust::AcceptAllHypotheses{}, shared);
    if (!result.ok() || result.inlier_count < min_group || result.scale > max_scale_rad) break;
    const int o = grouping_.orientations++;
    grouping_.orientation[static_cast<std::size_t>(o)] = result.model;
    grouping_.group_size[static_cast<std::size_t>(o)] = result.inlier_count;
    int next = 0;
    for (int k = 0; k < remaining; ++k) {
      const int index = remaining_[static_cast<std::size_t>(k)];
      if (result.inlier_mask[static_cast<std::size_t>(k)] != 0) {
        assigned_[static_cast<std::size_t>(index)] = 1;
      } else {
        next_remaining_[static_cast<std::size_t>(next++)] = index;
      }
    }
    std::swap(remaining_, next_remaining_);
    remaining = next;
  }
  grouping_.candidates = remaining;
  remaining_count_ = remaining;
}

int KeypointDetector::detect_is3d(const SampledCloud& cloud, std::span<int> out,
                                  GeometryStatus& status) {
  const int n = cloud.size;
  if (!grouped_) group(cloud, &orientation_team_);
  grouped_ = false;
  stats_ = grouping_;
  const int remaining = remaining_count_;

  // Features are the points in no dominant group; when more than max_keypoints remain, they are
  // ranked (Is3dRanking) and the first max_keypoints kept.
  const bool by_saliency = config_.is3d_ranking == Is3dRanking::kLocalSaliency || stats_.orientations == 0;
  if (by_saliency) {
    // Saliency of the candidates only (assigned_ marks the grouped points).
    for (int i = 0; i < n; ++i) assigned_[static_cast<std::size_t>(i)] ^= 1;
    compute_saliency(cloud, assigned_.data());
  }
  for (int k = 0; k < remaining; ++k) {
    const int index = remaining_[static_cast<std::size_t>(k)];
    float score = 0.0F;
    if (by_saliency) {
      score = static_cast<float>(saliency_[static_cast<std::size_t>(index)]);
    } else {
      float best_cos = -1.0F;
      const Eigen::Vector3f& normal = cloud.normals[static_cast<std::size_t>(index)];
      for (int o = 0; o < stats_.orientations; ++o) {
        best_cos = std::max(best_cos, normal.dot(stats_.orientation[static_cast<std::size_t>(o)].cast<float>()));
      }
      score = std::acos(std::clamp(best_cos, -1.0F, 1.0F));
    }
    ranked_[static_cast<std::size_t>(k)] = {score, index};
  }
  const auto begin = ranked_.begin();
  const auto end = begin + remaining;
  int first = 0;
  int usable = remaining;
  // Only the ranks up to the last kept one are needed: the orders below are total (ties by
  // index), so a partial sort gives those ranks exactly as a full sort would.
  if (by_saliency || config_.is3d_ranking == Is3dRanking::kFarthestFromOrientations) {
    // Descending score, ties by index; is3d_gross_error_fraction of the largest are dropped
    // (none by default: see the parameter).
    first = std::min(remaining, gross_error_count(remaining, config_.is3d_gross_error_fraction));
    usable = remaining - first;
    const int ranked = std::min(remaining, first + config_.max_keypoints);
    std::partial_sort(begin, begin + ranked, end, [](const auto& a, const auto& b) {
      return a.first > b.first || (a.first == b.first && a.second < b.second);
    });
  } else {
    const int ranked = std::min(remaining, config_.max_keypoints);
    std::partial_sort(begin, begin + ranked, end, [](const auto& a, const auto& b) {
      return a.first < b.first || (a.first == b.first && a.second < b.second);
    });
  }
  const int count = std::min(usable, config_.max_keypoints);
  for (int i = 0; i < count; ++i) {
    out[static_cast<std::size_t>(i)] = ranked_[static_cast<std::size_t>(first + i)].second;
  }
  status = GeometryStatus::kOk;
  return count;
}

int KeypointDetector::detect_uniform(const SampledCloud& cloud, std::span<int> out,
                                     GeometryStatus& status) {
  // One point per cell of a cubic grid whose edge gives about max_keypoints occupied cells: the
  // point nearest the cell centre (as PCL's UniformSampling). The edge is found by bisection on
  // the occupied-cell count, largest count ≤ max_keypoints.
  const int target = config_.max_keypoints;
  const auto points = cloud.point_span();
  float lo = 0.0F;  // cell edge giving more than target cells (0: unknown)
  float hi = 0.0F;  // cell edge giving at most target cells
  float cell = cloud.voxel_leaf_m *
               std::sqrt(static_cast<float>(cloud.size) / static_cast<float>(std::max(target, 1)));
  cell = std::max(cell, 1e-4F);
  for (int iteration = 0; iteration < 24; ++iteration) {
    (void)grid_.build(points, cell);
    const int cells = static_cast<int>(grid_.cells().size());
    if (cells <= target) {
      hi = cell;
      if (cells >= target - std::max(1, target / 50)) break;  // within 2 %
    } else {
      lo = cell;
    }
    if (hi > 0.0F && lo > 0.0F) {
      if (hi - lo < 1e-4F * hi) break;
      cell = 0.5F * (lo + hi);
    } else {
      cell = hi > 0.0F ? 0.7F * hi : 1.4F * lo;
    }
  }
  if (!(hi > 0.0F)) {
    status = GeometryStatus::kTooFewKeypoints;
    return 0;
  }
  if (grid_.cell_m() != hi) (void)grid_.build(points, hi);
  const auto cells = grid_.cells();
  const auto sorted = grid_.sorted_indices();
  int count = 0;
  for (const PointGrid::Cell& c : cells) {
    const Eigen::Vector3f centre =
        (Eigen::Vector3f(static_cast<float>(c.x), static_cast<float>(c.y), static_cast<float>(c.z)) +
         Eigen::Vector3f::Constant(0.5F)) * hi;
    int best = -1;
    float best_d2 = 0.0F;
    for (int k = c.start; k < c.start + c.count; ++k) {
      const int i = sorted[static_cast<std::size_t>(k)];
      const float d2 = (points[static_cast<std::size_t>(i)] - centre).squaredNorm();
      if (best < 0 || d2 < best_d2) {
        best = i;
        best_d2 = d2;
      }
    }
    if (count < target) out[static_cast<std::size_t>(count++)] = best;
  }
  stats_.candidates = static_cast<int>(cells.size());
  stats_.uniform_cell_m = hi;
  status = GeometryStatus::kOk;
  return count;
}

}  // namespace rankslam::geometry
