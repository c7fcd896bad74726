#pragma once

#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "rankslam/eval/associate.hpp"
#include "rankslam/eval/trajectory.hpp"

namespace rankslam::eval {

/// Curve colours (BGR): a blue and an orange that stay apart for colour-blind readers.
inline const cv::Scalar kGroundTruthBgr{180, 119, 31};
inline const cv::Scalar kEstimateBgr{14, 127, 255};

struct TopViewOptions {
  int width_px = 800;          ///< image width, clamped to [200, 8000]
  int height_px = 800;         ///< image height, clamped to [200, 8000]
  bool align_estimate = true;  ///< align the estimate onto the ground truth first
  double max_difference_s = kDefaultMaxDifference_s;  ///< association window for that alignment
  std::optional<double> ate_rmse_m;                   ///< shown in the legend when set
  std::string title;                                  ///< drawn above the legend when not empty
  bool show_legend = true;                            ///< title and legend above the plot
  cv::Scalar ground_truth_bgr = kGroundTruthBgr;
  cv::Scalar estimate_bgr = kEstimateBgr;
};

/// Top view of a trajectory (and its ground truth): positions are projected onto the plane of
/// the two principal axes of largest variance of the ground truth (of the estimate when there is
/// none), so the view is right for TUM's camera-world frame and a robot's base frame alike.
/// Both image axes have the same scale; the grid is labelled in metres from the mean position.
/// The estimate is drawn aligned to the ground truth (the ATE alignment) when ground truth is
/// given and options.align_estimate is set; only the ground truth within the estimate's stamps
/// (± options.max_difference_s) is drawn. Start: filled circle; end: cross.
/// Returns a CV_8UC3 image with a white background; never fails (empty input gives a labelled
/// empty plot).
[[nodiscard]] cv::Mat render_top_view(const Trajectory& estimate,
                                      const Trajectory* ground_truth_or_null,
                                      const TopViewOptions& options = {});

/// PNG bytes of `image`; empty when OpenCV cannot encode it (empty or unsupported image).
[[nodiscard]] std::vector<uchar> encode_png(const cv::Mat& image);

/// encode_png() written atomically. Returns an empty string on success, otherwise a message
/// naming the file.
[[nodiscard]] std::string write_png(const std::filesystem::path& path, const cv::Mat& image);

}  // namespace rankslam::eval
