#pragma once

// Evaluation of 2D image features against a known homography (test-only): repeatability as in
// Mikolajczyk et al. 2005 (the Oxford protocol), the matching inlier ratio, synthetic
// transformations of a real image, and the peer detectors compared with ROS2D.

#include <opencv2/core/mat.hpp>
#include <opencv2/core/matx.hpp>
#include <opencv2/core/types.hpp>

#include <functional>
#include <memory>
#include <string>
#include <vector>

namespace rankslam::feature_eval {

/// How the overlap error of two regions is measured. Both measure the regions in image 1: the
/// keypoint of image 1 is a circle of radius size/2, the keypoint of image 2 is its circle
/// mapped back through H⁻¹ (the local affinity of H at its centre: an ellipse).
enum class OverlapMode {
  /// The Oxford protocol: both regions' shapes are scaled by the factor that gives region 1 a
  /// radius of 30 px; the centres are not moved, so the error measures the localisation
  /// against a 30 px region whatever the detector's own region size.
  normalised,
  /// The plain overlap of the two regions at their own size.
  plain,
};

struct RepeatabilityOptions {
  OverlapMode mode = OverlapMode::normalised;
  /// A correspondence is repeated when 1 − |A∩B|/|A∪B| is below this (the protocol's 0.5).
  double max_overlap_error = 0.5;
  /// The region radius region 1 is scaled to in OverlapMode::normalised (the protocol's 30 px).
  double normalised_radius = 30.0;
};

struct RepeatabilityResult {
  int count1 = 0;       ///< keypoints of image 1 whose projection lies inside image 2
  int count2 = 0;       ///< keypoints of image 2 whose projection lies inside image 1
  int repeated = 0;     ///< one-to-one correspondences with overlap error below the bound
  double repeatability = 0.0;  ///< repeated / min(count1, count2); 0 when either is 0
};

/// Repeatability of `kp1` (image of `size1`) and `kp2` (image of `size2`) under `h1to2`, which
/// maps image-1 pixels to image-2 pixels. Correspondences are assigned one-to-one, the smallest
/// overlap error first (the protocol's greedy assignment).
[[nodiscard]] RepeatabilityResult repeatability(const std::vector<cv::KeyPoint>& kp1, cv::Size size1,
                                                const std::vector<cv::KeyPoint>& kp2, cv::Size size2,
                                                const cv::Matx33d& h1to2,
                                                const RepeatabilityOptions& options = {});

/// Overlap error 1 − |A∩B|/|A∪B| of two ellipses {x : (x−c)ᵀ·Q·(x−c) ≤ 1} (Q symmetric positive
/// definite), exact to the area of inscribed 32-gons (each 0.6 % short of its ellipse).
[[nodiscard]] double ellipse_overlap_error(cv::Point2d c1, const cv::Matx22d& q1, cv::Point2d c2,
                                           const cv::Matx22d& q2);

struct MatchingResult {
  int matches = 0;   ///< mutual nearest neighbours among the keypoints of the common part
  int inliers = 0;   ///< matches whose image-1 point projects within the bound of its partner
  double inlier_ratio = 0.0;  ///< inliers / matches; 0 without matches
};

/// Descriptor matching with a mutual (cross) check on the keypoints of both images whose
/// projection lies inside the other image; `norm_type` as cv::NORM_L2 or cv::NORM_HAMMING.
/// Brute force when n1·n2 ≤ `exact_pairs_limit`, else FLANN (k-d trees for float descriptors,
/// LSH for binary ones) to keep dense detectors' evaluation in seconds.
[[nodiscard]] MatchingResult match_inliers(const std::vector<cv::KeyPoint>& kp1, const cv::Mat& desc1,
                                           cv::Size size1, const std::vector<cv::KeyPoint>& kp2,
                                           const cv::Mat& desc2, cv::Size size2,
                                           const cv::Matx33d& h1to2, int norm_type,
                                           double max_pixel_error = 2.0,
                                           double exact_pairs_limit = 6.0e7);

/// H·p, dehomogenised.
[[nodiscard]] cv::Point2d project(const cv::Matx33d& h, cv::Point2d p);
/// Inside [−0.5, w − 0.5) × [−0.5, h − 0.5): the area the image's pixels cover.
[[nodiscard]] bool inside(cv::Point2d p, cv::Size size);

/// A transformed copy of an image and the homography from the original's pixels to its pixels.
struct Transformed {
  std::string family;  ///< rotation, scale, blur, jpeg, brightness
  std::string label;   ///< e.g. "rotation 30°"
  cv::Mat image;
  cv::Matx33d h = cv::Matx33d::eye();
};

/// Rotation by `degrees` (counter-clockwise) about the image centre, same canvas (corners leave,
/// black enters).
[[nodiscard]] Transformed rotate(const cv::Mat& image, double degrees);
/// Resized by `factor` (cv::resize, area averaging when shrinking, bilinear when enlarging).
[[nodiscard]] Transformed scale(const cv::Mat& image, double factor);
/// Gaussian blur of standard deviation `sigma` px; identity homography.
[[nodiscard]] Transformed blur(const cv::Mat& image, double sigma);
/// JPEG-encoded at `quality` (0–100) and decoded; identity homography.
[[nodiscard]] Transformed jpeg(const cv::Mat& image, int quality);
/// Intensities multiplied by `factor`, saturated to [0, 255]; identity homography.
[[nodiscard]] Transformed brightness(const cv::Mat& image, double factor);

/// The rows the evaluation reports: rotation 30°, 90°, 180°; scale 0.5, 2; blur σ 2; JPEG
/// quality 20; brightness ×0.5, ×1.6.
[[nodiscard]] std::vector<Transformed> standard_transformations(const cv::Mat& image);

/// One detector + descriptor under evaluation. extract(grey CV_8UC1) fills keypoints and
/// descriptors; detect() fills keypoints alone.
struct Peer {
  std::string name;
  int norm_type = 0;
  std::function<void(const cv::Mat&, std::vector<cv::KeyPoint>&, cv::Mat&)> extract;
  std::function<void(const cv::Mat&, std::vector<cv::KeyPoint>&)> detect;
};

/// ROS2D (rankslam::features, its defaults), keeping its strongest `max_features` (0: all).
[[nodiscard]] Peer ros2d_peer(int max_features = 0);

/// Every method compared, in the tables' order: ROS2D (rankslam::features, its defaults), SIFT,
/// ORB (`orb_features`), BRISK, AKAZE, FAST (threshold 20, non-maximum suppression) with SIFT
/// descriptors. OpenCV's defaults otherwise.
[[nodiscard]] std::vector<Peer> make_peers(int orb_features = 5000);

/// One method on one image pair.
struct PairScore {
  int count = 0;            ///< mean keypoints of the two images
  RepeatabilityResult rep;  ///< OverlapMode::normalised
  RepeatabilityResult rep_plain;
  MatchingResult matching;
  double extract_ms = 0.0;  ///< mean wall time of one image's extraction
};

/// Extracts `peer`'s features from both images (grey) and scores them under `h1to2`; without
/// `matching` the descriptors are neither computed nor matched (its result stays zero).
[[nodiscard]] PairScore evaluate_pair(Peer& peer, const cv::Mat& grey1, const cv::Mat& grey2,
                                      const cv::Matx33d& h1to2, bool matching = true);

/// Reads a 3×3 homography written as nine whitespace-separated numbers (Oxford's H1to3p).
/// False when the file cannot be read or holds fewer numbers.
[[nodiscard]] bool read_homography(const std::string& path, cv::Matx33d& h);

}  // namespace rankslam::feature_eval
