#pragma once

#include "rankslam/camera/depth_camera.hpp"
#include "rankslam/features/ros2d.hpp"
#include "rankslam/geometry/matching.hpp"
#include "rankslam/slam/config.hpp"
#include "rankslam/slam/image_source.hpp"
#include "rankslam/slam/orb_extractor.hpp"

#include <Eigen/Core>
#include <opencv2/core/mat.hpp>
#include <opencv2/features2d.hpp>

#include <cstdint>
#include <optional>
#include <vector>

namespace rankslam::slam {

/// ORB features of one frame that have valid depth, with their camera-frame 3D points.
struct PhotometricFeatures {
  std::vector<cv::KeyPoint> keypoints;
  cv::Mat descriptors;  ///< CV_8UC1, one 32-byte row per keypoint: a view of descriptor_storage.
  std::vector<Eigen::Vector3f> points_cam;
  /// Predicted standard deviation of each point's position, metres: depth error along the ray
  /// ((a+b)·z²: the calibration's depth_noise_per_m and SlamConfig::keypoint_depth_noise_per_m) combined with the keypoint's localisation error, which
  /// grows with its pyramid level.
  std::vector<float> sigma_m;
  /// The image the features were detected on: descriptors of different images never match.
  ImageSource source = ImageSource::kColour;
  /// Memory behind `descriptors`, allocated once so that extraction does not reallocate.
  cv::Mat descriptor_storage;

  /// Set-up: room for `capacity` features.
  void reserve(std::size_t capacity);
  /// Empties the set, keeping its memory.
  void clear();
  [[nodiscard]] std::size_t size() const { return points_cam.size(); }
};

/// A mutual (cross-checked) descriptor match: `source` indexes the earlier frame.
struct FeatureMatch {
  std::uint32_t source = 0;
  std::uint32_t target = 0;
  std::uint32_t distance = 0;
};

/// Extracts ORB features and keeps those with depth in range (docs/methods.md §2).
///
/// The nearest pixel's depth is used: bilinear sub-pixel depth, dropping keypoints at depth steps
/// and a per-cell detection quota were less accurate or cost more (docs/results.md §5).
///
/// Features come from OrbExtractor, whose memory is fixed at construction, unless
/// config.orb_implementation selects OpenCV's cv::ORB (which allocates on every frame).
class OrbFrontend {
 public:
  OrbFrontend(const SlamConfig& config, const camera::DepthCameraModel& camera);

  /// `gray` is the image features are detected on, of kind `source`; `depth` the registered raw
  /// depth. An infrared image is detected with config.ir_orb_fast_threshold where it is positive
  /// (its contrast differs from the colour image's): one extractor, and its buffers, serves both.
  void extract(const cv::Mat& gray, const cv::Mat& depth, PhotometricFeatures& features,
               ImageSource source = ImageSource::kColour);

 private:
  const camera::DepthCameraModel& camera_;
  float min_depth_m_;
  float max_depth_m_;
  float depth_noise_per_m_;
  float keypoint_sigma_px_;
  float scale_factor_;
  int colour_fast_threshold_;
  int infrared_fast_threshold_;
  OrbExtractor extractor_;
  std::optional<features::Ros2dDetector> ros2d_;  ///< Set only when config.ros2d_keypoints is 1.
  std::vector<cv::KeyPoint> ros2d_keypoints_;
  cv::Ptr<cv::ORB> opencv_orb_;  ///< Set only when config.orb_implementation is kOpenCv.
  std::vector<cv::KeyPoint> opencv_keypoints_;
  cv::Mat opencv_descriptors_;
};

/// Mutual nearest-neighbour matching by Hamming distance: i and j match when each is the
/// other's closest descriptor and the distance is at most `max_distance`. One pass over the
/// distance matrix finds both directions' minima.
class MutualHammingMatcher {
 public:
  /// Set-up (allocates): room for descriptor sets of up to `max_descriptors` rows, so that
  /// match() allocates nothing for sets no larger. Without it the scratch grows to the largest
  /// set matched so far, which can happen at any frame.
  void reserve(std::size_t max_descriptors);
  void match(const cv::Mat& source, const cv::Mat& target, int max_distance, std::vector<FeatureMatch>& matches);

 private:
  geometry::HammingNearest nearest_;
};

}  // namespace rankslam::slam
