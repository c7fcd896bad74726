#pragma once

#include "rankslam/hal/calibration.hpp"
#include "rankslam/hal/messages.hpp"
#include "rankslam/hal/status.hpp"

#include <chrono>
#include <cstdint>
#include <string>

namespace rankslam::hal {

/// Registered colour + depth (+ IR) camera. `open()` may allocate and fail with a message;
/// `read()` never blocks longer than `wait` and never throws.
class DepthCamera {
 public:
  virtual ~DepthCamera() = default;
  /// Returns an empty string on success, otherwise what went wrong.
  [[nodiscard]] virtual std::string open() = 0;
  [[nodiscard]] virtual const Calibration& calibration() const = 0;
  /// Fills `frame` with views into a pool slot that stays valid until the next `read()`.
  [[nodiscard]] virtual ReadStatus read(RgbdFrame& frame, std::chrono::milliseconds wait) = 0;
  virtual void close() = 0;
};

/// A single camera (the wide-angle camera).
class Camera {
 public:
  virtual ~Camera() = default;
  [[nodiscard]] virtual std::string open() = 0;
  [[nodiscard]] virtual ReadStatus read(ImageFrame& frame, std::chrono::milliseconds wait) = 0;
  virtual void close() = 0;
};

/// A CAN bus. Frames are caller-owned; neither call blocks longer than `wait`.
class CanBus {
 public:
  virtual ~CanBus() = default;
  [[nodiscard]] virtual std::string open() = 0;
  [[nodiscard]] virtual ReadStatus receive(CanFrame& frame, std::chrono::milliseconds wait) = 0;
  [[nodiscard]] virtual ReadStatus send(const CanFrame& frame) = 0;
  virtual void close() = 0;
};

/// Monotonic time source, so replay can run on recorded time and tests on a manual clock.
class Clock {
 public:
  virtual ~Clock() = default;
  [[nodiscard]] virtual std::int64_t now_ns() const = 0;
};

/// The host's CLOCK_MONOTONIC.
class MonotonicClock final : public Clock {
 public:
  [[nodiscard]] std::int64_t now_ns() const override {
    return std::chrono::duration_cast<std::chrono::nanoseconds>(
               std::chrono::steady_clock::now().time_since_epoch())
        .count();
  }
};

}  // namespace rankslam::hal
