#pragma once

#include "rankslam/camera/lens.hpp"
#include "rankslam/hal/calibration.hpp"

#include <Eigen/Geometry>
#include <opencv2/core/mat.hpp>

#include <optional>
#include <vector>

namespace rankslam::camera {

/// What VirtualViews renders.
struct VirtualViewOptions {
  int rows = 3;     ///< viewing directions stacked in pitch
  int columns = 3;  ///< and side by side in yaw: 3 × 3 = the thesis' 9 views
  /// Fraction of a view's field its neighbour shares, so that a feature on a seam lies whole in
  /// one of them.
  double overlap = 0.1;
};

/// Virtual images (ALGORITHMS.md §6.3): pinhole views without distortion that share the RGB-D
/// camera's intrinsics and the wide-angle camera's centre, looking in a grid of directions that
/// covers the wide-angle field, so that features on them look as they do on RGB-D images. The
/// remap tables are built here, at set-up; render() only samples.
class VirtualViews {
 public:
  /// `wide`: the wide-angle camera. `view`: the intrinsics and size every view takes (the RGB-D
  /// camera's; its distortion is ignored, views are ideal pinholes).
  VirtualViews(const hal::CameraCalibration& wide, const hal::CameraCalibration& view,
               const VirtualViewOptions& options = {});

  [[nodiscard]] int count() const { return static_cast<int>(views_.size()); }
  /// The views' pinhole camera: the RGB-D intrinsics, no distortion.
  [[nodiscard]] const hal::CameraCalibration& view_camera() const { return view_camera_; }
  /// Rotates directions in view `index`'s optical frame into the wide-angle camera's.
  [[nodiscard]] const Eigen::Matrix3d& R_wide_view(int index) const { return at(index).R_wide_view; }
  /// Share of view `index`'s pixels that the wide-angle image reaches.
  [[nodiscard]] double coverage(int index) const;
  /// CV_8UC1, 255 where view `index` shows the wide-angle image (inside its image and its lens'
  /// field), 0 where it is black.
  [[nodiscard]] const cv::Mat& valid_mask(int index) const { return at(index).valid; }
  [[nodiscard]] const Lens& wide_lens() const { return lens_; }

  /// Unit ray in the wide-angle camera's frame through pixel (u, v) of view `index`.
  [[nodiscard]] Eigen::Vector3d ray(int index, double u, double v) const;
  /// The wide-angle image's pixel that view `index` shows at (u, v); none outside its field.
  [[nodiscard]] std::optional<Eigen::Vector2d> wide_pixel(int index, double u, double v) const;

  /// Pixel of view `index` that shows the direction `ray_wide` (wide-angle camera's frame); none
  /// behind the view or outside its image.
  [[nodiscard]] std::optional<Eigen::Vector2d> view_pixel(int index, const Eigen::Vector3d& ray_wide) const;

  /// Sizes `views` for images of `type` (CV_8UC1, CV_8UC3, ...); once, at set-up.
  void allocate(std::vector<cv::Mat>& views, int type) const;
  /// Samples every view from one wide-angle image (bilinear; black outside the field) into views
  /// that allocate() sized for its type. False, and nothing drawn, when `wide` does not have the
  /// wide-angle calibration's size or `views` were not sized for it.
  [[nodiscard]] bool render(const cv::Mat& wide, std::vector<cv::Mat>& views) const;

 private:
  struct View {
    Eigen::Matrix3d R_wide_view;
    cv::Mat map_xy;     ///< CV_16SC2: integer source pixel
    cv::Mat map_frac;   ///< CV_16UC1: its sub-pixel table index
    cv::Mat valid;      ///< CV_8UC1
  };
  [[nodiscard]] const View& at(int index) const { return views_.at(static_cast<std::size_t>(index)); }
  /// Direction (not unit) of view pixel (u, v) in the wide-angle camera's frame.
  [[nodiscard]] Eigen::Vector3d direction(const Eigen::Matrix3d& R_wide_view, double u, double v) const;

  Lens lens_;
  hal::CameraCalibration view_camera_;
  std::vector<View> views_;
};

}  // namespace rankslam::camera
