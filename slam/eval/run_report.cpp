#include "rankslam/eval/run_report.hpp"

#include "rankslam/core/units.hpp"
#include "rankslam/eval/associate.hpp"

#include <cmath>

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
    case slam::FrameStatus::kFailed:
    case slam::FrameStatus::kLost: ++lost; break;
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
          result.wheels,
          Eigen::Isometry3d::Identity(),
          std::nullopt,
          std::nullopt,
          std::nullopt};
}

std::string frames_csv(const std::vector<FrameRecord>& records) {
  std::string text =
      "stamp,status,inliers,prior,compared,frame_distance_sq,window_distance_sq,disagree,vision_trusted,"
      "wheels_trusted,slip_event,photometric_matches,photometric_inliers,geometric_matches,geometric_inliers,"
      "photometric_weight,forward_residual_m,lateral_residual_m,yaw_residual_deg,height_residual_m,tilt_residual_deg,"
      "odom_x_m,odom_y_m,odom_yaw_deg,position_sigma_m,yaw_sigma_deg,gt_position_error_m,gt_yaw_error_deg\n";
  char line[384];
  for (const FrameRecord& r : records) {
    std::snprintf(line, sizeof line, "%.6f,%s,%d,%d,%d,%.3f,%.3f,%d,%d,%d,%d,%d,%d,%d,%d,%.3f,%.5f,%.5f,%.4f,%.5f,%.4f,", r.stamp_s,
                  std::string(slam::to_string(r.status)).c_str(), r.inliers, r.wheels.prior_given ? 1 : 0,
                  r.wheels.compared ? 1 : 0, r.wheels.frame_distance_sq, r.wheels.window_distance_sq,
                  r.wheels.disagree ? 1 : 0, r.wheels.vision_trusted ? 1 : 0, r.wheels.wheels_trusted ? 1 : 0,
                  r.wheels.slip_event ? 1 : 0, r.photometric_matches, r.photometric_inliers, r.geometric_matches,
                  r.geometric_inliers, r.photometric_weight, r.wheels.forward_residual_m, r.wheels.lateral_residual_m,
                  r.wheels.yaw_residual_deg, r.wheels.height_residual_m, r.wheels.tilt_residual_deg);
    text += line;
    const Eigen::Vector3d t = r.T_odom_base.translation();
    const double yaw_deg = rad_to_deg(std::atan2(r.T_odom_base.linear()(1, 0), r.T_odom_base.linear()(0, 0)));
    std::snprintf(line, sizeof line, "%.4f,%.4f,%.3f,", t.x(), t.y(), yaw_deg);
    text += line;
    // Unknown sigma, no ground truth: empty fields.
    const auto field = [&](const std::optional<double>& value, int decimals) {
      if (value) {
        std::snprintf(line, sizeof line, "%.*f", decimals, *value);
        text += line;
      }
    };
    field(r.sigmas ? std::optional<double>(r.sigmas->position_m) : std::nullopt, 5);
    text += ',';
    field(r.sigmas ? std::optional<double>(r.sigmas->yaw_deg) : std::nullopt, 4);
    text += ',';
    field(r.gt_position_error_m, 5);
    text += ',';
    field(r.gt_yaw_error_deg, 4);
    text += '\n';
  }
  return text;
}

