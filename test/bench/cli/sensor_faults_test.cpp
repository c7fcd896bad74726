// Sensor and time faults, replayed through the rankslam executable: small simulated recordings
// edited the way a failing camera, a lost USB link or a stepping clock would leave them. The run
// must finish, say what happened (status counts, skipped frames, wheel counters, warnings) and
// never write a pose that is not a number.
#include "rankslam/eval/trajectory.hpp"
#include "rankslam/hal/calibration.hpp"
#include "rankslam/hal/interfaces.hpp"
#include "rankslam/nav/live_wheels.hpp"
#include "rankslam/nav/pose_frames.hpp"
#include "rankslam/nav/pose_output.hpp"
#include "rankslam/replay/recording.hpp"
#include "rankslam/replay/replay_can_bus.hpp"

#include "cli_support.hpp"

#include <gtest/gtest.h>

#include <opencv2/imgcodecs.hpp>

#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

namespace {

namespace fs = std::filesystem;

using namespace cli_test;

std::vector<std::string> lines_of(const fs::path& path) {
  std::ifstream in(path);
  std::vector<std::string> lines;
  for (std::string line; std::getline(in, line);) lines.push_back(line);
  return lines;
}

void write_lines(const fs::path& path, const std::vector<std::string>& lines) {
  std::ofstream out(path, std::ios::trunc);
  for (const std::string& line : lines) out << line << '\n';
}

std::vector<std::string> fields_of(const std::string& line) {
  std::istringstream in(line);
  std::vector<std::string> fields;
  for (std::string field; in >> field;) fields.push_back(field);
  return fields;
}

std::string stamp_text(double stamp_s) {
  char text[32];
  std::snprintf(text, sizeof text, "%.6f", stamp_s);
  return text;
}

// An integer field of report.json, e.g. "skipped_frames" or "LOST"; -1 when absent.
long json_integer(const std::string& report, const std::string& key) {
  const std::string quoted = "\"" + key + "\": ";
  const std::size_t at = report.find(quoted);
  if (at == std::string::npos) return -1;
  return std::atol(report.c_str() + at + quoted.size());
}

fs::path temp_root() { return fs::temp_directory_path() / ("rankslam_faults_" + std::to_string(::getpid())); }

fs::path temp_dir(const std::string& name) { return temp_root() / name; }

// This program's recordings and outputs go when it ends.
class RemoveTempRoot : public ::testing::Environment {
 public:
  void TearDown() override {
    std::error_code ignored;
    fs::remove_all(temp_root(), ignored);
  }
};
[[maybe_unused]] const auto* const kRemoveTempRoot = ::testing::AddGlobalTestEnvironment(new RemoveTempRoot);

// A simulated recording of `scene`, written once per test program and copied for each test.
fs::path simulated(const std::string& scene, int frames) {
  const fs::path dir = temp_dir("sim_" + scene + "_" + std::to_string(frames));
  if (!fs::exists(dir / "associations.txt")) {
    fs::create_directories(dir.parent_path());
    const CommandResult result = run("simulate " + scene + " -o " + dir.string() + " -n " + std::to_string(frames));
    EXPECT_EQ(result.exit_code, 0) << result.output;
  }
  return dir;
}

fs::path copy_of(const fs::path& recording, const std::string& name) {
  const fs::path copy = temp_dir(name);
  fs::remove_all(copy);
  fs::copy(recording, copy, fs::copy_options::recursive);
  return copy;
}

// The association lines (comments dropped), in file order.
std::vector<std::vector<std::string>> associations(const fs::path& recording) {
  std::vector<std::vector<std::string>> rows;
  for (const std::string& line : lines_of(recording / "associations.txt")) {
    if (!line.empty() && line[0] != '#') rows.push_back(fields_of(line));
  }
  return rows;
}

void write_associations(const fs::path& recording, const std::vector<std::vector<std::string>>& rows) {
  std::vector<std::string> lines;
  for (const auto& row : rows) {
    std::string line;
    for (const std::string& field : row) line += (line.empty() ? "" : " ") + field;
    lines.push_back(line);
  }
  write_lines(recording / "associations.txt", lines);
}

// Adds `delta_s` to the stamps of groundtruth.txt lines stamped at or after `from_s`, so the
// accuracy of a recording with shifted frame stamps is still measured on the same poses.
void shift_ground_truth(const fs::path& recording, double from_s, double delta_s) {
  std::vector<std::string> lines = lines_of(recording / "groundtruth.txt");
  for (std::string& line : lines) {
    if (line.empty() || line[0] == '#') continue;
    const std::size_t space = line.find(' ');
    const double stamp_s = std::stod(line.substr(0, space));
    if (stamp_s >= from_s - 1e-7) line = stamp_text(stamp_s + delta_s) + line.substr(space);
  }
  write_lines(recording / "groundtruth.txt", lines);
}

struct FrameRow {
  double stamp_s = 0.0;
  std::string status;
};

std::vector<FrameRow> frames_csv(const fs::path& out) {
  std::vector<FrameRow> rows;
  for (const std::string& line : lines_of(out / "frames.csv")) {
    if (line.empty() || line.rfind("stamp,", 0) == 0) continue;
    std::string spaced = line;
    std::replace(spaced.begin(), spaced.end(), ',', ' ');
    const std::vector<std::string> fields = fields_of(spaced);
    if (fields.size() < 2) continue;
    rows.push_back({std::stod(fields[0]), fields[1]});
  }
  return rows;
}

// Every pose in trajectory.txt is finite; returns how many there are.
std::size_t expect_finite_trajectory(const fs::path& out) {
  auto trajectory = rankslam::eval::read_tum_trajectory(out / "trajectory.txt");
  EXPECT_TRUE(trajectory.ok()) << (trajectory.ok() ? "" : trajectory.error());
  if (!trajectory.ok()) return 0;
  std::size_t not_finite = 0;
  for (const auto& pose : trajectory.value()) {
    if (!pose.T_world_cam.matrix().allFinite() || !std::isfinite(pose.stamp_s)) ++not_finite;
  }
  EXPECT_EQ(not_finite, 0U);
  // The text itself: a NaN written by hand would not parse, but say so plainly.
  const std::string text = slurp(out / "trajectory.txt");
  EXPECT_EQ(text.find("nan"), std::string::npos);
  EXPECT_EQ(text.find("inf"), std::string::npos);
  return trajectory.value().size();
}

// The status counts of report.json add up to its frames and match frames.csv.
void expect_counts_match_frames_csv(const std::string& report, const std::vector<FrameRow>& rows) {
  std::map<std::string, long> counted;
  for (const FrameRow& row : rows) ++counted[row.status];
  EXPECT_EQ(json_integer(report, "frames"), static_cast<long>(rows.size())) << report;
  EXPECT_EQ(json_integer(report, "TRACKING") + json_integer(report, "DEGRADED") + json_integer(report, "LOST"),
            static_cast<long>(rows.size()))
      << report;
  EXPECT_EQ(json_integer(report, "LOST"), counted["failed"]) << report;
  EXPECT_EQ(json_integer(report, "DEGRADED"), counted["wheels"]) << report;
}

// The statuses of frames.csv from `begin` on, one letter each (t tracking, f failed, w wheels,
// 1 first frame), for messages.
std::string status_letters(const std::vector<FrameRow>& rows, std::size_t begin = 0) {
  std::string letters;
  for (std::size_t i = begin; i < rows.size(); ++i) {
    letters += rows[i].status == "first-frame" ? '1' : rows[i].status[0];
  }
  return letters;
}

constexpr int kOfficeFrames = 90;
constexpr int kFaultBegin = 30;  // first frame the fault touches
constexpr int kFaultFrames = 15;

// The camera stops for 4.5 s: 15 frames never arrive and the stamps after them come 4 s later
// still. The run goes on; the frames after the gap register again.
TEST(SensorFaults, CameraGapOfSecondsInTheFrameStamps) {
  const fs::path recording = copy_of(simulated("office", kOfficeFrames), "gap");
  auto rows = associations(recording);
  ASSERT_EQ(rows.size(), static_cast<std::size_t>(kOfficeFrames));
  const double resume_s = std::stod(rows[kFaultBegin + kFaultFrames][0]);
  constexpr double kExtraGap_s = 4.0;
  rows.erase(rows.begin() + kFaultBegin, rows.begin() + kFaultBegin + kFaultFrames);
  for (std::size_t i = kFaultBegin; i < rows.size(); ++i) {
    rows[i][0] = stamp_text(std::stod(rows[i][0]) + kExtraGap_s);
    rows[i][2] = stamp_text(std::stod(rows[i][2]) + kExtraGap_s);
  }
  write_associations(recording, rows);
  shift_ground_truth(recording, resume_s, kExtraGap_s);

  const fs::path out = temp_dir("gap_out");
  const CommandResult result = run("replay " + recording.string() + " -o " + out.string() + " --quiet");
  ASSERT_EQ(result.exit_code, 0) << result.output;
  const std::string report = slurp(out / "report.json");
  const std::vector<FrameRow> frames = frames_csv(out);
  ASSERT_EQ(frames.size(), static_cast<std::size_t>(kOfficeFrames - kFaultFrames));
  expect_counts_match_frames_csv(report, frames);
  EXPECT_EQ(expect_finite_trajectory(out), frames.size());
  // The gap is in frames.csv as it was in the stamps.
  const double gap_s = frames[kFaultBegin].stamp_s - frames[kFaultBegin - 1].stamp_s;
  EXPECT_GT(gap_s, kExtraGap_s);
  std::printf("gap of %.2f s after frame %d; statuses %s; %s\n", gap_s, kFaultBegin, status_letters(frames).c_str(),
              result.output.substr(0, result.output.find('\n')).c_str());
  // Tracking again after the gap: the last 30 frames all register.
  EXPECT_EQ(status_letters(frames, frames.size() - 30), std::string(30, 't')) << status_letters(frames);
  EXPECT_LT(json_integer(report, "LOST"), kFaultFrames) << report;
}

// The images of 15 frames are missing from the recording: each is skipped with a warning naming
// it, counted in skipped_frames, and the frames after them register again.
TEST(SensorFaults, MissingImagesAreSkippedCountedAndTrackingResumes) {
  const fs::path recording = copy_of(simulated("office", kOfficeFrames), "missing");
  const auto rows = associations(recording);
  ASSERT_EQ(rows.size(), static_cast<std::size_t>(kOfficeFrames));
  for (int i = kFaultBegin; i < kFaultBegin + kFaultFrames; ++i) {
    // Odd frames lose the colour image, even ones the depth image.
    fs::remove(recording / rows[static_cast<std::size_t>(i)][i % 2 == 1 ? 1 : 3]);
  }
  const fs::path out = temp_dir("missing_out");
  const CommandResult result = run("replay " + recording.string() + " -o " + out.string() + " --quiet");
  ASSERT_EQ(result.exit_code, 0) << result.output;
  const std::string report = slurp(out / "report.json");
  EXPECT_EQ(json_integer(report, "skipped_frames"), kFaultFrames) << report;
  EXPECT_NE(result.output.find(rows[kFaultBegin + 1][1]), std::string::npos) << result.output;
  EXPECT_NE(result.output.find(rows[kFaultBegin][3]), std::string::npos) << result.output;
  const std::vector<FrameRow> frames = frames_csv(out);
  ASSERT_EQ(frames.size(), static_cast<std::size_t>(kOfficeFrames - kFaultFrames));
  expect_counts_match_frames_csv(report, frames);
  EXPECT_EQ(expect_finite_trajectory(out), frames.size());
  std::printf("statuses %s\n", status_letters(frames).c_str());
  EXPECT_EQ(status_letters(frames, frames.size() - 30), std::string(30, 't')) << status_letters(frames);
}

// Blanks `count` frames from `begin`: black colour (and IR) images, depth without a single
// measurement, as a camera whose sensor stopped delivering still sends frames.
void blank_frames(const fs::path& recording, int begin, int count) {
  const auto rows = associations(recording);
  for (int i = begin; i < begin + count; ++i) {
    const auto& row = rows[static_cast<std::size_t>(i)];
    const cv::Mat rgb = cv::imread((recording / row[1]).string(), cv::IMREAD_UNCHANGED);
    const cv::Mat depth = cv::imread((recording / row[3]).string(), cv::IMREAD_UNCHANGED);
    ASSERT_FALSE(rgb.empty() || depth.empty()) << row[1];
    ASSERT_TRUE(cv::imwrite((recording / row[1]).string(), cv::Mat::zeros(rgb.size(), rgb.type())));
    ASSERT_TRUE(cv::imwrite((recording / row[3]).string(), cv::Mat::zeros(depth.size(), depth.type())));
  }
  if (fs::exists(recording / "ir.txt")) {
    for (const std::string& line : lines_of(recording / "ir.txt")) {
      if (line.empty() || line[0] == '#') continue;
      const auto fields = fields_of(line);
      const double stamp_s = std::stod(fields[0]);
      if (stamp_s < std::stod(rows[static_cast<std::size_t>(begin)][0]) - 1e-4 ||
          stamp_s > std::stod(rows[static_cast<std::size_t>(begin + count - 1)][0]) + 1e-4) {
        continue;
      }
      const cv::Mat ir = cv::imread((recording / fields[1]).string(), cv::IMREAD_UNCHANGED);
      ASSERT_TRUE(cv::imwrite((recording / fields[1]).string(), cv::Mat::zeros(ir.size(), ir.type())));
    }
  }
}

// The camera delivers frames without content for half a second: without wheels they are LOST, and
// tracking resumes when the images come back.
TEST(SensorFaults, BlankFramesAreLostThenTrackingResumes) {
  const fs::path recording = copy_of(simulated("office", kOfficeFrames), "blank");
  blank_frames(recording, kFaultBegin, kFaultFrames);
  const fs::path out = temp_dir("blank_out");
  const CommandResult result = run("replay " + recording.string() + " -o " + out.string() + " --quiet");
  ASSERT_EQ(result.exit_code, 0) << result.output;
  const std::string report = slurp(out / "report.json");
  const std::vector<FrameRow> frames = frames_csv(out);
  ASSERT_EQ(frames.size(), static_cast<std::size_t>(kOfficeFrames));
  expect_counts_match_frames_csv(report, frames);
  EXPECT_EQ(expect_finite_trajectory(out), frames.size());
  std::printf("statuses %s\n", status_letters(frames).c_str());
  EXPECT_EQ(status_letters(frames).substr(kFaultBegin, kFaultFrames), std::string(kFaultFrames, 'f'));
  // The first frame back registers against the reference, which may take a frame or two.
  EXPECT_GE(json_integer(report, "LOST"), kFaultFrames) << report;
  EXPECT_LE(json_integer(report, "LOST"), kFaultFrames + 3) << report;
  EXPECT_EQ(status_letters(frames, frames.size() - 30), std::string(30, 't')) << status_letters(frames);
}

// The camera's clock steps back by 0.51 s at frame 40 and runs on from there: the recording
// cannot say in which order those frames were taken, so the replay plays them in stamp order, and
// says so.
TEST(TimeFaults, CameraStampsSteppingBackAreWarnedAboutAndNeverGiveANanPose) {
  const fs::path recording = copy_of(simulated("office", kOfficeFrames), "camera_back");
  auto rows = associations(recording);
  ASSERT_EQ(rows.size(), static_cast<std::size_t>(kOfficeFrames));
  constexpr double kStep_s = -0.51;
  for (std::size_t i = 40; i < rows.size(); ++i) {
    rows[i][0] = stamp_text(std::stod(rows[i][0]) + kStep_s);
    rows[i][2] = stamp_text(std::stod(rows[i][2]) + kStep_s);
  }
  write_associations(recording, rows);
  const fs::path out = temp_dir("camera_back_out");
  const CommandResult result = run("replay " + recording.string() + " -o " + out.string() + " --quiet");
  ASSERT_EQ(result.exit_code, 0) << result.output;
  EXPECT_NE(result.output.find("warning: " + (recording / "associations.txt").string()), std::string::npos)
      << result.output;
  EXPECT_NE(result.output.find("stamps go backwards 1 times"), std::string::npos) << result.output;
  const std::string report = slurp(out / "report.json");
  const std::vector<FrameRow> frames = frames_csv(out);
  ASSERT_EQ(frames.size(), static_cast<std::size_t>(kOfficeFrames));
  expect_counts_match_frames_csv(report, frames);
  EXPECT_EQ(expect_finite_trajectory(out), frames.size());
  for (std::size_t i = 1; i < frames.size(); ++i) EXPECT_GE(frames[i].stamp_s, frames[i - 1].stamp_s) << i;
  std::printf("statuses %s\n", status_letters(frames).c_str());
}

// Adds `delta_s` to the stamps of the can.log frames stamped at or after `from_s`: the CAN
// receiver's clock stepped there and ran on.
void step_can_log_clock(const fs::path& recording, double from_s, double delta_s) {
  std::vector<std::string> lines = lines_of(recording / "can.log");
  for (std::string& line : lines) {
    if (line.size() < 3 || line[0] != '(') continue;
    const std::size_t close = line.find(')');
    const double stamp_s = std::stod(line.substr(1, close - 1));
    if (stamp_s < from_s) continue;
    std::string stepped = "(";
    stepped += stamp_text(stamp_s + delta_s);
    stepped.append(line, close);
    line = std::move(stepped);
  }
  write_lines(recording / "can.log", lines);
}

// The largest step between consecutive poses of trajectory.txt, m.
double largest_step_m(const fs::path& out) {
  auto trajectory = rankslam::eval::read_tum_trajectory(out / "trajectory.txt");
  if (!trajectory.ok()) return -1.0;
  double largest = 0.0;
  for (std::size_t i = 1; i < trajectory.value().size(); ++i) {
    largest = std::max(largest, (trajectory.value()[i].T_world_cam.translation() -
                                 trajectory.value()[i - 1].T_world_cam.translation())
                                    .norm());
  }
  return largest;
}

constexpr int kCorridorFrames = 150;

struct WheelRun {
  std::string output;
  std::string report;
  std::vector<FrameRow> frames;
  double largest_step_m = 0.0;
};

WheelRun replay_corridor(const fs::path& recording, const std::string& name) {
  WheelRun run_result;
  const fs::path out = temp_dir(name);
  const CommandResult result = run("replay " + recording.string() + " -o " + out.string() + " --quiet");
  EXPECT_EQ(result.exit_code, 0) << result.output;
  run_result.output = result.output;
  run_result.report = slurp(out / "report.json");
  run_result.frames = frames_csv(out);
  EXPECT_EQ(run_result.frames.size(), static_cast<std::size_t>(kCorridorFrames)) << result.output;
  expect_counts_match_frames_csv(run_result.report, run_result.frames);
  EXPECT_EQ(expect_finite_trajectory(out), run_result.frames.size());
  run_result.largest_step_m = largest_step_m(out);
  std::printf("%s: wheel prior frames %ld, missing %ld, timestamp jumps %ld, frames dropped %ld, DEGRADED %ld, LOST "
              "%ld, largest step %.3f m; statuses %s\n",
              name.c_str(), json_integer(run_result.report, "wheel_prior_frames"),
              json_integer(run_result.report, "wheel_prior_missing"),
              json_integer(run_result.report, "wheel_timestamp_jumps"),
              json_integer(run_result.report, "wheel_frames_dropped"), json_integer(run_result.report, "DEGRADED"),
              json_integer(run_result.report, "LOST"), run_result.largest_step_m,
              status_letters(run_result.frames).c_str());
  return run_result;
}

// The CAN receiver's clock steps back by 2 s, or forward by 3 s, part-way through the corridor
// loop: the wheel frames after the step no longer line up with the camera's. The odometry must not
// integrate across a step (no pose jumps) and the frames without a prior are counted. A step
// forward restarts the integration and is counted; a step back is warned about when the log is
// read (it is replayed in stamp order, where the two stretches of frames interleave and the
// odometry leaves out the frames that do not follow on).
TEST(TimeFaults, CanLogStampsSteppingBackOrForwardAreCountedWithoutAPoseJump) {
  const fs::path source = simulated("corridor-loop", kCorridorFrames);
  const WheelRun clean = replay_corridor(source, "can_clean_out");
  ASSERT_GT(json_integer(clean.report, "wheel_prior_frames"), kCorridorFrames - 5) << clean.report;
  const double step_from_s = std::stod(associations(source)[60][0]);
  for (const double step_s : {-2.0, 3.0}) {
    const std::string name = step_s < 0.0 ? "can_back" : "can_forward";
    const fs::path recording = copy_of(source, name);
    step_can_log_clock(recording, step_from_s, step_s);
    const WheelRun stepped = replay_corridor(recording, name + "_out");
    EXPECT_GT(json_integer(stepped.report, "wheel_prior_missing"), 0) << stepped.report;
    if (step_s < 0.0) {
      EXPECT_NE(stepped.output.find("warning: " + (recording / "can.log").string() + ": stamps go backwards"),
                std::string::npos)
          << stepped.output;
      EXPECT_GT(json_integer(stepped.report, "wheel_frames_dropped"), 0) << stepped.report;
    } else {
      EXPECT_GT(json_integer(stepped.report, "wheel_timestamp_jumps"), 0) << stepped.report;
    }
    // A robot at walking pace moves centimetres between frames; a pose from wheels integrated over
    // a step of seconds would jump by far more.
    EXPECT_LT(stepped.largest_step_m, std::max(0.1, 2.0 * clean.largest_step_m)) << name;
  }
}

// The pose output while the camera is away: its heartbeat goes on at its rate, the pose cycles
// report LOST once the watchdog expires, and stop doing so when frames come back. Driven on the
// recording's own clock by the frame stamps of a recording with a 4.5 s gap, over the replay bus.
TEST(TimeFaults, PoseOutputKeepsItsHeartbeatThroughACameraGap) {
  const fs::path recording_dir = simulated("office", kOfficeFrames);
  rankslam::replay::Recording recording;
  ASSERT_EQ(rankslam::replay::open_recording(recording_dir, recording), "");
  std::vector<double> stamps_s;
  for (std::size_t i = 0; i < recording.frames.size(); ++i) {
    if (i >= static_cast<std::size_t>(kFaultBegin) && i < static_cast<std::size_t>(kFaultBegin + kFaultFrames)) continue;
    stamps_s.push_back(recording.frames[i].rgb_stamp_s + (i >= static_cast<std::size_t>(kFaultBegin) ? 4.0 : 0.0));
  }
  struct RecordingClock final : rankslam::hal::Clock {
    std::int64_t now = 0;
    [[nodiscard]] std::int64_t now_ns() const override { return now; }
  } clock;
  const auto to_ns = [&](double stamp_s) { return static_cast<std::int64_t>(std::llround((stamp_s - stamps_s[0]) * 1e9)); };
  rankslam::replay::ReplayCanBus bus(recording.can_frames, {});
  ASSERT_EQ(bus.open(), "");
  rankslam::nav::PoseMailbox mailbox;
  rankslam::nav::LiveWheels wheels;
  rankslam::nav::PoseOutputOptions options;
  clock.now = 0;
  rankslam::nav::PoseOutput output(options, bus, clock, mailbox, wheels);
  const std::int64_t gap_begin_ns = to_ns(stamps_s[kFaultBegin - 1]);
  const std::int64_t gap_end_ns = to_ns(stamps_s[kFaultBegin]);
  rankslam::nav::PoseOutputCounters at_gap_begin;
  rankslam::nav::PoseOutputCounters at_gap_end;
  std::size_t next = 0;
  constexpr std::int64_t kStep_ns = 5'000'000;
  for (clock.now = 0; clock.now <= to_ns(stamps_s.back()) + 100'000'000; clock.now += kStep_ns) {
    while (next < stamps_s.size() && to_ns(stamps_s[next]) <= clock.now) {
      rankslam::nav::PoseSample sample;
      sample.capture_ns = clock.now;
      sample.frame_sequence = static_cast<std::uint32_t>(next);
      mailbox.post(sample, nullptr, std::nullopt);
      ++next;
    }
    output.step();
    if (clock.now <= gap_begin_ns) at_gap_begin = output.pose_counters();
    if (clock.now < gap_end_ns) at_gap_end = output.pose_counters();
  }
  const rankslam::nav::PoseOutputCounters& total = output.pose_counters();
  const double gap_s = static_cast<double>(gap_end_ns - gap_begin_ns) * 1e-9;
  const auto heartbeats_in_gap = static_cast<double>(at_gap_end.heartbeats - at_gap_begin.heartbeats);
  const auto lost_in_gap = static_cast<double>(at_gap_end.lost_cycles - at_gap_begin.lost_cycles);
  std::printf("gap of %.2f s: %.0f heartbeats, %.0f of %llu pose cycles LOST; after it %llu more LOST\n", gap_s,
              heartbeats_in_gap, lost_in_gap,
              static_cast<unsigned long long>(at_gap_end.pose_cycles - at_gap_begin.pose_cycles),
              static_cast<unsigned long long>(total.lost_cycles - at_gap_end.lost_cycles));
  EXPECT_EQ(at_gap_begin.lost_cycles, 0U);
  EXPECT_NEAR(heartbeats_in_gap, gap_s * options.broadcast.heartbeat_rate_hz, 2.0);
  // LOST from the watchdog's expiry to the gap's end, at the pose rate.
  EXPECT_NEAR(lost_in_gap, (gap_s - options.broadcast.watchdog_timeout_s) * options.broadcast.pose_rate_hz, 3.0);
  EXPECT_EQ(total.lost_cycles, at_gap_end.lost_cycles);
}

}  // namespace
