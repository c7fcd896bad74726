#pragma once

// ROS2D — image features selected by rank-order statistics (Yousif 2016 ch. 7, ALGORITHMS.md §7,
// docs/methods.md §15): a Gaussian-weighted intensity residual over a SIFT-like scale space,
// segmented by MSSE; the second (high-residual) group are the features.

#include "rankslam/parallel/thread_team.hpp"

#include <opencv2/core/mat.hpp>
#include <opencv2/core/types.hpp>

#include <cstdint>
#include <string_view>
#include <vector>

namespace rankslam::features {

struct Ros2dOptions {
  /// n: octaves of the scale space; each halves the previous one's resolution. Range [1, 8].
  int octaves = 4;
  /// m: layers per octave, σ_l = σ0·k^l with k = 2^{1/m} (SIFT's schedule). Range [1, 8].
  int layers = 3;
  /// σ0 of the first layer, pixels of its octave (SIFT's 1.6). Range (0.3, 10].
  double sigma0 = 1.6;
  /// κ of the MSSE segmentation of all residuals (thesis §4.3.3: 20 % for ROS saliency); k0 =
  /// ⌈κ·N⌉. Range (0, 1).
  double min_inlier_fraction = 0.2;
  /// T of the MSSE transition test r_(j+1) > T²·σ_j² on the residuals (eq. 4.4). Range (0, 100].
  double transition_factor = 2.5;
  /// Histogram-equalise the grey image first (§7.1, for lighting invariance).
  bool equalize = true;
  /// Pixels of each octave a feature keeps from the border, beyond the kernel's half-width, so
  /// its descriptor window stays mostly inside the image; at least 1 (the 3×3 neighbourhood).
  /// Range [1, 64].
  int border_px = 4;
  /// Keep only a point whose residual is the largest of its 3×3 neighbours in its layer (a
  /// plateau of equal residuals keeps one). Off keeps every point of the second group, as the
  /// thesis does; on gives fewer, better-localised features.
  bool local_peaks_only = false;
  /// Most features returned, strongest residuals first (0: all of the second group). Range ≥ 0.
  int max_features = 0;
  /// Orientation (SIFT, §7.4): extra features for histogram peaks ≥ this fraction of the
  /// highest. Range (0, 1].
  double orientation_peak_ratio = 0.8;
  /// Orientation off: every feature gets angle 0 (upright), as for a camera that does not roll.
  bool orientation = true;

  /// Empty when every field is in range, else the name of the first offending field.
  [[nodiscard]] std::string_view validate() const;
};

/// What one detect() measured.
struct Ros2dStats {
  std::int64_t residuals = 0;   ///< residuals segmented (points of all layers inside the borders)
  std::int64_t second_group = 0;///< residuals above the MSSE transition
  double threshold = 0.0;       ///< the smallest residual of the second group
  int features = 0;             ///< keypoints returned (with extra orientations, after the cap)
};

/// The ROS2D detector. reserve() sizes every workspace for the largest image; detect() on an
/// image no larger then allocates nothing once `keypoints` has room for what it returns.
class Ros2dDetector {
 public:
  explicit Ros2dDetector(const Ros2dOptions& options = {});

  [[nodiscard]] const Ros2dOptions& options() const { return options_; }

  /// Set-up: workspaces for images up to `size` (a larger image re-sizes them, allocating).
  void reserve(cv::Size size);
  /// Set-up: share the row loops (the residual filters, the gradient tables) with a team; the
  /// result is the same with or without it. Null (the default) runs them on the caller.
  void use_team(parallel::ThreadTeam* team);

  /// Features of an 8-bit grey image (CV_8UC1), strongest residual first. cv::KeyPoint: pt in
  /// full-resolution pixels, size = 2·σ_layer·2^octave (SIFT's convention, so that OpenCV's SIFT
  /// computes descriptors on it), angle in degrees [0, 360) in image axes, response = the
  /// residual, octave = octave | layer << 8 (SIFT's packing), class_id = layer. False (keypoints
  /// empty) for an empty or non-CV_8UC1 image or one too small for one octave's kernel.
  bool detect(const cv::Mat& grey, std::vector<cv::KeyPoint>& keypoints);

  /// The histogram-equalised image of the last detect() (the input itself when equalize is off):
  /// the image the thesis computes SIFT descriptors on (§7.5).
  [[nodiscard]] const cv::Mat& equalized() const { return equalized_view_; }
  [[nodiscard]] const Ros2dStats& stats() const { return stats_; }

  /// The 1-D kernel half-width shared by every layer, set by the largest σ (§7.2).
  [[nodiscard]] int kernel_radius() const { return radius_; }

 private:
  template <class Body>
  void for_rows(int begin, int end, Body&& body);
  void prepare_gradients(int octave, int layer);
  void add_oriented(const cv::KeyPoint& candidate, std::vector<cv::KeyPoint>& out, std::size_t cap);

  Ros2dOptions options_;
  parallel::ThreadTeam* team_ = nullptr;
  int radius_ = 0;
  std::vector<std::vector<float>> kernels_;  // per layer: 2·radius + 1 taps summing to 1
  std::vector<std::vector<float>> orientation_weights_;  // per layer: the orientation window
  std::vector<int> orientation_radius_;
  cv::Mat equalized_;
  cv::Mat equalized_view_;                   // equalized_ at the last image's size
  std::vector<cv::Mat> octave_images_;       // CV_32F, per octave: I and I²
  std::vector<cv::Mat> residuals_;           // CV_32F, per octave × layer: residual, mean, |∇|, bin
  std::vector<std::uint8_t> gradients_ready_;
  std::vector<std::int64_t> window_points_;  // per layer: orientation window points to visit
  cv::Mat blur_a_, blur_b_, tmp_;            // per-octave scratch
  std::vector<float> values_;                // all residuals, for the sort
  std::vector<float> sort_scratch_;
  std::vector<cv::KeyPoint> candidates_;
  Ros2dStats stats_;
};

}  // namespace rankslam::features
