#include "repeatability.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>

#include "geometry_bench_support.hpp"
#include "rankslam/geometry/point_grid.hpp"
#include "rankslam/camera/depth_camera.hpp"

#ifdef RANKSLAM_HAVE_PCL
#include <pcl/keypoints/iss_3d.h>
#include <pcl/point_types.h>
#include <pcl/search/kdtree.h>
#endif

namespace rankslam::geometry::bench {

namespace {

constexpr double kRadToDeg = 180.0 / 3.14159265358979323846;

// Nearest-neighbour queries over a small point set (the target's cloud or keypoints).
class NearestIndex {
 public:
  explicit NearestIndex(const std::vector<Eigen::Vector3f>& points, float cell_m)
      : points_(points), grid_(static_cast<int>(std::max<std::size_t>(points.size(), 1))) {
    (void)grid_.build(points_, cell_m);
  }
  /// Distance to the nearest point, or +inf when there is none within 4 cells.
  [[nodiscard]] float nearest_m(const Eigen::Vector3f& q) const {
    int index = 0;
    float d2 = 0.0F;
    if (points_.empty() || grid_.nearest(q, 1, -1, 4, &index, &d2) == 0) {
      return std::numeric_limits<float>::infinity();
    }
    return std::sqrt(d2);
  }

 private:
  const std::vector<Eigen::Vector3f>& points_;
  PointGrid grid_;
};

float mean_nearest_distance(const std::vector<Eigen::Vector3f>& cloud, float cell_m) {
  if (cloud.size() < 2) return 0.0F;
  PointGrid grid(static_cast<int>(cloud.size()));
  (void)grid.build(cloud, cell_m);
  double sum = 0.0;
  int count = 0;
  for (std::size_t i = 0; i < cloud.size(); ++i) {
    int index = 0;
    float d2 = 0.0F;
    if (grid.nearest(cloud[i], 1, static_cast<int>(i), 8, &index, &d2) == 1) {
      sum += std::sqrt(static_cast<double>(d2));
      ++count;
    }
  }
  return count > 0 ? static_cast<float>(sum / count) : 0.0F;
}

#ifdef RANKSLAM_HAVE_PCL
// PCL's ISS (Zhong 2009) with the parameters of PCL's documentation, scaled by the cloud's
// resolution: salient radius 6×, non-maximum radius 4×, eigenvalue ratios 0.975, 5 neighbours.
std::vector<Eigen::Vector3f> iss_keypoints(const std::vector<Eigen::Vector3f>& cloud,
                                           float resolution_m) {
  pcl::PointCloud<pcl::PointXYZ>::Ptr input(new pcl::PointCloud<pcl::PointXYZ>);
  input->reserve(cloud.size());
  for (const Eigen::Vector3f& p : cloud) input->push_back(pcl::PointXYZ(p.x(), p.y(), p.z()));
  pcl::search::KdTree<pcl::PointXYZ>::Ptr tree(new pcl::search::KdTree<pcl::PointXYZ>);
  pcl::ISSKeypoint3D<pcl::PointXYZ, pcl::PointXYZ> iss;
  iss.setSearchMethod(tree);
  iss.setSalientRadius(6.0 * static_cast<double>(resolution_m));
  iss.setNonMaxRadius(4.0 * static_cast<double>(resolution_m));
  iss.setThreshold21(0.975);
  iss.setThreshold32(0.975);
  iss.setMinNeighbors(5);
  iss.setNumberOfThreads(1);
  iss.setInputCloud(input);
  pcl::PointCloud<pcl::PointXYZ> keypoints;
  iss.compute(keypoints);
  std::vector<Eigen::Vector3f> out;
  out.reserve(keypoints.size());
  for (const pcl::PointXYZ& p : keypoints) out.emplace_back(p.x, p.y, p.z);
  return out;
}
#endif

struct Accumulator {
  std::array<double, kMethodCount> sum{};
  std::array<int, kMethodCount> valid{};
  std::array<double, kMethodCount> keypoints{};
  int pairs = 0;
  double angle_sum_deg = 0.0;

  std::vector<std::array<double, kMethodCount>> per_pair;

  void add(const FrameKeypoints& source, const FrameKeypoints& target,
           const Eigen::Isometry3d& T_target_source) {
    std::array<double, kMethodCount>& pair = per_pair.emplace_back();
    pair.fill(-1.0);
    for (int m = 0; m < kMethodCount; ++m) {
      if (m == kMethodIss && !have_iss()) continue;
      const double r = relative_repeatability(source, target, T_target_source, m);
      pair[static_cast<std::size_t>(m)] = r;
      if (r >= 0.0) {
        sum[static_cast<std::size_t>(m)] += r;
        ++valid[static_cast<std::size_t>(m)];
      }
      keypoints[static_cast<std::size_t>(m)] +=
          0.5 * static_cast<double>(source.keypoints[static_cast<std::size_t>(m)].size() +
                                    target.keypoints[static_cast<std::size_t>(m)].size());
    }
    ++pairs;
    angle_sum_deg += Eigen::AngleAxisd(T_target_source.rotation()).angle() * kRadToDeg;
  }

