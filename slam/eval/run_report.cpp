#include "rankslam/eval/run_report.hpp"

#include <algorithm>
#include <cstdio>

namespace rankslam::eval {
namespace {

// A loop closure counts as false when its measured relative pose is farther than this from the
// ground truth's: it joined two places that are not where the graph now puts them. (Correct
// closures on fr1_rpy_head are off by up to 0.12 m and 6 deg: imprecise, not false.)
constexpr double kFalseClosureTranslation_m = 0.25;
constexpr double kFalseClosureRotation_deg = 10.0;

}  // namespace

void StatusCounts::add(const slam::FrameResult& result) {
  switch (result.status) {
    case slam::FrameStatus::kFirstFrame:
    case slam::FrameStatus::kTracking: ++tracking; break;
    case slam::FrameStatus::kWheels: ++degraded; break;
    case slam::FrameStatus::kFailed: ++lost; break;
  }
  if (result.wheels.disagree) ++disagreements;
  if (result.wheels.wheels_trusted) ++wheels_trusted;
}

void write_status_and_wheels(JsonWriter& json, const StatusCounts& counts, const nav::WheelPrior* wheels,
                             int slip_events, const std::string& wheels_off_reason) {
  json.begin_object("status_counts");
  json.integer("TRACKING", counts.tracking);
  json.integer("DEGRADED", counts.degraded);
  json.integer("LOST", counts.lost);
  json.end_object();
  json.boolean("wheels_used", wheels != nullptr);
  if (wheels == nullptr) {
    json.string("wheels_off_reason", wheels_off_reason);
    json.null("wheel_slip_events");
    return;
  }
  const nav::WheelPriorCounters& prior = wheels->counters();
  const nav::WheelOdometryStats& odometry = wheels->odometry().stats();
  json.integer("wheel_slip_events", slip_events);
  json.integer("wheel_prior_frames", static_cast<long long>(prior.with_prior));
  json.integer("wheel_prior_missing", static_cast<long long>(prior.not_covered + prior.discontinuous + prior.wrong_order));
  json.integer("wheel_frames_integrated", static_cast<long long>(odometry.frames_integrated));
  json.integer("wheel_frames_missing", static_cast<long long>(odometry.frames_missing));
  json.integer("wheel_frames_malformed", static_cast<long long>(odometry.malformed));
  json.integer("wheel_timestamp_jumps",
               static_cast<long long>(odometry.timestamp_jumps_backward + odometry.timestamp_jumps_forward));
  json.integer("wheel_frames_dropped",
               static_cast<long long>(odometry.duplicates + odometry.out_of_order + odometry.implausible));
  json.integer("wheel_vision_disagreements", counts.disagreements);
  json.integer("wheel_overruled_frames", counts.wheels_trusted);
}

Percentiles percentiles(std::vector<double> values) {
  Percentiles result;
  if (values.empty()) return result;
  std::sort(values.begin(), values.end());
  const auto at = [&](double q) { return values[static_cast<std::size_t>(q * static_cast<double>(values.size() - 1) + 0.5)]; };
  result.median = at(0.5);
  result.p90 = at(0.9);
  result.max = values.back();
  return result;
}

void write_percentiles(JsonWriter& json, std::string_view key, const Percentiles& p) {
  json.begin_object(key).number("median", p.median).number("p90", p.p90).number("max", p.max).end_object();
}

void write_report_header(JsonWriter& json, std::string_view software_version, std::string_view command) {
  json.integer("format_version", kReportFormatVersion);
  json.string("software", "rankslam " + std::string(software_version));
  json.string("command", command);
}

FrameRecord frame_record(double stamp_s, const slam::FrameResult& result) {
  return {stamp_s,
          result.status,
          result.inliers,
          result.photometric_matches,
          result.photometric_inliers,
          result.geometric_matches,
          result.geometric_inliers,
          result.photometric_weight,
          result.wheels};
}

std::string frames_csv(const std::vector<FrameRecord>& records) {
  std::string text =
      "stamp,status,inliers,prior,compared,frame_distance_sq,window_distance_sq,disagree,vision_trusted,"
      "wheels_trusted,slip_event,photometric_matches,photometric_inliers,geometric_matches,geometric_inliers,"
      "photometric_weight,forward_residual_m,lateral_residual_m,yaw_residual_deg,height_residual_m,tilt_residual_deg\n";
  char line[320];
  for (const FrameRecord& r : records) {
    std::snprintf(line, sizeof line, "%.6f,%s,%d,%d,%d,%.3f,%.3f,%d,%d,%d,%d,%d,%d,%d,%d,%.3f,%.5f,%.5f,%.4f,%.5f,%.4f\n", r.stamp_s,
                  std::string(slam::to_string(r.status)).c_str(), r.inliers, r.wheels.prior_given ? 1 : 0,
                  r.wheels.compared ? 1 : 0, r.wheels.frame_distance_sq, r.wheels.window_distance_sq,
                  r.wheels.disagree ? 1 : 0, r.wheels.vision_trusted ? 1 : 0, r.wheels.wheels_trusted ? 1 : 0,
                  r.wheels.slip_event ? 1 : 0, r.photometric_matches, r.photometric_inliers, r.geometric_matches,
                  r.geometric_inliers, r.photometric_weight, r.wheels.forward_residual_m, r.wheels.lateral_residual_m,
                  r.wheels.yaw_residual_deg, r.wheels.height_residual_m, r.wheels.tilt_residual_deg);
    text += line;
  }
  return text;
}

bool is_false_closure(const RelativePoseError& error) {
  return error.has_ground_truth &&
         (error.translation_m > kFalseClosureTranslation_m || error.rotation_deg > kFalseClosureRotation_deg);
}

std::string loop_closures_csv(const std::vector<slam::LoopClosure>& closures,
                              const std::vector<RelativePoseError>& errors) {
  std::string text =
      "stored_stamp,current_stamp,tx,ty,tz,qx,qy,qz,qw,photometric_inliers,geometric_inliers,threshold,"
      "gt_translation_error_m,gt_rotation_error_deg,false_closure\n";
  char line[384];
  for (std::size_t i = 0; i < closures.size(); ++i) {
    const slam::LoopClosure& c = closures[i];
    const Eigen::Vector3d t = c.T_stored_current.translation();
    Eigen::Quaterniond q(c.T_stored_current.linear());
    if (q.w() < 0.0) q.coeffs() = -q.coeffs();
    const RelativePoseError* error = i < errors.size() && errors[i].has_ground_truth ? &errors[i] : nullptr;
    std::snprintf(line, sizeof line, "%.6f,%.6f,%.6f,%.6f,%.6f,%.6f,%.6f,%.6f,%.6f,%d,%d,%.1f,", c.stored_stamp_s,
                  c.current_stamp_s, t.x(), t.y(), t.z(), q.x(), q.y(), q.z(), q.w(), c.photometric_inliers,
                  c.geometric_inliers, c.threshold);
    text += line;
    if (error != nullptr) {
      std::snprintf(line, sizeof line, "%.4f,%.3f,%d\n", error->translation_m, error->rotation_deg,
                    is_false_closure(*error) ? 1 : 0);
    } else {
      std::snprintf(line, sizeof line, ",,\n");  // no ground truth: empty fields
    }
    text += line;
  }
  return text;
}

}  // namespace rankslam::eval
