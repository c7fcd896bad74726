#include "rankslam/slam/map_builder.hpp"

namespace rankslam::slam {

MapBuilder::MapBuilder(const SlamConfig& config, const camera::DepthCameraModel& camera)
    : config_(config),
      camera_(camera),
      map_(config.map.voxel_m, static_cast<std::size_t>(config.map.max_points)),
      sampler_(static_cast<std::mt19937::result_type>(config.seed)) {}

void MapBuilder::add_keyframe(const hal::RgbdFrame& frame, FrameImages& images, const Eigen::Isometry3d& T_world_cam,
                              StoredKeyframe* stored) {
  const Eigen::Isometry3f T = T_world_cam.cast<float>();
  std::uniform_int_distribution<int> column(0, camera_.width() - 1);
  std::uniform_int_distribution<int> row(0, camera_.height() - 1);
  const auto max_depth_m = static_cast<float>(config_.max_depth_m);
  const bool colour = images.has_colour();
  const cv::Mat* grey = colour ? nullptr : images.feature_image(frame, ImageSource::kInfrared);
  if (!colour && grey == nullptr) return;
  // Attempts are capped so a frame with little depth cannot stall the loop.
  int added = 0;
  for (int attempt = 0; attempt < config_.map.points_per_keyframe * 4 && added < config_.map.points_per_keyframe;
       ++attempt) {
    const int u = column(sampler_);
    const int v = row(sampler_);
    const unsigned short raw = frame.depth.at<unsigned short>(v, u);
    if (raw == 0) continue;
    const float z_m = camera_.metres(raw);
    if (z_m > max_depth_m) continue;
    const Eigen::Vector3f point_cam = camera_.back_project(u, v, z_m);
    const Eigen::Vector3f point = T * point_cam;
    KeyframePoint coloured{point_cam, 0, 0, 0};
    if (colour) {
      const cv::Vec3b bgr = frame.rgb.at<cv::Vec3b>(v, u);
      coloured.blue = bgr[0];
      coloured.green = bgr[1];
      coloured.red = bgr[2];
    } else {
      const unsigned char level = grey->at<unsigned char>(v, u);
      coloured.blue = coloured.green = coloured.red = level;
    }
    map_.insert(point, coloured.blue, coloured.green, coloured.red);
    if (stored != nullptr && stored->point_count < static_cast<int>(stored->points.size())) {
      stored->points[static_cast<std::size_t>(stored->point_count++)] = coloured;
    }
    ++added;
  }
}

void MapBuilder::rebuild(const KeyframeStore& store) {
  map_.clear();
  for (int i = 0; i < store.capacity(); ++i) {
    const StoredKeyframe& keyframe = store.slot(i);
    if (!keyframe.used) continue;
    const Eigen::Isometry3f T = keyframe.T_world_cam.cast<float>();
    for (int p = 0; p < keyframe.point_count; ++p) {
      const KeyframePoint& point = keyframe.points[static_cast<std::size_t>(p)];
      map_.insert(T * point.point_cam, point.blue, point.green, point.red);
    }
  }
}

}  // namespace rankslam::slam
