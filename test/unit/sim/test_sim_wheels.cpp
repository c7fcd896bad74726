// corridor-loop's wheel encoder log: it integrates to the ground-truth path, the loop closes,
// and slip segments over-count exactly one wheel.
#include "sim_test_support.hpp"

#include "rankslam/hal/candump.hpp"
#include "rankslam/nav/wheel_frame.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <numbers>

namespace rankslam::sim {
namespace {

using testing::TempDir;

struct WheelSample {
  std::int64_t stamp_ns = 0;
  double left_m = 0.0;   // unwrapped, from the first frame
  double right_m = 0.0;
};

// Decodes can.log, checking the frame stream itself (rate, rolling counter), and unwraps the
// 24-bit counters into wheel travel.
std::vector<WheelSample> read_wheels(const std::filesystem::path& can_log, const hal::WheelGeometry& geometry,
                                     bool* wrapped) {
  std::vector<WheelSample> samples;
  const double m_per_tick = 2.0 * std::numbers::pi * geometry.radius_m / geometry.ticks_per_revolution;
  std::optional<nav::WheelTicks> previous;
  WheelSample sample;
  *wrapped = false;
  for (const auto& line : testing::read_all_lines(can_log)) {
    const auto frame = hal::parse_candump_line(line);
    EXPECT_TRUE(frame) << line;
    if (!frame) continue;
    EXPECT_EQ(frame->id, geometry.can_id);
    const auto ticks = nav::decode_wheel_ticks(*frame);
    EXPECT_TRUE(ticks) << line;
    if (!ticks) continue;
    EXPECT_FALSE(ticks->left_fault || ticks->right_fault);
    if (previous) {
      EXPECT_EQ(frame->stamp_ns - sample.stamp_ns, 10'000'000) << line;
      EXPECT_EQ(ticks->rolling_counter, static_cast<std::uint8_t>(previous->rolling_counter + 1));
      const int dl = nav::wheel_tick_delta(previous->left_ticks, ticks->left_ticks);
      const int dr = nav::wheel_tick_delta(previous->right_ticks, ticks->right_ticks);
      *wrapped = *wrapped || (dl > 0 && ticks->left_ticks < previous->left_ticks) ||
                 (dr > 0 && ticks->right_ticks < previous->right_ticks);
      sample.left_m += dl * m_per_tick;
      sample.right_m += dr * m_per_tick;
    }
    sample.stamp_ns = frame->stamp_ns;
    samples.push_back(sample);
    previous = ticks;
  }
  return samples;
}

struct Recording {
  hal::Calibration calibration;
  std::vector<testing::StampedPose> base;  // ground-truth base poses, 30 Hz
  std::vector<WheelSample> wheels;         // 100 Hz
  bool wrapped = false;
};

Recording load(const std::filesystem::path& dir) {
  Recording r;
  r.calibration = testing::read_calibration(dir / "calibration.yaml");
  EXPECT_TRUE(r.calibration.wheels);
  r.base = testing::read_groundtruth(dir / "groundtruth.txt");
  // groundtruth.txt holds the colour camera; the base is T_world_cam · T_base_cam⁻¹.
  for (auto& pose : r.base) pose.T = pose.T * r.calibration.rgb.T_base_cam.inverse();
  if (r.calibration.wheels) r.wheels = read_wheels(dir / "can.log", *r.calibration.wheels, &r.wrapped);
  return r;
}

double wrap(double angle) { return std::remainder(angle, 2.0 * std::numbers::pi); }

TEST(SimWheels, EncoderTicksIntegrateToTheGroundTruthLoop) {
  TempDir dir("wheels");
  auto options = testing::options_for("corridor-loop", dir.path(), 0);  // one whole loop
  options.images = false;
  options.wheel_slip = false;
  ASSERT_EQ(simulate_recording(options, nullptr), "");
  const Recording r = load(dir.path());
  ASSERT_GT(r.base.size(), 2500U);
  EXPECT_TRUE(r.wrapped) << "the counters should pass the 24-bit wrap";
  const double duration = r.base.back().stamp_s - r.base.front().stamp_s;
  ASSERT_EQ(static_cast<double>(r.wheels.size()), std::floor(duration * 100.0 + 1e-6) + 1.0);

  // The robot drives on the floor and comes back to where it started.
  for (const auto& pose : r.base) EXPECT_NEAR(pose.T.translation().z(), 0.0, 1e-9);
  const Eigen::Isometry3d& start = r.base.front().T;
  const Eigen::Isometry3d& end = r.base.back().T;
  EXPECT_LT((end.translation() - start.translation()).norm(), 1e-3);
  EXPECT_LT(std::abs(wrap(testing::yaw_of(end) - testing::yaw_of(start))), 1e-3);

  // Differential-drive dead reckoning from the ticks.
  const double track = r.calibration.wheels->track_width_m;
  double x = start.translation().x();
  double y = start.translation().y();
  double heading = testing::yaw_of(start);
  double odometry_length = 0.0;
  double max_error = 0.0;
  std::size_t gt_index = 0;
  double gt_length = 0.0;
  for (std::size_t k = 1; k < r.wheels.size(); ++k) {
    const double dl = r.wheels[k].left_m - r.wheels[k - 1].left_m;
    const double dr = r.wheels[k].right_m - r.wheels[k - 1].right_m;
    const double ds = 0.5 * (dl + dr);
    const double dtheta = (dr - dl) / track;
    x += ds * std::cos(heading + 0.5 * dtheta);
    y += ds * std::sin(heading + 0.5 * dtheta);
    heading += dtheta;
    odometry_length += std::abs(ds);
    // Every 0.1 s the wheel frame and a ground-truth frame share a stamp.
    if (k % 10 == 0) {
      gt_index = k / 10 * 3;
      if (gt_index >= r.base.size()) break;
      EXPECT_NEAR(static_cast<double>(r.wheels[k].stamp_ns) * 1e-9, r.base[gt_index].stamp_s, 1e-5);
      const Eigen::Vector3d p = r.base[gt_index].T.translation();
      max_error = std::max(max_error, std::hypot(x - p.x(), y - p.y()));
    }
  }
  for (std::size_t i = 1; i < r.base.size(); ++i) {
    gt_length += (r.base[i].T.translation() - r.base[i - 1].T.translation()).norm();
  }
  ASSERT_GT(gt_length, 19.0);
  EXPECT_NEAR(odometry_length, gt_length, 0.01 * gt_length);
  EXPECT_LT(max_error, 0.02 * gt_length) << "dead reckoning should follow the loop within 2 %";
  EXPECT_LT(std::hypot(x - end.translation().x(), y - end.translation().y()), 0.02 * gt_length);
  EXPECT_LT(std::abs(wrap(heading - testing::yaw_of(end))), 2.0 * std::numbers::pi / 180.0);
}

TEST(SimWheels, SlipSegmentsOverCountOneWheelOnly) {
  TempDir dir("slip");
  auto options = testing::options_for("corridor-loop", dir.path(), 0);
  options.images = false;
  options.seed = 5;
  ASSERT_EQ(simulate_recording(options, nullptr), "");
  const Recording r = load(dir.path());

  struct Slip {
    double start_s, end_s;
    bool left;
  };
  std::vector<Slip> slips;
  for (const auto& row : testing::read_rows(dir / "slip.txt")) {
    ASSERT_EQ(row.size(), 3U);
    ASSERT_TRUE(row[2] == "left" || row[2] == "right") << row[2];
    slips.push_back({std::stod(row[0]), std::stod(row[1]), row[2] == "left"});
    EXPECT_GT(slips.back().end_s, slips.back().start_s);
  }
  ASSERT_GE(slips.size(), 1U);

  // Per 0.1 s step: wheel travel from the ground truth against the encoders.
  const double track = r.calibration.wheels->track_width_m;
  int clean_steps = 0;
  int slip_steps = 0;
  for (std::size_t i = 3; i < r.base.size(); i += 3) {
    const std::size_t k = i / 3 * 10;
    ASSERT_LT(k, r.wheels.size());
    const auto& a = r.base[i - 3];
    const auto& b = r.base[i];
    const double dtheta = wrap(testing::yaw_of(b.T) - testing::yaw_of(a.T));
    const double mid = testing::yaw_of(a.T) + 0.5 * dtheta;
    const Eigen::Vector3d dp = b.T.translation() - a.T.translation();
    const double ds = dp.x() * std::cos(mid) + dp.y() * std::sin(mid);
    const double expected_left = ds - 0.5 * track * dtheta;
    const double expected_right = ds + 0.5 * track * dtheta;
    const double left = r.wheels[k].left_m - r.wheels[k - 10].left_m;
    const double right = r.wheels[k].right_m - r.wheels[k - 10].right_m;
    const double t0 = a.stamp_s;
    const double t1 = b.stamp_s;
    const Slip* overlapping = nullptr;
    const Slip* covering = nullptr;
    for (const auto& slip : slips) {
      if (slip.start_s < t1 && slip.end_s > t0) overlapping = &slip;
      if (slip.start_s <= t0 + 1e-6 && slip.end_s >= t1 - 1e-6) covering = &slip;
    }
    constexpr double kTolerance_m = 3e-4;  // tick quantisation and read jitter
    if (!overlapping) {
      ++clean_steps;
      EXPECT_NEAR(left, expected_left, kTolerance_m) << "t = " << t1;
      EXPECT_NEAR(right, expected_right, kTolerance_m) << "t = " << t1;
    } else if (covering) {
      ++slip_steps;
      const double slipping = covering->left ? left - expected_left : right - expected_right;
      const double rolling = covering->left ? right - expected_right : left - expected_left;
      const double travel = std::abs(covering->left ? expected_left : expected_right);
      EXPECT_GT(slipping, 0.1 * travel) << "t = " << t1;
      EXPECT_NEAR(rolling, 0.0, kTolerance_m) << "t = " << t1;
    }
  }
  EXPECT_GT(clean_steps, 800);
  EXPECT_GT(slip_steps, 0) << "at least one 0.1 s step should lie inside a slip";
}

}  // namespace
}  // namespace rankslam::sim
