// The headers most test sources include, precompiled once per build for every test executable
// (test/CMakeLists.txt, RANKSLAM_TEST_PCH): parsing them took about 3 s of each source's compile.
#pragma once

#include <gtest/gtest.h>

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <random>
#include <string>
#include <vector>
