#pragma once

#include "rankslam/hal/calibration.hpp"

#include <filesystem>
#include <string>

namespace rankslam::openni2::test {

/// URI under which OpenNI2's DummyDevice driver opens its synthetic device.
inline constexpr const char* kDummyUri = "Dummy";

/// A calibration of the DummyDevice's 320x240 streams (it reports no field of view).
hal::Calibration dummy_calibration();

/// A fresh directory under the system temporary directory.
std::filesystem::path fresh_directory(const std::string& name);

/// Records `milliseconds` of the DummyDevice's colour and depth streams into `path` with
/// openni::Recorder. Empty on success, otherwise what failed.
std::string record_dummy_oni(const std::filesystem::path& path, int milliseconds);

}  // namespace rankslam::openni2::test
