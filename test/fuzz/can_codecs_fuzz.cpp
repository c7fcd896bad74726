// The CAN codecs on arbitrary frames: the wheel-encoder frame the base controller sends and the
// pose, quality and heartbeat frames rankslam sends. Every decoder refuses or decodes; what
// decodes encodes back to the same bytes.
#include "fuzz_support.hpp"
#include "rankslam/nav/pose_frames.hpp"
#include "rankslam/nav/wheel_frame.hpp"

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <cstring>

namespace {

using rankslam::fuzz::require;
using rankslam::hal::CanFrame;

bool same_payload(const CanFrame& a, const CanFrame& b) {
  return a.id == b.id && a.length == b.length && std::equal(a.data.begin(), a.data.begin() + a.length, b.data.begin());
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  namespace nav = rankslam::nav;
  if (size < 6) return 0;
  CanFrame frame;
  std::uint32_t id_bits = 0;
  std::memcpy(&id_bits, data, 4);
  // Mostly the identifiers the codecs know, so the fuzzer reaches their payload checks.
  static constexpr std::uint32_t kKnown[] = {nav::kPoseXYYawId,     nav::kPoseZRollPitchId,
                                             nav::kPoseQualityId,   nav::kHeartbeatId,
                                             nav::kMapOdomXYYawId,  nav::kMapOdomZRollPitchId};
  frame.id = (id_bits & 1U) != 0 ? kKnown[(id_bits >> 1) % std::size(kKnown)] : (id_bits >> 1) & 0x1FFFFFFFU;
  frame.extended = frame.id > 0x7FFU;
  frame.length = static_cast<std::uint8_t>(data[4] % 10);  // 8 and 9 test lengths beyond the payload
  const std::size_t payload = std::min<std::size_t>(size - 5, 8);
  std::memcpy(frame.data.data(), data + 5, payload);
  if (frame.length > 8) frame.length = 8;
  frame.stamp_ns = 1'700'000'000'000'000'000;

  if (const auto ticks = nav::decode_wheel_ticks(frame)) {
    require(ticks->left_ticks < nav::kWheelTickModulus && ticks->right_ticks < nav::kWheelTickModulus,
            "tick counters within 24 bits");
    const auto encoded = nav::encode_wheel_ticks(*ticks, frame.id, frame.stamp_ns);
    require(encoded.length == frame.length, "wheel frame length survives");
    require(std::equal(encoded.data.begin(), encoded.data.begin() + 7, frame.data.begin()),
            "wheel counters survive a round trip");
  }
  // Angles outside their range decode as sent and are wrapped when encoded again, so the pose
  // frames must reach a fixed point after one round trip, with positions unchanged.
  // The int22 minimum is outside the ±kPositionMaxCount the encoder saturates at.
  const auto in_range = [](double position_m) {
    const double limit_m = static_cast<double>(nav::kPositionMaxCount) * nav::kPositionScale_m;
    return std::clamp(position_m, -limit_m, limit_m);
  };
  if (const auto pose = nav::decode_pose_xy_yaw(frame, frame.id)) {
    const auto once = nav::encode_pose_xy_yaw(*pose, frame.stamp_ns, frame.id);
    const auto again = nav::decode_pose_xy_yaw(once, frame.id);
    require(again && again->x_m == in_range(pose->x_m) && again->y_m == in_range(pose->y_m),
            "PoseXYYaw positions survive");
    require(same_payload(nav::encode_pose_xy_yaw(*again, frame.stamp_ns, frame.id), once), "PoseXYYaw is stable");
  }
  if (const auto pose = nav::decode_pose_z_roll_pitch(frame, frame.id)) {
    const auto once = nav::encode_pose_z_roll_pitch(*pose, frame.stamp_ns, frame.id);
    const auto again = nav::decode_pose_z_roll_pitch(once, frame.id);
    require(again && again->z_m == in_range(pose->z_m), "PoseZRollPitch height survives");
    require(same_payload(nav::encode_pose_z_roll_pitch(*again, frame.stamp_ns, frame.id), once),
            "PoseZRollPitch is stable");
  }
  if (const auto quality = nav::decode_pose_quality(frame)) {
    require(quality->counter < 16, "cycle counter within 4 bits");
    require(same_payload(nav::encode_pose_quality(*quality, frame.stamp_ns), frame), "PoseQuality round trip");
  }
  if (const auto heartbeat = nav::decode_heartbeat(frame)) {
    // Byte 4 bits 2..7 and byte 5 bits 5..7 are reserved: the encoder writes zeros there.
    CanFrame expected = frame;
    expected.data[4] &= 0x03U;
    expected.data[5] &= 0x1FU;
    require(same_payload(nav::encode_heartbeat(*heartbeat, frame.stamp_ns), expected), "Heartbeat round trip");
  }
  return 0;
}
