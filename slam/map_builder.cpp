#include "rankslam/slam/map_builder.hpp"

#include <algorithm>

namespace rankslam::slam {

MapBuilder::MapBuilder(const SlamConfig& config, const camera::DepthCameraModel& camera)
    : config_(config),
      camera_(camera),
      map_(config.map.voxel_m, capacity(config)),
      sampler_(static_cast<std::mt19937::result_type>(config.seed)) {}

std::size_t MapBuilder::capacity(const SlamConfig& config) {
  if (config.map.max_points > 0) return static_cast<std::size_t>(config.map.max_points);
  return static_cast<std::size_t>(std::max(0, config.keyframe_capacity)) *
         static_cast<std::size_t>(std::max(0, config.map.points_per_keyframe));
}

void MapBuilder::add_keyframe(const hal::RgbdFrame& frame, FrameImages& images, const Eigen::Isometry3d& T_world_cam,
                              StoredKeyframe* stored) {
  const Eigen::Isometry3f T = T_world_cam.cast<float>();
  std::uniform_int_distribution<int> column(0, camera_.width() - 1);
  std::uniform_int_distribution<int> row(0, camera_.height() - 1);
  const auto max_depth_m = static_cast<float>(config_.max_depth_m);
  const bool colour = images.has_colour();
  const cv::Mat* grey = colour ? nullptr : images.feature_image(frame, ImageSource::kInfrared);
  if (stored != nullptr) stored->T_world_map = T_world_cam;
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
    KeyframePoint coloured{point_cam, 0, 0, 0, false};
    if (colour) {
      const cv::Vec3b bgr = frame.rgb.at<cv::Vec3b>(v, u);
      coloured.blue = bgr[0];
      coloured.green = bgr[1];
      coloured.red = bgr[2];
    } else {
      const unsigned char level = grey->at<unsigned char>(v, u);
      coloured.blue = coloured.green = coloured.red = level;
    }
    coloured.in_map = map_.insert(point, coloured.blue, coloured.green, coloured.red);
    if (stored != nullptr && stored->point_count < static_cast<int>(stored->points.size())) {
      stored->points[static_cast<std::size_t>(stored->point_count++)] = coloured;
    }
    ++added;
  }
}

void MapBuilder::remove_keyframe(StoredKeyframe& keyframe) {
  // The points at the pose they were added at, computed as then, so each finds its voxel.
  const Eigen::Isometry3f T = keyframe.T_world_map.cast<float>();
  for (int p = 0; p < keyframe.point_count; ++p) {
    KeyframePoint& point = keyframe.points[static_cast<std::size_t>(p)];
    if (point.in_map) (void)map_.remove(T * point.point_cam, point.blue, point.green, point.red);
    point.in_map = false;
  }
}

void MapBuilder::rebuild(KeyframeStore& store) { insert_all(store, &store); }

void MapBuilder::rebuild_copy(const KeyframeStore& store) { insert_all(store, nullptr); }

void MapBuilder::insert_all(const KeyframeStore& store, KeyframeStore* noted) {
  map_.clear();
  for (int i = 0; i < store.capacity(); ++i) {
    const StoredKeyframe& keyframe = store.slot(i);
    if (!keyframe.used) continue;
    StoredKeyframe* note = noted != nullptr ? &noted->slot(i) : nullptr;
    if (note != nullptr) note->T_world_map = keyframe.T_world_cam;
    const Eigen::Isometry3f T = keyframe.T_world_cam.cast<float>();
    for (int p = 0; p < keyframe.point_count; ++p) {
      const KeyframePoint& point = keyframe.points[static_cast<std::size_t>(p)];
      const bool added = map_.insert(T * point.point_cam, point.blue, point.green, point.red);
      if (note != nullptr) note->points[static_cast<std::size_t>(p)].in_map = added;
    }
  }
}

}  // namespace rankslam::slam
