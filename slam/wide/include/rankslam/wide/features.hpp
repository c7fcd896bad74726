#pragma once

#include "rankslam/camera/depth_camera.hpp"
#include "rankslam/camera/virtual_views.hpp"

#include <Eigen/Core>
#include <opencv2/core/mat.hpp>
#include <opencv2/features2d.hpp>

#include <vector>

namespace rankslam::wide {

/// What the SIFT extractors find (OpenCV's SIFT, Lowe 2004, as thesis ch. 6 uses).
struct SiftOptions {
  /// Strongest keypoints kept per image: per virtual view, and per RGB-D frame.
  int features_per_image = 500;
  /// SIFT's contrast threshold. OpenCV's 0.04 keeps 17-47 features with a depth per RGB-D frame
  /// of the simulated corridor's plain walls, too few to register; 0.01 keeps 116-237.
  double contrast_threshold = 0.01;
  /// Pixels of a view's black border (outside the wide-angle image) a keypoint keeps away from:
  /// the border's edge is not in the scene.
  int border_px = 8;
  /// Farthest depth an RGB-D keypoint takes its point from, metres (the Kinect's reliable range).
  double max_depth_m = 4.0;
};

/// SIFT features of one wide-angle frame, found on its virtual views.
struct WideFeatures {
  int count = 0;
  Eigen::Matrix3Xd rays;             ///< unit rays in the wide-angle camera's frame, 3 × count
  cv::Mat descriptors;               ///< count × 128, CV_32F
  std::vector<int> view;             ///< the view each was found on
  std::vector<cv::Point2f> pixel;    ///< where on that view
};

/// SIFT features of one RGB-D frame that have a depth.
struct RgbdFeatures {
  int count = 0;
  Eigen::Matrix3Xd points;           ///< in the colour camera's optical frame, metres, 3 × count
  cv::Mat descriptors;               ///< count × 128, CV_32F
  std::vector<cv::Point2f> pixel;
};

/// SIFT on every virtual view of a wide-angle frame (ALGORITHMS.md §6.4); each keypoint keeps
/// its ray in the wide-angle camera's frame, for registering on the original rays (§6.5).
class WideFeatureExtractor {
 public:
  /// `views` must outlive the extractor.
  explicit WideFeatureExtractor(const camera::VirtualViews& views, const SiftOptions& options = {});

  /// `wide`: the wide-angle image (grey or BGR) at its calibration's size. False, with `out`
  /// empty, for any other size.
  bool extract(const cv::Mat& wide, WideFeatures& out);
  /// The virtual views of the last extract(), grey.
  [[nodiscard]] const std::vector<cv::Mat>& views() const { return rendered_; }

 private:
  const camera::VirtualViews& views_;
  cv::Ptr<cv::SIFT> sift_;
  std::vector<cv::Mat> rendered_;
  std::vector<cv::Mat> masks_;
  cv::Mat grey_;
  std::vector<cv::KeyPoint> keypoints_;
  cv::Mat descriptors_;
};

/// SIFT on an RGB-D frame's colour image; keypoints without a depth in range are dropped.
class RgbdFeatureExtractor {
 public:
  explicit RgbdFeatureExtractor(const camera::DepthCameraModel& camera, const SiftOptions& options = {});

  /// `image` grey or BGR, `depth` CV_16UC1 registered to it, both at the camera's size. False,
  /// with `out` empty, otherwise.
  bool extract(const cv::Mat& image, const cv::Mat& depth, RgbdFeatures& out);

 private:
  camera::DepthCameraModel camera_;
  SiftOptions options_;
  cv::Ptr<cv::SIFT> sift_;
  cv::Mat grey_;
  std::vector<cv::KeyPoint> keypoints_;
  cv::Mat descriptors_;
};

}  // namespace rankslam::wide
