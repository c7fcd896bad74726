#pragma once

// Reading and decoding one recorded image, shared by the replay cameras.

#include "rankslam/hal/calibration.hpp"
#include "rankslam/hal/image_header.hpp"

#include <opencv2/core/mat.hpp>

#include <filesystem>
#include <string>
#include <vector>

namespace rankslam::replay::detail {

/// Reads an image file into `buffer`, reusing its capacity, and checks from its header, before
/// anything is decoded, that it has the calibration's size. Empty on success, else what is wrong.
[[nodiscard]] std::string read_image(const std::filesystem::path& path, const hal::CameraCalibration& camera,
                                     std::vector<unsigned char>& buffer, hal::ImageHeader& header);

/// Decodes `buffer` into `image` in place when its size and type already fit; false for data
/// no accepted format (PNG, JPEG, PPM/PGM, TIFF) starts with, or that fails to decode.
[[nodiscard]] bool decode(const std::vector<unsigned char>& buffer, int flags, cv::Mat& image);

}  // namespace rankslam::replay::detail