SigmaCoverage sigma_coverage(const std::vector<FrameRecord>& records) {
  SigmaCoverage coverage;
  std::vector<double> position_sigma, position_error, yaw_sigma, yaw_error;
  int position_within = 0;
  int yaw_within = 0;
  // Half a count of the CAN signals: an error of zero at a sigma of zero is covered.
  constexpr double kPositionQuantum_m = 0.5e-4;
  constexpr double kYawQuantum_deg = 0.01;
  for (const FrameRecord& r : records) {
    if (!r.sigmas || !r.gt_position_error_m || !r.gt_yaw_error_deg) continue;
    ++coverage.frames;
    position_within += *r.gt_position_error_m <= 3.0 * r.sigmas->position_m + kPositionQuantum_m ? 1 : 0;
    yaw_within += std::abs(*r.gt_yaw_error_deg) <= 3.0 * r.sigmas->yaw_deg + kYawQuantum_deg ? 1 : 0;
    position_sigma.push_back(r.sigmas->position_m);
    position_error.push_back(*r.gt_position_error_m);
    yaw_sigma.push_back(r.sigmas->yaw_deg);
    yaw_error.push_back(std::abs(*r.gt_yaw_error_deg));
  }
  if (coverage.frames == 0) return coverage;
  coverage.position_coverage = static_cast<double>(position_within) / coverage.frames;
  coverage.yaw_coverage = static_cast<double>(yaw_within) / coverage.frames;
  coverage.median_position_sigma_m = percentiles(position_sigma).median;
  coverage.median_position_error_m = percentiles(position_error).median;
  coverage.median_yaw_sigma_deg = percentiles(yaw_sigma).median;
  coverage.median_yaw_error_deg = percentiles(yaw_error).median;
  return coverage;
}

void add_odom_errors(std::vector<FrameRecord>& records, const Trajectory& ground_truth,
                     const Eigen::Isometry3d& T_base_cam) {
  std::vector<double> record_stamps;
  record_stamps.reserve(records.size());
  for (const FrameRecord& r : records) record_stamps.push_back(r.stamp_s);
  std::vector<double> truth_stamps;
  truth_stamps.reserve(ground_truth.size());
  for (const auto& pose : ground_truth) truth_stamps.push_back(pose.stamp_s);
  std::vector<StampMatch> matches = associate(record_stamps, truth_stamps);
  if (matches.empty()) return;
  std::sort(matches.begin(), matches.end(), [](const StampMatch& a, const StampMatch& b) { return a.first_index < b.first_index; });
  // The odom frame is the base at the first frame: the ground truth relative to its pose there.
  // Matches are in stamp order; the first record must have a match for the frames to agree.
  if (matches.front().first_index != 0) return;
  const Eigen::Isometry3d T_cam_base = T_base_cam.inverse();
  const Eigen::Isometry3d T_truth_first_base = ground_truth[matches.front().second_index].T_world_cam * T_cam_base;
  for (const StampMatch& match : matches) {
    FrameRecord& r = records[match.first_index];
    const Eigen::Isometry3d truth = T_truth_first_base.inverse() * ground_truth[match.second_index].T_world_cam * T_cam_base;
    r.gt_position_error_m = (r.T_odom_base.translation() - truth.translation()).head<2>().norm();
    const Eigen::Matrix3d difference = truth.linear().transpose() * r.T_odom_base.linear();
    // The yaw of the difference about the odom z axis, (−180, 180].
    const Eigen::Matrix3d in_odom = truth.linear() * difference * truth.linear().transpose();
    r.gt_yaw_error_deg = rad_to_deg(std::atan2(in_odom(1, 0), in_odom(0, 0)));
  }
}

bool is_false_closure(const RelativePoseError& error) {
  return error.has_ground_truth &&
         (error.translation_m > kFalseClosureTranslation_m || error.rotation_deg > kFalseClosureRotation_deg);
}

std::vector<RelocalisationError> relocalisation_errors(const Trajectory& ground_truth, const AteResult& ate,
                                                       const std::vector<RelocalisationRecord>& records,
                                                       double max_difference_s) {
  std::vector<RelocalisationError> errors(records.size());
  for (std::size_t r = 0; r < records.size(); ++r) {
    const StampedPose* nearest = nullptr;
    for (const StampedPose& pose : ground_truth) {
      if (nearest == nullptr || std::abs(pose.stamp_s - records[r].stamp_s) < std::abs(nearest->stamp_s - records[r].stamp_s)) {
        nearest = &pose;
      }
    }
    if (nearest == nullptr || std::abs(nearest->stamp_s - records[r].stamp_s) > max_difference_s) continue;
    errors[r] = {true, (ate.T_gtworld_estworld * records[r].T_world_cam.translation() - nearest->T_world_cam.translation()).norm()};
  }
  return errors;
}

bool is_false_relocalisation(const RelocalisationError& error) {
  return error.has_ground_truth && error.translation_m > kFalseClosureTranslation_m;
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
