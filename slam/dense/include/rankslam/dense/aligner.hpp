#pragma once

// Dense refinement of a frame-to-frame motion (docs/methods.md §17): coarse-to-fine direct
// alignment of an RGB-D frame to another over an image pyramid, with photometric residuals on the
// grey image and geometric ones on the depth image, each robustly weighted by its MSSE scale
// (docs/methods.md §1), started from the feature-based estimate.

#include "rankslam/camera/depth_camera.hpp"
#include "rankslam/camera/lens.hpp"

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <opencv2/core/mat.hpp>

#include <array>
#include <string_view>
#include <vector>

namespace rankslam::dense {

struct DenseOptions {
  /// Pyramid levels, each half the previous one's resolution; the alignment runs from the
  /// coarsest to the full-resolution one. Range [1, 5].
  int levels = 3;
  /// Gauss–Newton iterations per level at most. Range [1, 50].
  int iterations = 8;
  /// A pixel joins the photometric term when its grey gradient (central difference, grey levels
  /// per pixel) reaches this; pixels of a regular 4×4 grid join the depth term regardless.
  /// Range [0, 255].
  double min_gradient = 6.0;
  /// Reference pixels at most at full resolution, half as many per coarser level (an even
  /// subsample beyond it). Range [100, 100000].
  int max_points = 4000;
  /// Fewer photometric inliers than this at full resolution: the refinement is not used.
  /// Range [10, 100000].
  int min_inliers = 300;
  /// Depth range of the pixels used (metres). min in [0, 10), max in (min, 20].
  double min_depth_m = 0.3;
  double max_depth_m = 4.0;
  /// a in the depth residual's noise σ_z = a·z² (the sensor's axial noise). Range (0, 0.1].
  double depth_noise_per_m = 3.0e-3;
  /// Weight of the depth term: 0 aligns on the grey image alone. Range [0, 10].
  double depth_weight = 1.0;
  /// The refined motion may differ from the start by this much at most; beyond, the start is kept
  /// (a refinement that moves farther has locked onto something else). Ranges (0, 1] m, (0, 30]°.
  double max_change_m = 0.03;
  double max_change_deg = 1.5;
  /// κ and T of the MSSE scale of each term (docs/methods.md §1). κ in (0, 1), T in (0, 100].
  double min_inlier_fraction = 0.2;
  double transition_factor = 2.5;

  /// Empty when every field is in range, else the name of the first offending field.
  [[nodiscard]] std::string_view validate() const;
};

/// One frame's pyramid: grey image, its gradients, depth in metres and its gradients per level.
/// Sized once by reserve(); prepare() allocates nothing.
class DenseFrame {
 public:
  static constexpr int kMaxLevels = 5;

  /// Set-up: buffers for `levels` levels of a width × height frame.
  void reserve(int width, int height, int levels);
  /// Builds the pyramid of an 8-bit grey image and a raw depth image (CV_16UC1, 0 = none) of the
  /// reserved size; `source` tags the image kind (frames of different kinds are not aligned).
  /// False (and the frame invalid) for images of another size or type.
  bool prepare(const cv::Mat& grey, const cv::Mat& depth_raw, float metres_per_unit, float min_depth_m,
               float max_depth_m, int source);
  void invalidate() { valid_ = false; }
  [[nodiscard]] bool valid() const { return valid_; }
  [[nodiscard]] int source() const { return source_; }
  [[nodiscard]] int levels() const { return levels_; }

  struct Level {
    cv::Mat grey, gx, gy;      ///< CV_32F: intensity and its central differences
    cv::Mat depth, zx, zy;     ///< CV_32F: metres (0 = none) and central differences (NaN = none)
  };
  [[nodiscard]] const Level& level(int l) const { return level_[static_cast<std::size_t>(l)]; }

 private:
  std::array<Level, kMaxLevels> level_;
  int levels_ = 0;
  int width_ = 0;
  int height_ = 0;
  bool valid_ = false;
  int source_ = 0;
};

/// What one align() did.
struct DenseResult {
  bool ok = false;                  ///< the refined motion is to be used
  std::string_view reason;          ///< why not, when !ok
  int points = 0;                   ///< reference pixels at full resolution
  int photometric_inliers = 0;      ///< at full resolution, final motion
  int depth_inliers = 0;
  double photometric_sigma = 0.0;   ///< MSSE scale, grey levels
  double depth_sigma = 0.0;         ///< MSSE scale of the noise-normalised depth residuals
  int iterations = 0;               ///< Gauss–Newton steps taken over all levels
  double initial_cost = 0.0;        ///< full resolution, final scales: the start ...
  double final_cost = 0.0;          ///< ... and the refined motion
};

/// The aligner: camera model and options fixed at construction, which sizes every buffer.
class DenseAligner {
 public:
  DenseAligner(const camera::DepthCameraModel& camera, const DenseOptions& options);

  [[nodiscard]] const DenseOptions& options() const { return options_; }
  /// Set-up: a frame's buffers for this camera and these options.
  void reserve(DenseFrame& frame) const;

  /// Refines T_cur_ref (maps the reference frame's points into the current frame's) from its
  /// value on entry. On !ok it is left unchanged.
  DenseResult align(const DenseFrame& reference, const DenseFrame& current, Eigen::Isometry3d& T_cur_ref);

 private:
  struct Point {
    Eigen::Vector3f p;  // reference-frame point
    float intensity;
    bool photometric;   // gradient high enough for the grey term
  };
  struct Residual {
    float r_photo = 0.0F;  // NaN: none
    float r_depth = 0.0F;  // noise-normalised; NaN: none
    Eigen::Matrix<float, 6, 1> j_photo;
    Eigen::Matrix<float, 6, 1> j_depth;
  };
  struct Scales {
    double photo_bias = 0.0;
    double photo_sigma = 1.0;
    double depth_sigma = 1.0;
  };

  int select_points(const DenseFrame& reference, int level);
  /// Residuals (and with `jacobians` their Jacobians) of the selected points under T at `level`.
  void evaluate(const DenseFrame& current, int level, const Eigen::Isometry3f& T, bool jacobians);
  [[nodiscard]] Scales estimate_scales();
  /// Normal equations of the last evaluate() (with Jacobians) under `scales`, inliers only.
  void accumulate(const Scales& scales, Eigen::Matrix<double, 6, 6>& H, Eigen::Matrix<double, 6, 1>& g) const;
  /// Truncated quadratic cost of the last evaluate() under `scales`; counts inliers.
  double cost(const Scales& scales, int* photo_inliers, int* depth_inliers) const;

  camera::DepthCameraModel camera_;
  camera::Lens lens_;  // projects into the frame (the depth camera's table back-projects)
  DenseOptions options_;
  std::vector<Point> points_;
  std::vector<int> candidates_;  // usable pixels of a level: index · 2 + photometric
  std::vector<Residual> residuals_;
  int count_ = 0;
  std::vector<float> sample_;  // squared residuals for the MSSE scale
  std::vector<float> signed_sample_;
};

}  // namespace rankslam::dense