  [[nodiscard]] RepeatabilityRow row(const std::string& set, double nominal_deg) const {
    RepeatabilityRow r;
    r.set = set;
    r.misalignment_deg = nominal_deg >= 0.0 ? nominal_deg : (pairs > 0 ? angle_sum_deg / pairs : 0.0);
    r.pairs = pairs;
    r.per_pair = per_pair;
    for (std::size_t m = 0; m < kMethodCount; ++m) {
      r.repeatability[m] = valid[m] > 0 ? sum[m] / valid[m] : -1.0;
      r.keypoints[m] = pairs > 0 ? keypoints[m] / pairs : 0.0;
    }
    return r;
  }
};

}  // namespace

const char* method_name(int method) {
  switch (method) {
    case kMethodIs3d: return "IS3D";
    case kMethodRos: return "ROS";
    case kMethodUniform: return "uniform";
    case kMethodIss: return "ISS (PCL)";
    default: return "?";
  }
}

bool have_iss() {
#ifdef RANKSLAM_HAVE_PCL
  return true;
#else
  return false;
#endif
}

std::string extract_frame_keypoints(const cv::Mat& depth, GeometricFrontend& frontend,
                                    GeometricFeatures& features, FrameKeypoints& out) {
  out = FrameKeypoints{};
  const std::array<KeypointMethod, 3> methods = {KeypointMethod::kIs3d, KeypointMethod::kRos,
                                                 KeypointMethod::kUniform};
  for (std::size_t m = 0; m < methods.size(); ++m) {
    const GeometryStatus status = frontend.extract(depth, methods[m], features);
    const SampledCloud& cloud = frontend.last_cloud();
    if (m == 0) {
      if (cloud.size < 3) return "extraction failed: " + std::string(to_string(status));
      out.cloud.assign(cloud.points.begin(), cloud.points.begin() + cloud.size);
      out.resolution_m = mean_nearest_distance(out.cloud, cloud.voxel_leaf_m);
    }
    // Keypoints as detected (before descriptor failures), so each detector is judged alone.
    for (const int index : frontend.last_keypoints()) {
      out.keypoints[m].push_back(cloud.points[static_cast<std::size_t>(index)]);
    }
  }
#ifdef RANKSLAM_HAVE_PCL
  out.keypoints[kMethodIss] = iss_keypoints(out.cloud, out.resolution_m);
#endif
  return {};
}

double relative_repeatability(const FrameKeypoints& source, const FrameKeypoints& target,
                              const Eigen::Isometry3d& T_target_source, int method,
                              int* overlapping) {
  const float resolution = source.resolution_m;
  if (overlapping != nullptr) *overlapping = 0;
  if (!(resolution > 0.0F)) return -1.0;
  const auto& keypoints = source.keypoints[static_cast<std::size_t>(method)];
  const NearestIndex target_cloud(target.cloud, 2.0F * resolution);
  const NearestIndex target_keypoints(target.keypoints[static_cast<std::size_t>(method)],
                                      2.0F * resolution);
  const Eigen::Isometry3f T = T_target_source.cast<float>();
  int overlap = 0;
  int repeatable = 0;
  for (const Eigen::Vector3f& k : keypoints) {
    const Eigen::Vector3f moved = T * k;
    if (target_cloud.nearest_m(moved) > resolution) continue;
    ++overlap;
    if (target_keypoints.nearest_m(moved) < 2.0F * resolution) ++repeatable;
  }
  if (overlapping != nullptr) *overlapping = overlap;
  return overlap > 0 ? static_cast<double>(repeatable) / overlap : -1.0;
}

std::string run_repeatability(const RepeatabilityOptions& options,
                              std::vector<RepeatabilityRow>& rows) {
  rows.clear();
  GeometricFrontend frontend;
  GeometricFeatures features;
  bool configured = false;
  const auto configure = [&](const hal::Calibration& calibration) -> std::string {
    if (configured) return {};
    const camera::DepthCameraModel camera(calibration.rgb, calibration.depth_scale);
    if (std::string error = frontend.configure(camera, options.config); !error.empty()) return error;
    features = frontend.make_features();
    configured = true;
    return {};
  };

  for (const std::string& scene : options.sim_scenes) {
    std::filesystem::path root_a;
    std::filesystem::path root_b;
    if (std::string e = simulated_recording(scene, options.sim_frames, 1, root_a); !e.empty()) return e;
    if (std::string e = simulated_recording(scene, options.sim_frames, 2, root_b); !e.empty()) return e;
    DepthSequence a;
    if (std::string e = load_depth_sequence(root_a, a); !e.empty()) return e;
    configured = false;
    if (std::string e = configure(a.calibration); !e.empty()) return e;
    const int n = static_cast<int>(a.depth.size());
    std::vector<FrameKeypoints> keypoints(static_cast<std::size_t>(n));
    std::vector<bool> done(static_cast<std::size_t>(n), false);
    const auto frame = [&](int i) -> const FrameKeypoints& {
      if (!done[static_cast<std::size_t>(i)]) {
        (void)extract_frame_keypoints(a.depth[static_cast<std::size_t>(i)], frontend, features,
                                      keypoints[static_cast<std::size_t>(i)]);
        done[static_cast<std::size_t>(i)] = true;
      }
      return keypoints[static_cast<std::size_t>(i)];
    };

    // 0°: the same frame under independent sensor noise (the second seed's recording).
    {
      DepthSequence b;
      if (std::string e = load_depth_sequence(root_b, b); !e.empty()) return e;
      Accumulator acc;
      const int step = std::max(1, n / std::max(options.pairs_per_angle, 1));
      for (int i = 0; i < n && acc.pairs < options.pairs_per_angle; i += step) {
        FrameKeypoints other;
        if (!extract_frame_keypoints(b.depth[static_cast<std::size_t>(i)], frontend, features, other)
                 .empty()) {
          continue;
        }
        acc.add(frame(i), other, Eigen::Isometry3d::Identity());
      }
      rows.push_back(acc.row("sim " + scene, 0.0));
    }
    // 5°, 15°, 20°: frame pairs of one recording.
    for (const double angle : {5.0, 15.0, 20.0}) {
      struct Candidate {
        int i;
        int j;
        double translation_m;
      };
      std::vector<Candidate> candidates;
      for (int i = 0; i < n; ++i) {
        for (int j = i + 1; j < n; ++j) {
          if (!a.T_world_cam[static_cast<std::size_t>(i)] || !a.T_world_cam[static_cast<std::size_t>(j)]) continue;
          const Eigen::Isometry3d T_i_j =
              a.T_world_cam[static_cast<std::size_t>(i)]->inverse() * *a.T_world_cam[static_cast<std::size_t>(j)];
          const double deg = Eigen::AngleAxisd(T_i_j.rotation()).angle() * kRadToDeg;
          if (std::abs(deg - angle) <= 1.0) candidates.push_back({i, j, T_i_j.translation().norm()});
        }
      }
      std::sort(candidates.begin(), candidates.end(),
                [](const Candidate& x, const Candidate& y) { return x.translation_m < y.translation_m; });
      Accumulator acc;
      std::vector<int> used;
      for (const Candidate& c : candidates) {
        if (acc.pairs >= options.pairs_per_angle) break;
        // Distinct pairs: no source frame within 5 frames of one already used.
        if (std::any_of(used.begin(), used.end(), [&](int u) { return std::abs(u - c.i) < 5; })) continue;
        used.push_back(c.i);
        const Eigen::Isometry3d T_target_source =
            a.T_world_cam[static_cast<std::size_t>(c.j)]->inverse() * *a.T_world_cam[static_cast<std::size_t>(c.i)];
        acc.add(frame(c.i), frame(c.j), T_target_source);
      }
      rows.push_back(acc.row("sim " + scene, angle));
    }
  }

  for (const std::string& name : options.real_recordings) {
    const std::filesystem::path root = shared_recording(name);
    if (root.empty()) continue;
    DepthSequence a;
    if (std::string e = load_depth_sequence(root, a); !e.empty()) return e;
    configured = false;
    if (std::string e = configure(a.calibration); !e.empty()) return e;
    const int n = static_cast<int>(a.depth.size());
    std::vector<FrameKeypoints> keypoints(static_cast<std::size_t>(n));
    for (int i = 0; i < n; ++i) {
      if (!extract_frame_keypoints(a.depth[static_cast<std::size_t>(i)], frontend, features,
                                   keypoints[static_cast<std::size_t>(i)])
               .empty()) {
        keypoints[static_cast<std::size_t>(i)] = FrameKeypoints{};
      }
    }
    // Pairs up to 30 frames (1 s) apart, binned by their ground-truth rotation.
    constexpr std::array<double, 5> kBins = {0.0, 5.0, 10.0, 15.0, 20.0};
    std::array<Accumulator, kBins.size()> bins{};
    for (int i = 0; i < n; ++i) {
      for (int j = i + 1; j < n && j <= i + 30; ++j) {
        if (!a.T_world_cam[static_cast<std::size_t>(i)] || !a.T_world_cam[static_cast<std::size_t>(j)]) continue;
        if (keypoints[static_cast<std::size_t>(i)].cloud.empty() ||
            keypoints[static_cast<std::size_t>(j)].cloud.empty()) {
          continue;
        }
        const Eigen::Isometry3d T_target_source =
            a.T_world_cam[static_cast<std::size_t>(j)]->inverse() * *a.T_world_cam[static_cast<std::size_t>(i)];
        const double deg = Eigen::AngleAxisd(T_target_source.rotation()).angle() * kRadToDeg;
        for (std::size_t b = 0; b < kBins.size(); ++b) {
          if (std::abs(deg - kBins[b]) <= 2.5 && bins[b].pairs < 40) {
            bins[b].add(keypoints[static_cast<std::size_t>(i)], keypoints[static_cast<std::size_t>(j)],
                        T_target_source);
          }
        }
      }
    }
    for (const Accumulator& acc : bins) {
      if (acc.pairs > 0) rows.push_back(acc.row(name, -1.0));
    }
  }
  return {};
}

PairedLead paired_lead(const RepeatabilityRow& row, int method, int other) {
  PairedLead lead;
  double sum = 0.0;
  double sum_sq = 0.0;
  for (const auto& pair : row.per_pair) {
    const double a = pair[static_cast<std::size_t>(method)];
    const double b = pair[static_cast<std::size_t>(other)];
    if (a < 0.0 || b < 0.0) continue;
    const double d = 100.0 * (a - b);
    sum += d;
    sum_sq += d * d;
    ++lead.pairs;
  }
  if (lead.pairs == 0) return lead;
  const double n = lead.pairs;
  lead.mean_points = sum / n;
  if (lead.pairs > 1) {
    const double variance = std::max(0.0, (sum_sq - n * lead.mean_points * lead.mean_points) / (n - 1.0));
    lead.standard_error_points = std::sqrt(variance / n);
  }
  return lead;
}

std::string format_repeatability_table(const std::vector<RepeatabilityRow>& rows) {
  std::string out;
  char line[256];
  std::snprintf(line, sizeof line, "%-18s %9s %5s", "pairs", "rotation", "n");
  out += line;
  for (int m = 0; m < kMethodCount; ++m) {
    std::snprintf(line, sizeof line, " %17s", method_name(m));
    out += line;
  }
  out += "\n";
  for (const RepeatabilityRow& row : rows) {
    std::snprintf(line, sizeof line, "%-18s %8.1f° %5d", row.set.c_str(), row.misalignment_deg, row.pairs);
    out += line;
    for (std::size_t m = 0; m < kMethodCount; ++m) {
      if (row.repeatability[m] < 0.0) {
        std::snprintf(line, sizeof line, " %17s", "n/a");
      } else {
        std::snprintf(line, sizeof line, "   %5.1f %% (%4.0f kp)", 100.0 * row.repeatability[m], row.keypoints[m]);
      }
      out += line;
    }
    out += "\n";
  }
  constexpr std::array<std::array<int, 2>, 3> kLeads = {
      {{kMethodIs3d, kMethodRos}, {kMethodRos, kMethodUniform}, {kMethodIs3d, kMethodIss}}};
  std::snprintf(line, sizeof line, "\npaired lead, points (mean ± standard error over the pairs)\n%-18s %9s", "pairs",
                "rotation");
  out += line;
  for (const auto& lead : kLeads) {
    const std::string name = std::string(method_name(lead[0])) + " - " + method_name(lead[1]);
    std::snprintf(line, sizeof line, " %21s", name.c_str());
    out += line;
  }
  out += "\n";
  for (const RepeatabilityRow& row : rows) {
    std::snprintf(line, sizeof line, "%-18s %8.1f°", row.set.c_str(), row.misalignment_deg);
    out += line;
    for (const auto& lead : kLeads) {
      const PairedLead l = paired_lead(row, lead[0], lead[1]);
      if (l.pairs == 0) {
        std::snprintf(line, sizeof line, " %21s", "n/a");
      } else {
        std::snprintf(line, sizeof line, "         %+6.1f ± %4.1f", l.mean_points, l.standard_error_points);
      }
      out += line;
    }
    out += "\n";
  }
  return out;
}

}  // namespace rankslam::geometry::bench
