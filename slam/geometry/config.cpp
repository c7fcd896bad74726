#include "rankslam/geometry/config.hpp"

#include <cmath>
#include <type_traits>

namespace rankslam::geometry {

std::string_view GeometryConfig::validate() const {
  // Ranges live once, in visit_parameters(); walk a copy since visiting hands out references.
  GeometryConfig copy = *this;
  std::string_view bad;
  copy.visit_parameters([&bad](std::string_view name, auto& field, auto min, auto max,
                               std::string_view /*unit*/, std::string_view /*doc*/) {
    if (!bad.empty()) return;
    const auto value = static_cast<double>(field);
    if (!std::isfinite(value) || value < static_cast<double>(min) ||
        value > static_cast<double>(max)) {
      bad = name;
    }
  });
  if (!bad.empty()) return bad;
  if (!std::isfinite(max_depth_m)) return "max_depth_m";
  if (!(min_depth_m >= 0.0 && min_depth_m < max_depth_m)) return "min_depth_m";
  if (msse_hypotheses < 10) return "msse_hypotheses";
  if (seed < 0) return "seed";
  if (min_voxel_leaf_m > max_voxel_leaf_m) return "min_voxel_leaf_m";
  switch (keypoint_method) {
    case KeypointMethod::kIs3d:
    case KeypointMethod::kRos:
    case KeypointMethod::kUniform: break;
    default: return "keypoint_method";
  }
  switch (is3d_ranking) {
    case Is3dRanking::kLocalSaliency:
    case Is3dRanking::kFarthestFromOrientations:
    case Is3dRanking::kNearestToOrientations: break;
    default: return "is3d_ranking";
  }
  switch (ros_selection) {
    case RosSelection::kMostSalient:
    case RosSelection::kFirstPastTransition: break;
    default: return "ros_selection";
  }
  return {};
}

}  // namespace rankslam::geometry
