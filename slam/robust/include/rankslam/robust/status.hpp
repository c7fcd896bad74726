#pragma once

#include <cstdint>
#include <string_view>

namespace rankslam::robust {

/// Outcome of a robust estimate (MSSE or RANSAC). The per-frame loop branches on it; it never
/// throws.
enum class [[nodiscard]] RobustStatus : std::uint8_t {
  kOk,                ///< A model was estimated; the result's fields are valid.
  kTooFewPoints,      ///< Fewer points than the model's minimal sample, its p + 1, or k0 needs.
  kDegenerate,        ///< Every drawn minimal sample was degenerate (coincident, collinear, ...).
  kNoHypothesis,      ///< Every non-degenerate hypothesis was rejected by the caller's gate.
  kInvalidInput,      ///< Non-finite values, mismatched sizes or non-positive sigmas/weights.
  kInvalidConfig,     ///< A config field is out of range (see the config's validate()).
  kCapacityExceeded,  ///< More points than the workspace or model was set up for.
};

constexpr std::string_view to_string(RobustStatus status) {
  switch (status) {
    case RobustStatus::kOk: return "ok";
    case RobustStatus::kTooFewPoints: return "too-few-points";
    case RobustStatus::kDegenerate: return "degenerate";
    case RobustStatus::kNoHypothesis: return "no-hypothesis";
    case RobustStatus::kInvalidInput: return "invalid-input";
    case RobustStatus::kInvalidConfig: return "invalid-config";
    case RobustStatus::kCapacityExceeded: return "capacity-exceeded";
  }
  return "unknown";
}

}  // namespace rankslam::robust
