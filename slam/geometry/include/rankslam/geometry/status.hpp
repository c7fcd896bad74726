#pragma once

#include <cstdint>
#include <string_view>

namespace rankslam::geometry {

/// Outcome of a per-frame geometric step. The loop branches on it; nothing here throws.
enum class [[nodiscard]] GeometryStatus : std::uint8_t {
  kOk,
  kNotConfigured,      ///< configure() has not succeeded.
  kInvalidImage,       ///< Not a CV_16UC1 image of the camera's size.
  kTooFewPoints,       ///< Too few valid depth pixels or sampled points with normals.
  kCapacityExceeded,   ///< More sampled points than the set-up capacity, even at the largest leaf.
  kTooFewKeypoints,    ///< Fewer than 3 keypoints with a descriptor.
  kTooFewMatches,      ///< Fewer mutual matches than a rigid fit needs.
  kRegistrationFailed, ///< MSSE failed or found fewer inliers than min_inliers.
};

constexpr std::string_view to_string(GeometryStatus status) {
  switch (status) {
    case GeometryStatus::kOk: return "ok";
    case GeometryStatus::kNotConfigured: return "not-configured";
    case GeometryStatus::kInvalidImage: return "invalid-image";
    case GeometryStatus::kTooFewPoints: return "too-few-points";
    case GeometryStatus::kCapacityExceeded: return "capacity-exceeded";
    case GeometryStatus::kTooFewKeypoints: return "too-few-keypoints";
    case GeometryStatus::kTooFewMatches: return "too-few-matches";
    case GeometryStatus::kRegistrationFailed: return "registration-failed";
  }
  return "unknown";
}

}  // namespace rankslam::geometry
