#pragma once

// Depth frames for the geometric front-end's tests: real TUM frames (when the shared data is
// present) and simulated frames with and without sensor noise.

#include <filesystem>
#include <string>
#include <vector>

#include <opencv2/core/mat.hpp>

#include "rankslam/hal/calibration.hpp"

namespace rankslam::geometry::testing {

/// The first `count` depth images of a TUM recording under RANKSLAM_SHARED_DATA/tum/<name>, with
/// the freiburg1 calibration; empty when the data is absent.
[[nodiscard]] std::vector<cv::Mat> tum_depth_frames(const std::string& name, int count,
                                                    hal::Calibration& calibration);

/// Frames [first, first + count) of a simulated scene (rankslam::sim), with or without sensor
/// noise; the same seed gives the same geometry and motion either way. Empty with `error` set
/// on failure.
[[nodiscard]] std::vector<cv::Mat> simulated_depth_frames(const std::string& scene, int first,
                                                          int count, bool sensor_noise,
                                                          hal::Calibration& calibration,
                                                          std::string& error);

}  // namespace rankslam::geometry::testing
