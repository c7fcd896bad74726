#include "rankslam/stereo/sequence.hpp"

#include <algorithm>
#include <cstdio>
#include <exception>

#include <opencv2/imgcodecs.hpp>

#include "rankslam/eval/json_writer.hpp"
#include "rankslam/eval/metrics.hpp"

namespace rankslam::stereo {
namespace {

double median(const std::vector<double>& values) { return eval::compute_error_stats(values).median; }

template <class Field>
std::vector<double> column(const std::vector<StereoFrameResult>& frames, Field field) {
  std::vector<double> values;
  values.reserve(frames.size());
  for (const auto& f : frames) values.push_back(static_cast<double>(f.*field));
  return values;
}

const char* layout_name(DatasetLayout layout) { return layout == DatasetLayout::euroc ? "euroc" : "kitti"; }

}  // namespace

eval::Result<StereoRun> run_stereo_sequence(const StereoDataset& dataset, const StereoOdometryConfig& config,
                                            const SequenceOptions& options,
                                            const std::function<void(int, const StereoFrameResult&)>& progress) {
  using R = eval::Result<StereoRun>;
  if (const auto field = config.validate(); !field.empty()) {
    return R::failure("stereo odometry configuration: " + std::string(field) + " is out of range");
  }
  StereoRun run;
  std::optional<Rectifier> rectifier;
  try {
    rectifier.emplace(dataset.calibration);
  } catch (const std::exception& error) {
    return R::failure(std::string("the stereo calibration cannot be rectified: ") + error.what());
  }
  run.rig = rectifier->rig();
  if (!(run.rig.baseline_m > 0.0 && run.rig.fx > 0.0)) {
    return R::failure("the rectified rig has no positive baseline: is cam1 the right camera?");
  }
  StereoOdometry odometry(run.rig, config);
  // Rectified pose → raw left camera: T_raw0_rawk = R_rect_leftᵀ · T_rect0_rectk · R_rect_left.
  Eigen::Isometry3d T_rect_raw = Eigen::Isometry3d::Identity();
  T_rect_raw.linear() = rectifier->R_rect_left();
  const Eigen::Isometry3d T_raw_rect = T_rect_raw.inverse();

  cv::Mat left, right, left_rect, right_rect;
  const std::size_t limit = options.max_frames > 0
                                ? std::min(dataset.frames.size(), static_cast<std::size_t>(options.max_frames))
                                : dataset.frames.size();
  run.trajectory.reserve(limit);
  run.frames.reserve(limit);
  for (std::size_t i = 0; i < limit; ++i) {
    const StereoFrameFiles& files = dataset.frames[i];
    left = cv::imread(files.left.string(), cv::IMREAD_GRAYSCALE);
    right = cv::imread(files.right.string(), cv::IMREAD_GRAYSCALE);
    if (!rectifier->rectify(left, right, left_rect, right_rect)) {
      ++run.unreadable_pairs;
      run.warnings.push_back((left.empty() ? files.left : files.right).string() +
                             ": unreadable or not of the calibrated size; pair skipped");
      continue;
    }
    const StereoFrameResult result = odometry.process(left_rect, right_rect);
    run.frames.push_back(result);
    run.trajectory.push_back({files.stamp_s, T_raw_rect * result.T_world_cam * T_rect_raw});
    if (progress) progress(static_cast<int>(i), result);
  }
  if (run.frames.empty()) return R::failure("no stereo pair could be read (" + std::to_string(run.unreadable_pairs) + " skipped)");
  return R::success(std::move(run));
}

StereoAccuracy evaluate_stereo_run(const StereoRun& run, const std::optional<eval::Trajectory>& ground_truth) {
  StereoAccuracy accuracy;
  if (!ground_truth) {
    accuracy.eval_missing_reason = "no ground truth";
    accuracy.segments_missing_reason = "no ground truth";
    return accuracy;
  }
  auto result = eval::evaluate(*ground_truth, run.trajectory);
  if (result) {
    accuracy.eval = std::move(result).value();
  } else {
    accuracy.eval_missing_reason = result.error();
  }
  eval::Trajectory still = run.trajectory;
  for (auto& pose : still) pose.T_world_cam = Eigen::Isometry3d::Identity();
  if (auto baseline = eval::compute_ate(*ground_truth, still); baseline) {
    accuracy.zero_motion_ate_rmse_m = baseline.value().translation_m.rmse;
  }
  auto segments = eval::compute_segment_errors(*ground_truth, run.trajectory);
  if (segments) {
    accuracy.segments = std::move(segments).value();
  } else {
    accuracy.segments_missing_reason = segments.error();
  }
  return accuracy;
}

std::string stereo_report_json(const StereoDataset& dataset, const std::filesystem::path& dataset_dir,
                               const StereoOdometryConfig& config, const StereoRun& run, const StereoAccuracy& accuracy) {
  eval::JsonWriter json;
  json.begin_object();
  json.string("dataset", dataset_dir.string());
  json.string("layout", layout_name(dataset.layout));
  json.string("ground_truth", dataset.ground_truth_file.string());
  json.string("features", features::feature_kind_name(config.features.kind));
  json.integer("max_features", config.max_features);
  json.string("motion", config.motion == MotionModel::p3p ? "p3p" : "rigid");
  json.boolean("bundle_adjustment", config.bundle_adjustment);
  json.integer("window_size", config.window_size);
  json.begin_object("rig");
  json.number("fx_px", run.rig.fx);
  json.number("fy_px", run.rig.fy);
  json.number("cx_px", run.rig.cx);
  json.number("cy_px", run.rig.cy);
  json.number("baseline_m", run.rig.baseline_m);
  json.end_object();
  int tracked = 0;
  for (const auto& f : run.frames) tracked += f.tracked ? 1 : 0;
  json.integer("frames", static_cast<long long>(run.frames.size()));
  json.integer("tracked_frames", tracked);
  json.integer("unreadable_pairs", run.unreadable_pairs);
  json.begin_object("median_per_frame");
  json.number("left_features", median(column(run.frames, &StereoFrameResult::left_features)));
  json.number("right_features", median(column(run.frames, &StereoFrameResult::right_features)));
  json.number("stereo_points", median(column(run.frames, &StereoFrameResult::stereo_points)));
  json.number("temporal_matches", median(column(run.frames, &StereoFrameResult::temporal_matches)));
  json.number("inliers", median(column(run.frames, &StereoFrameResult::inliers)));
  json.end_object();
  json.begin_object("ms_per_frame");
  json.number("median", median(column(run.frames, &StereoFrameResult::total_ms)));
  const auto total = column(run.frames, &StereoFrameResult::total_ms);
  json.number("max", total.empty() ? 0.0 : *std::max_element(total.begin(), total.end()));
  json.number("median_features", median(column(run.frames, &StereoFrameResult::features_ms)));
  json.number("median_matching", median(column(run.frames, &StereoFrameResult::matching_ms)));
  json.number("median_pose", median(column(run.frames, &StereoFrameResult::pose_ms)));
  json.number("median_ba", median(column(run.frames, &StereoFrameResult::ba_ms)));
  json.end_object();
  if (accuracy.eval) {
    const auto& ate = accuracy.eval->ate;
    json.begin_object("ate");
    json.integer("pairs", static_cast<long long>(ate.matches.size()));
    json.number("rmse_m", ate.translation_m.rmse);
    json.number("mean_m", ate.translation_m.mean);
    json.number("median_m", ate.translation_m.median);
    json.number("max_m", ate.translation_m.max);
    json.end_object();
    if (accuracy.eval->rpe) {
      const auto& rpe = *accuracy.eval->rpe;
      json.begin_object("rpe");
      json.number("delta_s", rpe.delta_s);
      json.integer("pairs", static_cast<long long>(rpe.pairs.size()));
      json.number("trans_rmse_m_per_s", rpe.translation_m_per_s.rmse);
      json.number("rot_rmse_deg_per_s", rpe.rotation_deg_per_s.rmse);
      json.end_object();
    } else {
      json.null("rpe");
      json.string("rpe_missing_reason", accuracy.eval->rpe_missing_reason);
    }
  } else {
    json.null("ate");
    json.null("rpe");
    json.string("accuracy_missing_reason", accuracy.eval_missing_reason);
  }
  json.number("zero_motion_ate_rmse_m", accuracy.zero_motion_ate_rmse_m);
  if (accuracy.segments) {
    json.begin_object("kitti_segments");
    json.integer("segments", accuracy.segments->segments);
    json.number("path_length_m", accuracy.segments->path_length_m);
    json.number("translation_percent", accuracy.segments->translation_percent);
    json.number("rotation_deg_per_m", accuracy.segments->rotation_deg_per_m);
    json.end_object();
  } else {
    json.null("kitti_segments");
    json.string("kitti_segments_missing_reason", accuracy.segments_missing_reason);
  }
  json.end_object();
  return json.str();
}

std::string format_stereo_summary(const StereoRun& run, const StereoAccuracy& accuracy) {
  std::string text;
  char line[256];
  int tracked = 0;
  for (const auto& f : run.frames) tracked += f.tracked ? 1 : 0;
  std::snprintf(line, sizeof line, "frames %zu  tracked %d  unreadable %d  median %.1f ms/frame  median features %.0f  stereo points %.0f  inliers %.0f\n",
                run.frames.size(), tracked, run.unreadable_pairs, median(column(run.frames, &StereoFrameResult::total_ms)),
                median(column(run.frames, &StereoFrameResult::left_features)),
                median(column(run.frames, &StereoFrameResult::stereo_points)),
                median(column(run.frames, &StereoFrameResult::inliers)));
  text += line;
  if (accuracy.eval) {
    std::snprintf(line, sizeof line, "ATE RMSE %.4f m over %zu poses", accuracy.eval->ate.translation_m.rmse,
                  accuracy.eval->ate.matches.size());
    text += line;
    if (accuracy.eval->rpe) {
      std::snprintf(line, sizeof line, "  RPE %.4f m/s %.3f deg/s", accuracy.eval->rpe->translation_m_per_s.rmse,
                    accuracy.eval->rpe->rotation_deg_per_s.rmse);
      text += line;
    }
    if (accuracy.zero_motion_ate_rmse_m) {
      std::snprintf(line, sizeof line, "  (zero-motion ATE %.4f m)", *accuracy.zero_motion_ate_rmse_m);
      text += line;
    }
    text += "\n";
  } else {
    text += "ATE n/a (" + accuracy.eval_missing_reason + ")\n";
  }
  if (accuracy.segments) {
    std::snprintf(line, sizeof line, "KITTI segments %d: %.2f %%  %.4f deg/m\n", accuracy.segments->segments,
                  accuracy.segments->translation_percent, accuracy.segments->rotation_deg_per_m);
    text += line;
  } else {
    text += "KITTI segments n/a (" + accuracy.segments_missing_reason + ")\n";
  }
  return text;
}

}  // namespace rankslam::stereo
