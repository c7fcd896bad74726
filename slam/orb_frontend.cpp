#include "rankslam/slam/orb_frontend.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>

namespace rankslam::slam {

void PhotometricFeatures::reserve(std::size_t capacity) {
  keypoints.reserve(capacity);
  points_cam.reserve(capacity);
  sigma_m.reserve(capacity);
  descriptor_storage.create(static_cast<int>(capacity), 32, CV_8UC1);
  descriptors = descriptor_storage.rowRange(0, 0);
}

void PhotometricFeatures::clear() {
  keypoints.clear();
  points_cam.clear();
  sigma_m.clear();
  descriptors = descriptor_storage.rowRange(0, 0);
}

namespace {

OrbExtractorSettings extractor_settings(const SlamConfig& config, const camera::DepthCameraModel& camera) {
  OrbExtractorSettings settings;
  // With OpenCV's ORB in its place the extractor is left without image buffers.
  const bool used = config.orb_implementation == OrbImplementation::kFixedMemory;
  settings.width = used ? camera.width() : 0;
  settings.height = used ? camera.height() : 0;
  settings.max_features = config.orb_features;
  settings.scale_factor = static_cast<float>(config.orb_scale_factor);
  settings.levels = config.orb_levels;
  settings.fast_threshold = config.orb_fast_threshold;
  return settings;
}

}  // namespace

OrbFrontend::OrbFrontend(const SlamConfig& config, const camera::DepthCameraModel& camera)
    : camera_(camera),
      min_depth_m_(static_cast<float>(config.min_depth_m)),
      max_depth_m_(static_cast<float>(config.max_depth_m)),
      depth_noise_per_m_(static_cast<float>(camera.depth_noise_per_m() + config.keypoint_depth_noise_per_m)),
      keypoint_sigma_px_(static_cast<float>(config.keypoint_sigma_px)),
      scale_factor_(static_cast<float>(config.orb_scale_factor)),
      colour_fast_threshold_(config.orb_fast_threshold),
      infrared_fast_threshold_(config.ir_orb_fast_threshold > 0 ? config.ir_orb_fast_threshold : config.orb_fast_threshold),
      extractor_(extractor_settings(config, camera)) {
  if (config.ros2d_keypoints != 0 && config.orb_implementation == OrbImplementation::kFixedMemory) {
    features::Ros2dOptions options;
    // Only the octaves the descriptor pyramid spans: a coarser feature would be described at
    // the wrong scale.
    const double span = std::pow(config.orb_scale_factor, config.orb_levels - 1);
    options.octaves = std::clamp(static_cast<int>(std::floor(std::log2(span))) + 1, 1, options.octaves);
    // Candidates beyond the budget: some fall within the descriptor patch's border and are dropped.
    options.max_features = 2 * config.orb_features;
    // One keypoint per residual peak: the whole second group runs along edges, pixel beside pixel.
    options.local_peaks_only = true;
    ros2d_.emplace(options);
    ros2d_->reserve(cv::Size(camera.width(), camera.height()));
    ros2d_keypoints_.reserve(static_cast<std::size_t>(options.max_features));
  }
  if (config.orb_implementation == OrbImplementation::kOpenCv) {
    opencv_orb_ = cv::ORB::create(config.orb_features, static_cast<float>(config.orb_scale_factor), config.orb_levels, 31,
                                  0, 2, cv::ORB::HARRIS_SCORE, 31, config.orb_fast_threshold);
    opencv_keypoints_.reserve(static_cast<std::size_t>(config.orb_features) * 2);
  }
}

void OrbFrontend::extract(const cv::Mat& gray, const cv::Mat& depth, PhotometricFeatures& features,
                          ImageSource source) {
  features.clear();
  const int fast_threshold = source == ImageSource::kInfrared ? infrared_fast_threshold_ : colour_fast_threshold_;
  if (opencv_orb_) {
    opencv_orb_->setFastThreshold(fast_threshold);
    opencv_keypoints_.clear();
    opencv_orb_->detectAndCompute(gray, cv::noArray(), opencv_keypoints_, opencv_descriptors_);
  } else if (ros2d_) {
    // ROS2D's scale 2σ0 (its finest keypoint size) is the pyramid's level 0.
    if (!ros2d_->detect(gray, ros2d_keypoints_) ||
        !extractor_.describe(gray, ros2d_keypoints_, static_cast<float>(2.0 * ros2d_->options().sigma0))) {
      return;
    }
  } else {
    extractor_.set_fast_threshold(fast_threshold);
    if (!extractor_.extract(gray)) return;
  }
  const std::vector<cv::KeyPoint>& detected = opencv_orb_ ? opencv_keypoints_ : extractor_.keypoints();
  const cv::Mat descriptors = opencv_orb_ ? opencv_descriptors_ : extractor_.descriptors();
  if (features.descriptor_storage.rows < static_cast<int>(detected.size())) {
    features.descriptor_storage.create(static_cast<int>(detected.size()), 32, CV_8UC1);
  }
  int kept = 0;
  for (std::size_t i = 0; i < detected.size(); ++i) {
    const cv::KeyPoint& keypoint = detected[i];
    const int u = static_cast<int>(std::lround(keypoint.pt.x));
    const int v = static_cast<int>(std::lround(keypoint.pt.y));
    if (u < 0 || v < 0 || u >= camera_.width() || v >= camera_.height()) continue;
    const unsigned short raw = depth.at<unsigned short>(v, u);
    if (raw == 0) continue;
    const float z_m = camera_.metres(raw);
    if (z_m < min_depth_m_ || z_m > max_depth_m_) continue;
    features.keypoints.push_back(keypoint);
    // The ray comes from the sub-pixel keypoint position; depth from its nearest pixel.
    const float x = std::clamp(keypoint.pt.x, 0.0F, static_cast<float>(camera_.width() - 1));
    const float y = std::clamp(keypoint.pt.y, 0.0F, static_cast<float>(camera_.height() - 1));
    const Eigen::Vector2f ray = camera_.ray(x, y);
    features.points_cam.emplace_back(ray.x() * z_m, ray.y() * z_m, z_m);
    const float axial_m = depth_noise_per_m_ * z_m * z_m;
    const float lateral_m = keypoint_sigma_px_ * std::pow(scale_factor_, static_cast<float>(keypoint.octave)) * z_m /
                            static_cast<float>(camera_.calibration().fx);
    features.sigma_m.push_back(std::sqrt(axial_m * axial_m + 2.0F * lateral_m * lateral_m));
    std::memcpy(features.descriptor_storage.ptr(kept), descriptors.ptr(static_cast<int>(i)), 32);
    ++kept;
  }
  // A view of the storage: the next frame reuses its memory.
  features.descriptors = features.descriptor_storage.rowRange(0, kept);
}

void MutualHammingMatcher::reserve(std::size_t max_descriptors) { nearest_.reserve(max_descriptors); }

void MutualHammingMatcher::match(const cv::Mat& source, const cv::Mat& target, int max_distance,
                                 std::vector<FeatureMatch>& matches) {
  matches.clear();
  const int n_source = source.rows;
  const int n_target = target.rows;
  if (n_source == 0 || n_target == 0) return;
  nearest_.scan(source, target);
  for (int i = 0; i < n_source; ++i) {
    const std::uint32_t j = nearest_.nearest_target(i);
    if (j == geometry::HammingNearest::kNone) continue;
    const int jj = static_cast<int>(j);
    if (nearest_.nearest_source(jj) != static_cast<std::uint32_t>(i)) continue;
    if (nearest_.source_distance(jj) > static_cast<std::uint32_t>(max_distance)) continue;
    matches.push_back({static_cast<std::uint32_t>(i), j, nearest_.source_distance(jj)});
  }
}

}  // namespace rankslam::slam
