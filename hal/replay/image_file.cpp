#include "image_file.hpp"

#include "rankslam/hal/regular_file.hpp"

#include <opencv2/imgcodecs.hpp>

#include <algorithm>
#include <initializer_list>

namespace rankslam::replay::detail {
namespace {

// Larger is not a camera frame: 64 MiB holds an uncompressed 16-bit three-channel 4K image (50 MB).
constexpr std::size_t kMaxImageFileBytes = std::size_t{64} << 20U;

// A decoder may turn an image by its EXIF orientation, so either way round is the calibration's size.
bool has_size(const hal::ImageHeader& header, const hal::CameraCalibration& camera) {
  return (header.width == camera.width && header.height == camera.height) ||
         (header.width == camera.height && header.height == camera.width);
}

// OpenCV leaves a preallocated destination untouched, and reports nothing, when no decoder
// recognises the data, so unknown data must be caught before decoding.
bool has_image_signature(const std::vector<unsigned char>& buffer) {
  const auto starts_with = [&](std::initializer_list<unsigned char> prefix) {
    return buffer.size() >= prefix.size() && std::equal(prefix.begin(), prefix.end(), buffer.begin());
  };
  return starts_with({0x89, 'P', 'N', 'G', '\r', '\n', 0x1A, '\n'}) || starts_with({0xFF, 0xD8, 0xFF}) ||
         starts_with({'P', '5'}) || starts_with({'P', '6'}) || starts_with({'I', 'I', 0x2A, 0x00}) ||
         starts_with({'M', 'M', 0x00, 0x2A});
}

}  // namespace

std::string read_image(const std::filesystem::path& path, const hal::CameraCalibration& camera,
                       std::vector<unsigned char>& buffer, hal::ImageHeader& header) {
  if (auto error = hal::read_regular_file(path, kMaxImageFileBytes, buffer); !error.empty()) return error;
  const auto read = hal::read_image_header(buffer);
  if (!read) return path.string() + ": not a decodable image";
  header = *read;
  if (!has_size(header, camera)) {
    return path.string() + ": " + std::to_string(header.width) + "x" + std::to_string(header.height) +
           " but the calibration says " + std::to_string(camera.width) + "x" + std::to_string(camera.height);
  }
  return {};
}

// A decoder that fails after reading the header releases `image`, so an empty result means corrupt data.
bool decode(const std::vector<unsigned char>& buffer, int flags, cv::Mat& image) {
  if (!has_image_signature(buffer)) return false;
  try {
    cv::Mat decoded = cv::imdecode(buffer, flags, &image);
    return !decoded.empty();
  } catch (const cv::Exception&) {
    return false;
  }
}

}  // namespace rankslam::replay::detail
