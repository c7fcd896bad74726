#include "rankslam/nav/pose_broadcaster.hpp"
#include "rankslam/nav/pose_frames.hpp"
#include "rankslam/nav/pose_output.hpp"
#include "rankslam/nav/pose_uncertainty.hpp"

#include "allocation_counter.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <map>
#include <regex>
#include <string>
#include <numbers>
#include <random>
#include <vector>

namespace rankslam::nav {
namespace {

double angle_difference_deg(double a, double b) {
  const double d = std::fmod(a - b + 540.0, 360.0) - 180.0;
  return std::abs(d);
}

double rotation_angle_deg(const Eigen::Isometry3d& a, const Eigen::Isometry3d& b) {
  return Eigen::AngleAxisd(a.linear().transpose() * b.linear()).angle() * 180.0 / std::numbers::pi;
}

TEST(PoseFrames, LayoutMatchesTheDbcBitPositions) {
  PoseXYYaw pose;
  pose.x_m = 0.001;     // count 1
  pose.y_m = -0.001;    // count -1 = 0x3FFFFF in 22 bits
  pose.yaw_deg = 0.02;  // count 2
  pose.counter = 0xA;
  const hal::CanFrame frame = encode_pose_xy_yaw(pose, 7);
  EXPECT_EQ(frame.id, kPoseXYYawId);
  EXPECT_EQ(frame.length, 8);
  EXPECT_EQ(frame.stamp_ns, 7);
  std::uint64_t word = 0;
  for (int i = 0; i < 8; ++i) word |= static_cast<std::uint64_t>(frame.data[static_cast<std::size_t>(i)]) << (8 * i);
  EXPECT_EQ(word & 0x3FFFFFU, 1U);
  EXPECT_EQ((word >> 22U) & 0x3FFFFFU, 0x3FFFFFU);
  EXPECT_EQ((word >> 44U) & 0xFFFFU, 2U);
  EXPECT_EQ(word >> 60U, 0xAU);
}

TEST(PoseFrames, RoundTripWithinHalfACount) {
  std::mt19937_64 rng(42);
  std::uniform_real_distribution<double> position(-2000.0, 2000.0);
  std::uniform_real_distribution<double> angle(-180.0, 180.0);
  std::uniform_real_distribution<double> pitch(-90.0, 90.0);
  for (int i = 0; i < 10000; ++i) {
    PoseXYYaw a{position(rng), position(rng), angle(rng), static_cast<std::uint8_t>(i % 16)};
    const auto decoded = decode_pose_xy_yaw(encode_pose_xy_yaw(a, 0));
    ASSERT_TRUE(decoded);
    EXPECT_LE(std::abs(decoded->x_m - a.x_m), 0.0005 + 1e-9);
    EXPECT_LE(std::abs(decoded->y_m - a.y_m), 0.0005 + 1e-9);
    EXPECT_LE(angle_difference_deg(decoded->yaw_deg, a.yaw_deg), 0.005 + 1e-9);
    EXPECT_EQ(decoded->counter, a.counter);

    PoseZRollPitch b{position(rng), angle(rng), pitch(rng), static_cast<std::uint8_t>(15 - i % 16)};
    const auto decoded_b = decode_pose_z_roll_pitch(encode_pose_z_roll_pitch(b, 0));
    ASSERT_TRUE(decoded_b);
    EXPECT_LE(std::abs(decoded_b->z_m - b.z_m), 0.0005 + 1e-9);
    EXPECT_LE(angle_difference_deg(decoded_b->roll_deg, b.roll_deg), 0.005 + 1e-9);
    EXPECT_LE(std::abs(decoded_b->pitch_deg - b.pitch_deg), 0.005 + 1e-9);
    EXPECT_EQ(decoded_b->counter, b.counter);
  }
}

TEST(PoseFrames, AnglesWrapAndPositionsSaturate) {
  PoseXYYaw pose;
  pose.yaw_deg = 180.0;  // the range is [-180, 180)
  EXPECT_DOUBLE_EQ(decode_pose_xy_yaw(encode_pose_xy_yaw(pose, 0))->yaw_deg, -180.0);
  pose.yaw_deg = 539.99;
  EXPECT_NEAR(decode_pose_xy_yaw(encode_pose_xy_yaw(pose, 0))->yaw_deg, 179.99, 1e-9);
  pose.yaw_deg = -190.0;
  EXPECT_NEAR(decode_pose_xy_yaw(encode_pose_xy_yaw(pose, 0))->yaw_deg, 170.0, 1e-9);
  pose.x_m = 5000.0;
  pose.y_m = -5000.0;
  const auto decoded = decode_pose_xy_yaw(encode_pose_xy_yaw(pose, 0));
  EXPECT_NEAR(decoded->x_m, 2097.151, 1e-9);
  EXPECT_NEAR(decoded->y_m, -2097.151, 1e-9);
  EXPECT_TRUE(position_saturates(PlanarPose{5000.0, 0.0, 0.0, 0.0, 0.0, 0.0}));
  EXPECT_FALSE(position_saturates(PlanarPose{2097.0, -2097.0, 1.0, 0.0, 0.0, 0.0}));
  pose.x_m = std::nan("");
  EXPECT_DOUBLE_EQ(decode_pose_xy_yaw(encode_pose_xy_yaw(pose, 0))->x_m, 0.0);
}

TEST(PoseFrames, QualityAndHeartbeatRoundTrip) {
  PoseQuality quality;
  quality.status = PoseStatus::kDegraded;
  quality.position_saturated = true;
  quality.wheel_slip = true;
  quality.counter = 9;
  quality.frame_counter = 201;
  quality.age_ms = 65000;
  quality.position_sigma_m = 0.0123;
  quality.yaw_sigma_deg = 0.5;
  quality.inlier_percent = 87;
  const auto q = decode_pose_quality(encode_pose_quality(quality, 0));
  ASSERT_TRUE(q);
  EXPECT_EQ(q->status, PoseStatus::kDegraded);
  EXPECT_TRUE(q->position_saturated);
  EXPECT_TRUE(q->wheel_slip);
  EXPECT_EQ(q->counter, 9);
  EXPECT_EQ(q->frame_counter, 201);
  EXPECT_EQ(q->age_ms, 65000);
  EXPECT_NEAR(*q->position_sigma_m, 0.0123, 1e-9);
  EXPECT_NEAR(*q->yaw_sigma_deg, 0.5, 1e-9);
  EXPECT_EQ(*q->inlier_percent, 87);

  const auto unknown = decode_pose_quality(encode_pose_quality(PoseQuality{}, 0));
  ASSERT_TRUE(unknown);
  EXPECT_FALSE(unknown->position_sigma_m);
  EXPECT_FALSE(unknown->yaw_sigma_deg);
  EXPECT_FALSE(unknown->inlier_percent);
  EXPECT_EQ(unknown->status, PoseStatus::kInitialising);

  Heartbeat heartbeat{4'000'000'000U, PoseStatus::kLost, true, true, false, true, true, 30, 255};
  const auto h = decode_heartbeat(encode_heartbeat(heartbeat, 0));
  ASSERT_TRUE(h);
  EXPECT_EQ(h->uptime_ms, 4'000'000'000U);
  EXPECT_EQ(h->status, PoseStatus::kLost);
  EXPECT_TRUE(h->camera_fault);
  EXPECT_TRUE(h->camera_watchdog);
  EXPECT_FALSE(h->can_tx_dropped);
  EXPECT_TRUE(h->end_of_stream);
  EXPECT_TRUE(h->wide_camera_fault);
  EXPECT_EQ(h->frames_per_s, 30);
  EXPECT_EQ(h->counter, 255);
}

TEST(PoseFrames, DecodersRefuseWrongFrames) {
  hal::CanFrame frame = encode_pose_xy_yaw(PoseXYYaw{}, 0);
  EXPECT_FALSE(decode_pose_z_roll_pitch(frame));
  EXPECT_FALSE(decode_heartbeat(frame));
  frame.length = 7;
  EXPECT_FALSE(decode_pose_xy_yaw(frame));
  frame = encode_pose_xy_yaw(PoseXYYaw{}, 0);
  frame.extended = true;
  EXPECT_FALSE(decode_pose_xy_yaw(frame));
  frame = encode_pose_quality(PoseQuality{}, 0);
  frame.data[7] = 101;  // inlier percent above 100
  EXPECT_FALSE(decode_pose_quality(frame));
  frame = encode_pose_z_roll_pitch(PoseZRollPitch{}, 0);
  const std::uint64_t pitch_9001 = std::uint64_t{9001} << 38U;  // 90.01°, outside the range
  for (std::size_t i = 0; i < 8; ++i) frame.data[i] = static_cast<std::uint8_t>((pitch_9001 >> (8U * i)) & 0xFFU);
  EXPECT_FALSE(decode_pose_z_roll_pitch(frame));
  frame = encode_pose_z_roll_pitch(PoseZRollPitch{0.0, 0.0, 90.0, 0}, 0);
  EXPECT_TRUE(decode_pose_z_roll_pitch(frame));
}

TEST(PoseFrames, EulerDecompositionRoundTrips) {
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> angle(-179.0, 179.0);
  std::uniform_real_distribution<double> pitch(-89.0, 89.0);
  for (int i = 0; i < 1000; ++i) {
    const PlanarPose pose{1.0, -2.0, 0.5, angle(rng), pitch(rng), angle(rng)};
    const Eigen::Isometry3d T = to_isometry(pose);
    const PlanarPose back = to_planar_pose(T);
    EXPECT_LE(rotation_angle_deg(to_isometry(back), T), 1e-6);
    EXPECT_NEAR(back.yaw_deg, pose.yaw_deg, 1e-6);
    EXPECT_NEAR(back.pitch_deg, pose.pitch_deg, 1e-6);
    EXPECT_NEAR(back.roll_deg, pose.roll_deg, 1e-6);
  }
  // Gimbal lock keeps the rotation even though roll and yaw are not separable.
  const Eigen::Isometry3d locked = to_isometry(PlanarPose{0, 0, 0, 30.0, 90.0, 10.0});
  EXPECT_LE(rotation_angle_deg(to_isometry(to_planar_pose(locked)), locked), 1e-6);
}

// A whole pose through the three frames stays within 1 mm and 0.1°, the output's specification.
TEST(PoseFrames, FullPoseWithinOneMillimetreAndATenthOfADegree) {
  std::mt19937_64 rng(3);
  std::uniform_real_distribution<double> position(-100.0, 100.0);
  std::uniform_real_distribution<double> unit(-1.0, 1.0);
  for (int i = 0; i < 2000; ++i) {
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    T.linear() = Eigen::Quaterniond(unit(rng), unit(rng), unit(rng), unit(rng)).normalized().toRotationMatrix();
    T.translation() = Eigen::Vector3d(position(rng), position(rng), position(rng));
    const PlanarPose pose = to_planar_pose(T);
    const auto a = decode_pose_xy_yaw(encode_pose_xy_yaw(PoseXYYaw{pose.x_m, pose.y_m, pose.yaw_deg, 0}, 0));
    const auto b = decode_pose_z_roll_pitch(encode_pose_z_roll_pitch(PoseZRollPitch{pose.z_m, pose.roll_deg, pose.pitch_deg, 0}, 0));
    ASSERT_TRUE(a && b);
    const Eigen::Isometry3d decoded = to_isometry(PlanarPose{a->x_m, a->y_m, b->z_m, b->roll_deg, b->pitch_deg, a->yaw_deg});
    EXPECT_LE((decoded.translation() - T.translation()).norm(), 0.001);
    EXPECT_LE(rotation_angle_deg(decoded, T), 0.1);
  }
}

// --- PoseBroadcaster on a recording bus and a manual clock ---

class RecordingBus final : public hal::CanBus {
 public:
  std::string open() override { return {}; }
  hal::ReadStatus receive(hal::CanFrame&, std::chrono::milliseconds) override { return hal::ReadStatus::kNoData; }
  hal::ReadStatus send(const hal::CanFrame& frame) override {
    if (full) return hal::ReadStatus::kNoData;
    sent.push_back(frame);
    return hal::ReadStatus::kOk;
  }
  void close() override {}
  std::vector<hal::CanFrame> sent;
  bool full = false;
};

class ManualClock final : public hal::Clock {
 public:
  std::int64_t now_ns() const override { return now; }
  std::int64_t now = 1'000'000'000;
};

std::vector<PoseQuality> qualities(const std::vector<hal::CanFrame>& frames) {
  std::vector<PoseQuality> out;
  for (const auto& frame : frames) {
    if (auto q = decode_pose_quality(frame)) out.push_back(*q);
  }
  return out;
}

std::vector<Heartbeat> heartbeats(const std::vector<hal::CanFrame>& frames) {
  std::vector<Heartbeat> out;
  for (const auto& frame : frames) {
    if (auto h = decode_heartbeat(frame)) out.push_back(*h);
  }
  return out;
}

// Advances the clock in 1 ms steps for `duration_ms`, polling each step.
void run_for(PoseBroadcaster& broadcaster, ManualClock& clock, int duration_ms) {
  for (int i = 0; i < duration_ms; ++i) {
    (void)broadcaster.poll();
    clock.now += 1'000'000;
  }
}

TEST(PoseBroadcaster, SendsPoseCyclesAndHeartbeatsAtTheirRates) {
  RecordingBus bus;
  ManualClock clock;
  PoseOutputConfig config;
  config.pose_rate_hz = 50.0;
  config.heartbeat_rate_hz = 10.0;
  config.watchdog_timeout_s = 10.0;
  PoseBroadcaster broadcaster(config, bus, clock);
  PoseSample sample;
  sample.T_map_base.translation() = Eigen::Vector3d(1.234, -0.5, 0.0);
  sample.T_map_base.linear() = Eigen::AngleAxisd(0.5, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  sample.capture_ns = clock.now - 20'000'000;
  sample.frame_sequence = 300;
  sample.inlier_percent = 64;
  broadcaster.update(sample);
  run_for(broadcaster, clock, 1000);
  EXPECT_EQ(broadcaster.counters().pose_cycles, 50U);
  EXPECT_EQ(broadcaster.counters().heartbeats, 10U);
  ASSERT_EQ(bus.sent.size(), 310U);
  // Cycle order and shared counter.
  EXPECT_EQ(bus.sent[0].id, kPoseXYYawId);
  EXPECT_EQ(bus.sent[1].id, kPoseZRollPitchId);
  EXPECT_EQ(bus.sent[2].id, kMapOdomXYYawId);
  EXPECT_EQ(bus.sent[3].id, kMapOdomZRollPitchId);
  EXPECT_EQ(bus.sent[4].id, kPoseVelocityId);
  EXPECT_EQ(bus.sent[5].id, kPoseQualityId);
  EXPECT_EQ(bus.sent[6].id, kHeartbeatId);
  const auto first = decode_pose_xy_yaw(bus.sent[0]);
  ASSERT_TRUE(first);
  EXPECT_NEAR(first->x_m, 1.234, 1e-9);
  EXPECT_NEAR(first->yaw_deg, 28.65, 0.006);
  const auto q = qualities(bus.sent);
  ASSERT_EQ(q.size(), 50U);
  EXPECT_EQ(q[0].status, PoseStatus::kTracking);
  EXPECT_EQ(q[0].frame_counter, 300 % 256);
  EXPECT_EQ(q[0].age_ms, 20);
  EXPECT_EQ(*q[0].inlier_percent, 64);
  for (std::size_t i = 0; i < q.size(); ++i) EXPECT_EQ(q[i].counter, i % 16);
  const auto h = heartbeats(bus.sent);
  ASSERT_EQ(h.size(), 10U);
  for (std::size_t i = 0; i < h.size(); ++i) {
    EXPECT_EQ(h[i].counter, i);
    EXPECT_EQ(h[i].uptime_ms, 100 * i);
  }
}

// The SLAM thread's wide-angle camera state reaches the heartbeat through the mailbox, both ways.
TEST(PoseBroadcaster, TheMailboxCarriesTheWideCameraFaultToTheHeartbeat) {
  RecordingBus bus;
  ManualClock clock;
  PoseOutputConfig config;
  config.watchdog_timeout_s = 10.0;
  PoseBroadcaster broadcaster(config, bus, clock);
  PoseMailbox mailbox;
  std::optional<std::int64_t> wheel_stamp_ns;
  mailbox.set_wide_camera_fault(true);
  mailbox.deliver(broadcaster, wheel_stamp_ns);
  run_for(broadcaster, clock, 300);
  auto h = heartbeats(bus.sent);
  ASSERT_FALSE(h.empty());
  EXPECT_TRUE(h.back().wide_camera_fault);
  EXPECT_FALSE(h.back().camera_fault);
  mailbox.set_wide_camera_fault(false);
  mailbox.deliver(broadcaster, wheel_stamp_ns);
  bus.sent.clear();
  run_for(broadcaster, clock, 300);
  h = heartbeats(bus.sent);
  ASSERT_FALSE(h.empty());
  EXPECT_FALSE(h.back().wide_camera_fault);
}

// The base in the map frame from the latest complete cycle: map-odom composed with the odom pose.
struct DecodedCycle {
  Eigen::Isometry3d T_odom_base = Eigen::Isometry3d::Identity();
  Eigen::Isometry3d T_map_odom = Eigen::Isometry3d::Identity();
};

DecodedCycle last_cycle(const std::vector<hal::CanFrame>& frames) {
  DecodedCycle cycle;
  std::optional<PoseXYYaw> xy, map_xy;
  std::optional<PoseZRollPitch> zrp, map_zrp;
  for (const auto& frame : frames) {
    if (auto d = decode_pose_xy_yaw(frame)) xy = d;
    if (auto d = decode_pose_z_roll_pitch(frame)) zrp = d;
    if (auto d = decode_pose_xy_yaw(frame, kMapOdomXYYawId)) map_xy = d;
    if (auto d = decode_pose_z_roll_pitch(frame, kMapOdomZRollPitchId)) map_zrp = d;
  }
  EXPECT_TRUE(xy && zrp && map_xy && map_zrp);
  if (!(xy && zrp && map_xy && map_zrp)) return cycle;
  EXPECT_EQ(xy->counter, map_zrp->counter);
  cycle.T_odom_base = to_isometry(PlanarPose{xy->x_m, xy->y_m, zrp->z_m, zrp->roll_deg, zrp->pitch_deg, xy->yaw_deg});
  cycle.T_map_odom = to_isometry(PlanarPose{map_xy->x_m, map_xy->y_m, map_zrp->z_m, map_zrp->roll_deg,
                                            map_zrp->pitch_deg, map_xy->yaw_deg});
  return cycle;
}

TEST(PoseBroadcaster, LoopClosureCorrectionsMoveTheMapOdomFrameNotTheOdomPose) {
  RecordingBus bus;
  ManualClock clock;
  PoseOutputConfig config;
  config.watchdog_timeout_s = 10.0;
  PoseBroadcaster broadcaster(config, bus, clock);
  // The robot drives 1 cm per frame along x while turning 0.2° per frame.
  const auto tracked = [](int frame) {
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    for (int i = 0; i < frame; ++i) {
      Eigen::Isometry3d step = Eigen::Isometry3d::Identity();
      step.translation() = Eigen::Vector3d(0.01, 0.0, 0.0);
      step.linear() = Eigen::AngleAxisd(0.2 * M_PI / 180.0, Eigen::Vector3d::UnitZ()).toRotationMatrix();
      T = T * step;
    }
    return T;
  };
  // At frame 30 a loop closure moves the map by 0.25 m and 3° (and a little z and roll).
  Eigen::Isometry3d correction = Eigen::Isometry3d::Identity();
  correction.translation() = Eigen::Vector3d(-0.25, 0.1, 0.004);
  correction.linear() = (Eigen::AngleAxisd(3.0 * M_PI / 180.0, Eigen::Vector3d::UnitZ()) *
                         Eigen::AngleAxisd(0.3 * M_PI / 180.0, Eigen::Vector3d::UnitX())).toRotationMatrix();
  Eigen::Isometry3d previous_odom = Eigen::Isometry3d::Identity();
  double largest_odom_step_m = 0.0;
  for (int frame = 0; frame < 60; ++frame) {
    PoseSample sample;
    sample.capture_ns = clock.now;
    sample.frame_sequence = static_cast<std::uint32_t>(frame);
    sample.T_map_base = frame >= 30 ? Eigen::Isometry3d(correction * tracked(frame)) : tracked(frame);
    if (frame == 30) sample.map_correction = correction;
    broadcaster.update(sample);
    run_for(broadcaster, clock, 20);  // one cycle per frame
    const DecodedCycle cycle = last_cycle(bus.sent);
    // The map pose is always the SLAM pose; the odom pose moves by the tracked step only.
    const Eigen::Isometry3d T_map_base = cycle.T_map_odom * cycle.T_odom_base;
    EXPECT_LT((T_map_base.translation() - sample.T_map_base.translation()).norm(), 0.002) << "frame " << frame;
    EXPECT_LT(Eigen::AngleAxisd(T_map_base.rotation().transpose() * sample.T_map_base.rotation()).angle(), 0.001);
    EXPECT_LT((cycle.T_odom_base.translation() - tracked(frame).translation()).norm(), 0.001) << "frame " << frame;
    if (frame > 0) {
      largest_odom_step_m = std::max(largest_odom_step_m, (cycle.T_odom_base.translation() - previous_odom.translation()).norm());
    }
    previous_odom = cycle.T_odom_base;
    if (frame < 30) {
      EXPECT_TRUE(cycle.T_map_odom.isApprox(Eigen::Isometry3d::Identity(), 1e-12)) << "frame " << frame;
    } else {
      EXPECT_LT((cycle.T_map_odom.translation() - correction.translation()).norm(), 0.001);
    }
  }
  EXPECT_LT(largest_odom_step_m, 0.0115);  // 1 cm steps and quantisation; the 0.27 m correction is not among them
  EXPECT_TRUE(broadcaster.T_map_odom().isApprox(correction, 1e-9));
}

TEST(PoseBroadcaster, WheelMotionSinceTheFrameMovesThePoseUntilTheNextFrame) {
  RecordingBus bus;
  ManualClock clock;
  PoseOutputConfig config;
  config.watchdog_timeout_s = 10.0;
  PoseBroadcaster broadcaster(config, bus, clock);
  PoseSample sample;
  sample.T_map_base.translation() = Eigen::Vector3d(2.0, 1.0, 0.0);
  sample.T_map_base.linear() = Eigen::AngleAxisd(M_PI / 2.0, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  broadcaster.update(sample);
  run_for(broadcaster, clock, 20);
  EXPECT_LT((last_cycle(bus.sent).T_odom_base.translation() - Eigen::Vector3d(2.0, 1.0, 0.0)).norm(), 0.001);
  // 5 cm forward in the base frame (facing +y in the map) and 2 degrees left since the frame.
  Eigen::Isometry3d motion = Eigen::Isometry3d::Identity();
  motion.translation() = Eigen::Vector3d(0.05, 0.0, 0.0);
  motion.linear() = Eigen::AngleAxisd(2.0 * M_PI / 180.0, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  broadcaster.set_wheel_motion(motion);
  run_for(broadcaster, clock, 20);
  const DecodedCycle moved = last_cycle(bus.sent);
  EXPECT_LT((moved.T_odom_base.translation() - Eigen::Vector3d(2.0, 1.05, 0.0)).norm(), 0.001);
  EXPECT_NEAR(to_planar_pose(moved.T_odom_base).yaw_deg, 92.0, 0.01);
  // The next frame replaces the propagated pose.
  sample.T_map_base.translation() = Eigen::Vector3d(2.0, 1.06, 0.0);
  broadcaster.update(sample);
  run_for(broadcaster, clock, 20);
  EXPECT_LT((last_cycle(bus.sent).T_odom_base.translation() - Eigen::Vector3d(2.0, 1.06, 0.0)).norm(), 0.001);
  // Switched off, the SLAM pose is re-sent unchanged.
  config.wheel_propagation = false;
  RecordingBus plain_bus;
  PoseBroadcaster plain(config, plain_bus, clock);
  plain.update(sample);
  plain.set_wheel_motion(motion);
  run_for(plain, clock, 20);
  EXPECT_LT((last_cycle(plain_bus.sent).T_odom_base.translation() - Eigen::Vector3d(2.0, 1.06, 0.0)).norm(), 0.001);
}

TEST(PoseBroadcaster, WatchdogReportsLostWhileHeartbeatsContinue) {
  RecordingBus bus;
  ManualClock clock;
  PoseOutputConfig config;
  config.pose_rate_hz = 20.0;
  config.heartbeat_rate_hz = 5.0;
  config.watchdog_timeout_s = 0.3;
  PoseBroadcaster broadcaster(config, bus, clock);
  EXPECT_EQ(broadcaster.status(), PoseStatus::kInitialising);
  for (int frame = 0; frame < 10; ++frame) {  // 30 fps for 1/3 s
    PoseSample sample;
    sample.capture_ns = clock.now;
    sample.frame_sequence = static_cast<std::uint32_t>(frame);
    broadcaster.update(sample);
    run_for(broadcaster, clock, 33);
  }
  EXPECT_EQ(broadcaster.status(), PoseStatus::kTracking);
  const std::size_t before = bus.sent.size();
  run_for(broadcaster, clock, 2000);  // the camera stops
  EXPECT_EQ(broadcaster.status(), PoseStatus::kLost);
  const std::vector<hal::CanFrame> after(bus.sent.begin() + static_cast<std::ptrdiff_t>(before), bus.sent.end());
  const auto q = qualities(after);
  const auto h = heartbeats(after);
  ASSERT_EQ(q.size(), 40U);
  ASSERT_EQ(h.size(), 10U);
  // Lost from the first cycle more than 0.3 s after the last frame (cycles every 50 ms).
  int lost = 0;
  for (const auto& quality : q) lost += quality.status == PoseStatus::kLost ? 1 : 0;
  EXPECT_GE(lost, 33);
  EXPECT_LE(lost, 35);
  EXPECT_EQ(q.back().status, PoseStatus::kLost);
  EXPECT_EQ(q.back().frame_counter, 9);
  EXPECT_TRUE(h.back().camera_watchdog);
  EXPECT_EQ(h.back().status, PoseStatus::kLost);
  EXPECT_EQ(h.back().frames_per_s, 0);
  // A frame clears it.
  PoseSample sample;
  sample.capture_ns = clock.now;
  broadcaster.update(sample);
  EXPECT_EQ(broadcaster.status(), PoseStatus::kTracking);
}

TEST(PoseBroadcaster, FailedRegistrationsDegradeThenLose) {
  RecordingBus bus;
  ManualClock clock;
  PoseOutputConfig config;
  config.lost_after_failed_frames = 3;
  PoseBroadcaster broadcaster(config, bus, clock);
  PoseSample sample;
  broadcaster.update(sample);
  EXPECT_EQ(broadcaster.status(), PoseStatus::kTracking);
  sample.registered = false;
  broadcaster.update(sample);
  EXPECT_EQ(broadcaster.status(), PoseStatus::kDegraded);
  broadcaster.update(sample);
  EXPECT_EQ(broadcaster.status(), PoseStatus::kDegraded);
  broadcaster.update(sample);
  EXPECT_EQ(broadcaster.status(), PoseStatus::kLost);
  sample.registered = true;
  broadcaster.update(sample);
  EXPECT_EQ(broadcaster.status(), PoseStatus::kTracking);
}

TEST(PoseBroadcaster, APoseOutsideTheMapIsLostAtOnceEvenWithWheels) {
  RecordingBus bus;
  ManualClock clock;
  PoseOutputConfig config;
  config.lost_after_failed_frames = 3;
  PoseBroadcaster broadcaster(config, bus, clock);
  PoseSample sample;
  sample.registered = false;
  sample.wheels_only = true;
  sample.lost = true;
  broadcaster.update(sample);
  EXPECT_EQ(broadcaster.status(), PoseStatus::kLost);
  sample.lost = false;
  sample.registered = true;
  sample.wheels_only = false;
  broadcaster.update(sample);
  EXPECT_EQ(broadcaster.status(), PoseStatus::kTracking);
}

TEST(PoseBroadcaster, WheelsOnlyFramesStayDegradedForAsLongAsTheyLast) {
  RecordingBus bus;
  ManualClock clock;
  PoseOutputConfig config;
  config.lost_after_failed_frames = 3;
  PoseBroadcaster broadcaster(config, bus, clock);
  PoseSample sample;
  broadcaster.update(sample);
  sample.registered = false;
  sample.wheels_only = true;
  for (int i = 0; i < 50; ++i) {
    broadcaster.update(sample);
    ASSERT_EQ(broadcaster.status(), PoseStatus::kDegraded) << "frame " << i;
  }
  // Neither vision nor wheels: the failures count from here.
  sample.wheels_only = false;
  broadcaster.update(sample);
  broadcaster.update(sample);
  EXPECT_EQ(broadcaster.status(), PoseStatus::kDegraded);
  broadcaster.update(sample);
  EXPECT_EQ(broadcaster.status(), PoseStatus::kLost);
}

TEST(PoseBroadcaster, WheelSlipFlagFollowsTheFrameThePoseComesFrom) {
  RecordingBus bus;
  ManualClock clock;
  PoseOutputConfig config;
  config.pose_rate_hz = 10.0;
  PoseBroadcaster broadcaster(config, bus, clock);
  PoseSample sample;
  for (const bool slip : {false, true, true, false}) {
    sample.wheel_slip = slip;
    broadcaster.update(sample);
    bus.sent.clear();
    clock.now += 100'000'000;
    (void)broadcaster.poll();
    const auto q = qualities(bus.sent);
    ASSERT_EQ(q.size(), 1U);
    EXPECT_EQ(q[0].wheel_slip, slip);
    EXPECT_EQ(q[0].status, PoseStatus::kTracking);
  }
}

TEST(PoseBroadcaster, FullQueueIsCountedAndFlaggedInTheHeartbeat) {
  RecordingBus bus;
  ManualClock clock;
  PoseOutputConfig config;
  config.pose_rate_hz = 10.0;
  config.heartbeat_rate_hz = 1.0;
  PoseBroadcaster broadcaster(config, bus, clock);
  (void)broadcaster.poll();  // heartbeat 0 and the first cycle
  bus.full = true;
  clock.now += 100'000'000;
  (void)broadcaster.poll();  // one cycle refused
  EXPECT_EQ(broadcaster.counters().tx_dropped, 6U);  // its six frames
  bus.full = false;
  clock.now += 900'000'000;
  (void)broadcaster.poll();
  const auto h = heartbeats(bus.sent);
  ASSERT_EQ(h.size(), 2U);
  EXPECT_FALSE(h[0].can_tx_dropped);
  EXPECT_TRUE(h[1].can_tx_dropped);
}

TEST(PoseBroadcaster, StallDoesNotBurst) {
  RecordingBus bus;
  ManualClock clock;
  PoseOutputConfig config;
  config.pose_rate_hz = 100.0;
  config.heartbeat_rate_hz = 1.0;
  PoseBroadcaster broadcaster(config, bus, clock);
  (void)broadcaster.poll();
  clock.now += 500'000'000;  // the sender thread was stalled for half a second
  const std::int64_t wait_ns = broadcaster.poll();
  EXPECT_EQ(broadcaster.counters().pose_cycles, 2U);
  EXPECT_EQ(wait_ns, 10'000'000);
}

TEST(PoseBroadcaster, SteadyStateDoesNotAllocate) {
  RecordingBus bus;
  bus.sent.reserve(100000);
  ManualClock clock;
  PoseBroadcaster broadcaster(PoseOutputConfig{}, bus, clock);
  PoseSample sample;
  sample.inlier_percent = 50;
  long allocations = 0;
  {
    const test_support::CountAllocations count;
    for (int frame = 0; frame < 300; ++frame) {
      sample.frame_sequence = static_cast<std::uint32_t>(frame);
      sample.registered = frame % 7 != 0;
      broadcaster.update(sample);
      run_for(broadcaster, clock, 33);
    }
    allocations = count.allocations();
  }
  EXPECT_EQ(allocations, 0);
  EXPECT_GT(broadcaster.counters().pose_cycles, 400U);
}

TEST(PoseOutputConfig, RangesAreChecked) {
  EXPECT_TRUE(validate(PoseOutputConfig{}).empty());
  PoseOutputConfig config;
  config.pose_rate_hz = 0.0;
  EXPECT_NE(validate(config).find("pose_rate_hz"), std::string::npos);
  config = {};
  config.watchdog_timeout_s = 20.0;
  EXPECT_NE(validate(config).find("watchdog_timeout_s"), std::string::npos);
}

TEST(PoseFrames, VelocityRoundTripSaturatesAndKeepsUnknown) {
  PoseVelocity velocity{0.3, -0.012, -45.67, 11};
  auto decoded = decode_pose_velocity(encode_pose_velocity(velocity, 5));
  ASSERT_TRUE(decoded && decoded->vx_mps && decoded->vy_mps && decoded->yaw_rate_dps);
  EXPECT_NEAR(*decoded->vx_mps, 0.3, 1e-9);
  EXPECT_NEAR(*decoded->vy_mps, -0.012, 1e-9);
  EXPECT_NEAR(*decoded->yaw_rate_dps, -45.67, 1e-9);
  EXPECT_EQ(decoded->counter, 11);
  // Saturation stays clear of the unknown value; not finite is unknown.
  velocity = {100.0, -100.0, std::nan(""), 0};
  decoded = decode_pose_velocity(encode_pose_velocity(velocity, 0));
  ASSERT_TRUE(decoded);
  EXPECT_NEAR(*decoded->vx_mps, 32.767, 1e-9);
  EXPECT_NEAR(*decoded->vy_mps, -32.767, 1e-9);
  EXPECT_FALSE(decoded->yaw_rate_dps);
  decoded = decode_pose_velocity(encode_pose_velocity(PoseVelocity{}, 0));
  ASSERT_TRUE(decoded);
  EXPECT_FALSE(decoded->vx_mps || decoded->vy_mps || decoded->yaw_rate_dps);
  hal::CanFrame wrong = encode_pose_velocity(PoseVelocity{}, 0);
  wrong.length = 6;
  EXPECT_FALSE(decode_pose_velocity(wrong));
  EXPECT_FALSE(decode_pose_velocity(encode_pose_quality(PoseQuality{}, 0)));
}

std::vector<PoseVelocity> velocities(const std::vector<hal::CanFrame>& frames) {
  std::vector<PoseVelocity> out;
  for (const auto& frame : frames) {
    if (auto v = decode_pose_velocity(frame)) out.push_back(*v);
  }
  return out;
}

TEST(PoseBroadcaster, VelocityFromTheOdomPoseChangeBetweenFrames) {
  RecordingBus bus;
  ManualClock clock;
  PoseOutputConfig config;
  config.watchdog_timeout_s = 10.0;
  PoseBroadcaster broadcaster(config, bus, clock);
  PoseSample sample;
  sample.T_map_base.linear() = Eigen::AngleAxisd(M_PI / 2.0, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  sample.capture_ns = clock.now;
  broadcaster.update(sample);
  run_for(broadcaster, clock, 33);
  ASSERT_FALSE(velocities(bus.sent).empty());
  EXPECT_FALSE(velocities(bus.sent).back().vx_mps);  // one frame: no velocity yet
  // 1 cm forward (+y in the map, the base faces it) and 1° left in 33 ms.
  sample.T_map_base.translation() = Eigen::Vector3d(0.0, 0.01, 0.0);
  sample.T_map_base.linear() = Eigen::AngleAxisd(M_PI / 2.0 + M_PI / 180.0, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  sample.capture_ns += 33'000'000;
  // A loop-closure correction with it: the odom pose, and so the velocity, does not jump.
  sample.map_correction.translation() = Eigen::Vector3d(5.0, 0.0, 0.0);
  sample.T_map_base.translation() += Eigen::Vector3d(5.0, 0.0, 0.0);
  broadcaster.update(sample);
  run_for(broadcaster, clock, 20);
  const PoseVelocity v = velocities(bus.sent).back();
  ASSERT_TRUE(v.vx_mps && v.vy_mps && v.yaw_rate_dps);
  EXPECT_NEAR(*v.vx_mps, 0.01 / 0.033, 0.002);
  EXPECT_NEAR(*v.vy_mps, 0.0, 0.002);
  EXPECT_NEAR(*v.yaw_rate_dps, 1.0 / 0.033, 0.05);
  EXPECT_EQ(v.counter, qualities(bus.sent).back().counter);
  // Frames too far apart give no velocity.
  sample.capture_ns += 600'000'000;
  sample.map_correction.setIdentity();
  broadcaster.update(sample);
  run_for(broadcaster, clock, 20);
  EXPECT_FALSE(velocities(bus.sent).back().vx_mps);
}

TEST(PoseBroadcaster, SigmasSentWhileTrackingGrowWithTheWheelsAndAreUnknownWhenLost) {
  RecordingBus bus;
  ManualClock clock;
  PoseOutputConfig config;
  config.watchdog_timeout_s = 0.3;
  PoseBroadcaster broadcaster(config, bus, clock, WheelNoise{1e-4, 0.30});
  run_for(broadcaster, clock, 20);
  ASSERT_FALSE(qualities(bus.sent).empty());
  EXPECT_FALSE(qualities(bus.sent).back().position_sigma_m);  // INITIALISING: unknown
  PoseSample sample;
  sample.position_sigma_m = 0.05;
  sample.yaw_sigma_deg = 1.0;
  broadcaster.update(sample);
  run_for(broadcaster, clock, 20);
  PoseQuality q = qualities(bus.sent).back();
  ASSERT_EQ(q.status, PoseStatus::kTracking);
  ASSERT_TRUE(q.position_sigma_m && q.yaw_sigma_deg);
  EXPECT_NEAR(*q.position_sigma_m, 0.05, 1e-4);
  EXPECT_NEAR(*q.yaw_sigma_deg, 1.0, 0.02);
  // 1 m on the wheels since the frame: the variance grows by 1e-4 / 2 per metre rolled.
  Eigen::Isometry3d motion = Eigen::Isometry3d::Identity();
  motion.translation().x() = 1.0;
  broadcaster.set_wheel_motion(motion);
  run_for(broadcaster, clock, 20);
  q = qualities(bus.sent).back();
  ASSERT_TRUE(q.position_sigma_m && q.yaw_sigma_deg);
  EXPECT_NEAR(*q.position_sigma_m, std::sqrt(0.05 * 0.05 + 0.5e-4), 1e-4);
  EXPECT_GT(*q.yaw_sigma_deg, 1.0);
  // No frame for longer than the watchdog: LOST, and the sigmas and velocity unknown.
  run_for(broadcaster, clock, 400);
  q = qualities(bus.sent).back();
  ASSERT_EQ(q.status, PoseStatus::kLost);
  EXPECT_FALSE(q.position_sigma_m || q.yaw_sigma_deg);
  EXPECT_FALSE(velocities(bus.sent).back().vx_mps);
}

TEST(PoseUncertainty, SigmasOfTheBaseFromTheCameraCovariance) {
  // Camera looking forward along the base's x axis (optical z forward, x right, y down), 0.2 m
  // ahead of the base origin.
  Eigen::Isometry3d T_base_cam = Eigen::Isometry3d::Identity();
  T_base_cam.linear() << 0, 0, 1, -1, 0, 0, 0, -1, 0;
  T_base_cam.translation() = Eigen::Vector3d(0.2, 0.0, 0.5);
  Eigen::Matrix<double, 6, 6> covariance = Eigen::Matrix<double, 6, 6>::Zero();
  // Translation: 3 cm sd along the optical z (base x), 1 cm along optical x (base y), 5 cm along
  // optical y (base z, not horizontal).
  covariance.diagonal().tail<3>() << 1e-4, 25e-4, 9e-4;
  PoseSigmas sigmas = pose_sigmas(Eigen::Isometry3d::Identity(), covariance, T_base_cam);
  EXPECT_NEAR(sigmas.position_m, 0.03, 1e-9);
  EXPECT_NEAR(sigmas.yaw_deg, 0.0, 1e-9);
  // A rotation about optical −y is a yaw of the base; the base origin 0.2 m behind the camera
  // swings sideways with it.
  covariance.setZero();
  covariance(1, 1) = std::pow(2.0 * M_PI / 180.0, 2);
  sigmas = pose_sigmas(Eigen::Isometry3d::Identity(), covariance, T_base_cam);
  EXPECT_NEAR(sigmas.yaw_deg, 2.0, 1e-9);
  EXPECT_NEAR(sigmas.position_m, 0.2 * 2.0 * M_PI / 180.0, 1e-9);
  // Wheels: no motion, no growth.
  EXPECT_EQ(grown_by_wheels(sigmas, 0.0, 0.0, 1e-4, 0.3).position_m, sigmas.position_m);
  const PoseSigmas grown = grown_by_wheels(PoseSigmas{0.0, 0.0}, 2.0, 0.0, 1e-4, 0.3);
  EXPECT_NEAR(grown.position_m, std::sqrt(1e-4), 1e-12);
  EXPECT_NEAR(grown.yaw_deg, std::sqrt(2.0 * 1e-4 * 2.0 / 0.09) * 180.0 / M_PI, 1e-9);
}

}  // namespace
}  // namespace rankslam::nav

// The database the base controller's side is generated from must describe what the codec sends:
// every signal of the pose frames, decoded the generic DBC way, equals the codec's value.
namespace rankslam::nav {
namespace {

struct DbcSignal {
  unsigned start = 0;
  unsigned length = 0;
  bool is_signed = false;
  double scale = 1.0;
};

std::map<std::uint32_t, std::map<std::string, DbcSignal>> read_dbc(const std::string& path) {
  std::map<std::uint32_t, std::map<std::string, DbcSignal>> messages;
  std::ifstream in(path);
  std::string line;
  std::uint32_t current = 0;
  const std::regex message(R"(^BO_ (\d+) \w+: 8 \w+)");
  const std::regex signal(R"(^ SG_ (\w+) : (\d+)\|(\d+)@1([+-]) \(([-0-9.e]+),0\))");
  std::smatch match;
  while (std::getline(in, line)) {
    if (std::regex_search(line, match, message)) {
      current = static_cast<std::uint32_t>(std::stoul(match[1]));
    } else if (std::regex_search(line, match, signal)) {
      messages[current][match[1]] = {static_cast<unsigned>(std::stoul(match[2])), static_cast<unsigned>(std::stoul(match[3])),
                                     match[4] == "-", std::stod(match[5])};
    }
  }
  return messages;
}

double dbc_value(const hal::CanFrame& frame, const DbcSignal& signal) {
  std::uint64_t word = 0;
  for (std::size_t i = 0; i < 8; ++i) word |= static_cast<std::uint64_t>(frame.data[i]) << (8U * i);
  const std::uint64_t mask = signal.length == 64 ? ~std::uint64_t{0} : (std::uint64_t{1} << signal.length) - 1;
  std::uint64_t raw = (word >> signal.start) & mask;
  double value = static_cast<double>(raw);
  if (signal.is_signed && (raw >> (signal.length - 1)) != 0) value -= static_cast<double>(std::uint64_t{1} << signal.length);
  return value * signal.scale;
}

TEST(PoseFrames, DbcDescribesTheCodec) {
  const auto dbc = read_dbc(std::string(RANKSLAM_SOURCE_DIR) + "/deploy/can/rankslam.dbc");
  ASSERT_TRUE(dbc.contains(kPoseXYYawId) && dbc.contains(kPoseZRollPitchId) && dbc.contains(kPoseQualityId) &&
              dbc.contains(kHeartbeatId) && dbc.contains(0x101) && dbc.contains(kMapOdomXYYawId) &&
              dbc.contains(kMapOdomZRollPitchId));
  // The map-odom frames share the pose frames' layout.
  for (const auto& [name, signal] : dbc.at(kPoseXYYawId)) {
    ASSERT_TRUE(dbc.at(kMapOdomXYYawId).contains(name)) << name;
    EXPECT_EQ(dbc.at(kMapOdomXYYawId).at(name).start, signal.start) << name;
    EXPECT_EQ(dbc.at(kMapOdomXYYawId).at(name).length, signal.length) << name;
  }
  for (const auto& [name, signal] : dbc.at(kPoseZRollPitchId)) {
    ASSERT_TRUE(dbc.at(kMapOdomZRollPitchId).contains(name)) << name;
    EXPECT_EQ(dbc.at(kMapOdomZRollPitchId).at(name).start, signal.start) << name;
    EXPECT_EQ(dbc.at(kMapOdomZRollPitchId).at(name).length, signal.length) << name;
  }
  const hal::CanFrame map_xy = encode_pose_xy_yaw(PoseXYYaw{3.5, -0.25, 12.34, 9}, 0, kMapOdomXYYawId);
  EXPECT_EQ(map_xy.id, kMapOdomXYYawId);
  EXPECT_NEAR(dbc_value(map_xy, dbc.at(kMapOdomXYYawId).at("X")), 3.5, 1e-9);
  EXPECT_NEAR(dbc_value(map_xy, dbc.at(kMapOdomXYYawId).at("Yaw")), 12.34, 1e-9);
  EXPECT_FALSE(decode_pose_xy_yaw(map_xy));  // a map-odom frame is not a pose frame
  const hal::CanFrame xy = encode_pose_xy_yaw(PoseXYYaw{-1234.567, 42.001, -123.45, 13}, 0);
  const auto& m110 = dbc.at(kPoseXYYawId);
  EXPECT_NEAR(dbc_value(xy, m110.at("X")), -1234.567, 1e-9);
  EXPECT_NEAR(dbc_value(xy, m110.at("Y")), 42.001, 1e-9);
  EXPECT_NEAR(dbc_value(xy, m110.at("Yaw")), -123.45, 1e-9);
  EXPECT_EQ(dbc_value(xy, m110.at("CycleCounter")), 13.0);
  const hal::CanFrame zrp = encode_pose_z_roll_pitch(PoseZRollPitch{-0.25, 179.99, -89.5, 7}, 0);
  const auto& m111 = dbc.at(kPoseZRollPitchId);
  EXPECT_NEAR(dbc_value(zrp, m111.at("Z")), -0.25, 1e-9);
  EXPECT_NEAR(dbc_value(zrp, m111.at("Roll")), 179.99, 1e-9);
  EXPECT_NEAR(dbc_value(zrp, m111.at("Pitch")), -89.5, 1e-9);
  EXPECT_EQ(dbc_value(zrp, m111.at("CycleCounter")), 7.0);
  PoseQuality quality;
  quality.status = PoseStatus::kLost;
  quality.position_saturated = true;
  quality.wheel_slip = true;
  quality.counter = 5;
  quality.frame_counter = 77;
  quality.age_ms = 1234;
  quality.position_sigma_m = 0.0456;
  quality.yaw_sigma_deg = 1.2;
  quality.inlier_percent = 42;
  const hal::CanFrame q = encode_pose_quality(quality, 0);
  const auto& m112 = dbc.at(kPoseQualityId);
  EXPECT_EQ(dbc_value(q, m112.at("Status")), 3.0);
  EXPECT_EQ(dbc_value(q, m112.at("PositionSaturated")), 1.0);
  EXPECT_EQ(dbc_value(q, m112.at("WheelSlip")), 1.0);
  EXPECT_EQ(dbc_value(q, m112.at("CycleCounter")), 5.0);
  EXPECT_EQ(dbc_value(q, m112.at("FrameCounter")), 77.0);
  EXPECT_EQ(dbc_value(q, m112.at("PoseAge")), 1234.0);
  EXPECT_NEAR(dbc_value(q, m112.at("PositionSigma")), 0.0456, 1e-9);
  EXPECT_NEAR(dbc_value(q, m112.at("YawSigma")), 1.2, 1e-9);
  EXPECT_EQ(dbc_value(q, m112.at("InlierRatio")), 42.0);
  const hal::CanFrame h = encode_heartbeat(Heartbeat{123456789U, PoseStatus::kDegraded, false, true, true, false, true, 29, 200}, 0);
  const auto& m118 = dbc.at(kHeartbeatId);
  EXPECT_EQ(dbc_value(h, m118.at("Uptime")), 123456789.0);
  EXPECT_EQ(dbc_value(h, m118.at("Status")), 2.0);
  EXPECT_EQ(dbc_value(h, m118.at("CameraFault")), 0.0);
  EXPECT_EQ(dbc_value(h, m118.at("CameraWatchdog")), 1.0);
  EXPECT_EQ(dbc_value(h, m118.at("CanTxDropped")), 1.0);
  EXPECT_EQ(dbc_value(h, m118.at("EndOfStream")), 0.0);
  EXPECT_EQ(dbc_value(h, m118.at("WideCameraFault")), 1.0);
  EXPECT_EQ(dbc_value(h, m118.at("FramesPerSecond")), 29.0);
  EXPECT_EQ(dbc_value(h, m118.at("RollingCounter")), 200.0);
  // Signals of one message never overlap and fit 64 bits.
  for (const auto& [id, signals] : dbc) {
    std::uint64_t used = 0;
    for (const auto& [name, signal] : signals) {
      ASSERT_LE(signal.start + signal.length, 64U) << name;
      const std::uint64_t bits = (signal.length == 64 ? ~std::uint64_t{0} : ((std::uint64_t{1} << signal.length) - 1)) << signal.start;
      EXPECT_EQ(used & bits, 0U) << "message " << id << " signal " << name << " overlaps";
      used |= bits;
    }
  }
}

}  // namespace
}  // namespace rankslam::nav
