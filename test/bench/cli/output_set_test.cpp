// The outputs of `rankslam replay` as a set: whatever stops a run (kill -9, SIGTERM, a full disk,
// an unwritable --out), --out holds wholly the previous run's files or wholly the new run's.
// RANKSLAM_EXE in the environment tests another build of the executable.
#include "cli_support.hpp"

#include <gtest/gtest.h>

#include <fcntl.h>
#include <poll.h>
#include <sys/inotify.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <csignal>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <map>
#include <optional>
#include <random>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

namespace {

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

/// README's "Outputs" of a replay.
const std::array<std::string, 6> kOutputs = {"trajectory.txt",    "map.ply",        "frames.csv",
                                             "loop_closures.csv", "trajectory.png", "report.json"};

/// The recording's frames; the runs alternate between all of them and fewer, so that every
/// output of one run differs from the other's.
constexpr int kRecordingFrames = 32;
constexpr int kShortRunFrames = 24;

std::string executable() {
  const char* override_exe = std::getenv("RANKSLAM_EXE");
  return override_exe != nullptr && *override_exe != '\0' ? override_exe : RANKSLAM_EXE;
}

using cli_test::slurp;

fs::path fresh_dir(const std::string& name) {
  const fs::path dir = fs::temp_directory_path() / name;
  fs::remove_all(dir);
  fs::create_directories(dir);
  return dir;
}

/// Starts rankslam with `arguments`, stdout and stderr on `output_fd`; `file_size_limit` is
/// RLIMIT_FSIZE with SIGXFSZ ignored, so that writes fail with EFBIG as on a full disk.
pid_t spawn(const std::vector<std::string>& arguments, int output_fd, std::optional<rlim_t> file_size_limit = std::nullopt) {
  std::vector<std::string> argv_strings{executable()};
  argv_strings.insert(argv_strings.end(), arguments.begin(), arguments.end());
  std::vector<char*> argv;
  for (std::string& a : argv_strings) argv.push_back(a.data());
  argv.push_back(nullptr);
  const pid_t pid = ::fork();
  if (pid != 0) return pid;
  ::dup2(output_fd, STDOUT_FILENO);
  ::dup2(output_fd, STDERR_FILENO);
  sigset_t none;
  sigemptyset(&none);
  ::sigprocmask(SIG_SETMASK, &none, nullptr);
  ::signal(SIGTERM, SIG_DFL);
  ::signal(SIGINT, SIG_DFL);
  if (file_size_limit) {
    ::signal(SIGXFSZ, SIG_IGN);
    rlimit limit{};
    ::getrlimit(RLIMIT_FSIZE, &limit);
    limit.rlim_cur = *file_size_limit;
    ::setrlimit(RLIMIT_FSIZE, &limit);
  }
  ::execv(argv[0], argv.data());
  ::_exit(127);
}

int wait_status(pid_t pid) {
  int status = 0;
  while (::waitpid(pid, &status, 0) < 0 && errno == EINTR) {
  }
  return status;
}

std::string describe_status(int status) {
  if (WIFEXITED(status)) return "exit " + std::to_string(WEXITSTATUS(status));
  if (WIFSIGNALED(status)) return "killed by signal " + std::to_string(WTERMSIG(status));
  return "status " + std::to_string(status);
}

struct Completed {
  int status = 0;
  std::string output;
};

std::vector<std::string> replay_arguments(const fs::path& recording, const fs::path& out, int frames) {
  return {"replay", recording.string(), "--out", out.string(), "--quiet", "--max-frames", std::to_string(frames)};
}

/// Runs rankslam to its end; its output through a pipe, which no file-size limit cuts short.
Completed run_to_end(const std::vector<std::string>& arguments, std::optional<rlim_t> file_size_limit = std::nullopt) {
  std::array<int, 2> pipe_fds{};
  Completed result;
  if (::pipe2(pipe_fds.data(), O_CLOEXEC) != 0) return result;
  const pid_t pid = spawn(arguments, pipe_fds[1], file_size_limit);
  ::close(pipe_fds[1]);
  std::array<char, 4096> buffer{};
  ssize_t n = 0;
  while ((n = ::read(pipe_fds[0], buffer.data(), buffer.size())) != 0) {
    if (n > 0) result.output.append(buffer.data(), static_cast<std::size_t>(n));
    if (n < 0 && errno != EINTR) break;
  }
  ::close(pipe_fds[0]);
  result.status = wait_status(pid);
  return result;
}

/// Starts rankslam with its output in the file `log`.
pid_t spawn_logged(const std::vector<std::string>& arguments, const fs::path& log) {
  const int log_fd = ::open(log.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  const pid_t pid = spawn(arguments, log_fd);
  ::close(log_fd);
  return pid;
}

/// The outputs as a reader of --out sees them: each file's bytes, nullopt when it is absent.
using OutputSet = std::map<std::string, std::optional<std::string>>;

OutputSet read_outputs(const fs::path& out) {
  OutputSet set;
  for (const std::string& name : kOutputs) {
    std::error_code ec;
    if (fs::is_regular_file(out / name, ec)) {
      set[name] = slurp(out / name);
    } else {
      set[name] = std::nullopt;
    }
  }
  return set;
}

struct ReportSummary {
  int frames = -1;
  bool interrupted = false;
};

std::optional<ReportSummary> summarize_report(const std::optional<std::string>& report) {
  if (!report || report->empty() || report->back() != '\n' || report->find("\"calibration\"") == std::string::npos) {
    return std::nullopt;
  }
  const std::string key = "\"frames\": ";
  const std::size_t at = report->find(key);
  if (at == std::string::npos) return std::nullopt;
  ReportSummary summary;
  summary.frames = std::atoi(report->c_str() + at + key.size());
  summary.interrupted = report->find("\"interrupted\": true") != std::string::npos;
  return summary;
}

/// The stamps (first column) of the records of a TUM trajectory or frames.csv (comments and the
/// CSV header skipped).
std::vector<std::string> stamps(const std::string& text) {
  std::vector<std::string> result;
  std::istringstream in(text);
  std::string line;
  while (std::getline(in, line)) {
    if (line.empty() || line[0] == '#' || line.rfind("stamp,", 0) == 0) continue;
    result.push_back(line.substr(0, line.find_first_of(" ,")));
  }
  return result;
}

/// Whether `set` is wholly the outputs of one run over the recording's first `frames` frames
/// (fewer when that run was interrupted): complete runs are byte-compared with `reference`, a
/// complete run's set (report.json holds timings and is checked for its frame count); an
/// interrupted run's files must agree with its report and none may be left from `previous`.
bool is_whole_set_of_run(const OutputSet& set, int frames, const OutputSet& reference, const OutputSet& previous) {
  for (const std::string& name : kOutputs) {
    if (!set.at(name)) return false;
  }
  const auto report = summarize_report(set.at("report.json"));
  if (!report) return false;
  if (!report->interrupted) {
    if (report->frames != frames) return false;
    for (const std::string& name : kOutputs) {
      if (name != "report.json" && set.at(name) != reference.at(name)) return false;
    }
    return true;
  }
  if (report->frames > frames) return false;
  const std::vector<std::string> reference_stamps = stamps(*reference.at("trajectory.txt"));
  const std::vector<std::string> trajectory_stamps = stamps(*set.at("trajectory.txt"));
  const std::vector<std::string> frame_stamps = stamps(*set.at("frames.csv"));
  if (trajectory_stamps.size() != static_cast<std::size_t>(report->frames) || frame_stamps != trajectory_stamps) {
    return false;
  }
  if (!std::equal(trajectory_stamps.begin(), trajectory_stamps.end(), reference_stamps.begin())) return false;
  if (set.at("map.ply")->rfind("ply\n", 0) != 0 || set.at("trajectory.png")->substr(1, 3) != "PNG") return false;
  const auto previous_report = summarize_report(previous.at("report.json"));
  // Files with a line or a drawn pose per frame; the map follows the key-frames, which runs of
  // different lengths may share.
  if (previous_report && previous_report->frames != report->frames) {
    for (const char* name : {"trajectory.txt", "frames.csv", "trajectory.png"}) {
      if (set.at(name) == previous.at(name)) return false;
    }
  }
  return true;
}

/// Which outputs equal the previous set's, for the message of a mixed set.
std::string describe_against(const OutputSet& set, const OutputSet& previous) {
  std::string text;
  for (const std::string& name : kOutputs) {
    text += "  " + name + ": " +
            (!set.at(name) ? "absent" : set.at(name) == previous.at(name) ? "previous" : "not previous") + "\n";
  }
  return text;
}

/// What other than one copy of each output --out holds: temporaries, staged or abandoned sets.
std::vector<std::string> leftovers(const fs::path& out) {
  std::vector<std::string> found;
  int regular_files = 0;
  for (const auto& entry : fs::recursive_directory_iterator(out)) {
    const std::string name = entry.path().filename().string();
    if (name.find(".tmp") != std::string::npos) found.push_back(entry.path().string());
    if (entry.symlink_status().type() == fs::file_type::regular) ++regular_files;
  }
  if (regular_files != static_cast<int>(kOutputs.size())) {
    found.push_back(std::to_string(regular_files) + " regular files under " + out.string() + " for " +
                    std::to_string(kOutputs.size()) + " outputs");
  }
  return found;
}

/// Reports files created directly in a directory (inotify IN_CREATE): the first one a replay
/// makes in --out starts its write phase.
class CreationWatch {
 public:
  explicit CreationWatch(const fs::path& dir) : fd_(::inotify_init1(IN_NONBLOCK | IN_CLOEXEC)) {
    if (fd_ >= 0) ::inotify_add_watch(fd_, dir.c_str(), IN_CREATE);
  }
  ~CreationWatch() {
    if (fd_ >= 0) ::close(fd_);
  }
  CreationWatch(const CreationWatch&) = delete;
  CreationWatch& operator=(const CreationWatch&) = delete;
  [[nodiscard]] bool ok() const { return fd_ >= 0; }

  /// Forgets the events so far.
  void drain() {
    std::array<char, 4096> buffer{};
    while (::read(fd_, buffer.data(), buffer.size()) > 0) {
    }
  }
  /// Whether a creation is pending, waiting up to `timeout_ms`.
  [[nodiscard]] bool created(int timeout_ms) {
    pollfd p{fd_, POLLIN, 0};
    return ::poll(&p, 1, timeout_ms) > 0;
  }

 private:
  int fd_;
};

class OutputSetTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    // ctest runs each test as its own process, some at once: each needs its own folder.
    root_ = fresh_dir("rankslam_cli_output_sets_" + std::to_string(::getpid()));
    recording_ = root_ / "recording";
    const auto simulated = run_to_end({"simulate", "office", "--out", recording_.string(), "--frames",
                                       std::to_string(kRecordingFrames)});
    ASSERT_EQ(describe_status(simulated.status), "exit 0") << simulated.output;
    // The known-good sets: one complete run of each length.
    for (const int frames : {kShortRunFrames, kRecordingFrames}) {
      const fs::path out = root_ / ("reference-" + std::to_string(frames));
      const auto done = run_to_end(replay_arguments(recording_, out, frames));
      ASSERT_EQ(describe_status(done.status), "exit 0") << done.output;
      references_[frames] = read_outputs(out);
    }
  }
  static void TearDownTestSuite() { fs::remove_all(root_); }

  void SetUp() override {
    if (references_.size() != 2) GTEST_SKIP() << "the recording or the reference runs failed";
  }

  static const OutputSet& reference(int frames) { return references_.at(frames); }

  /// A first complete run of `frames` into `out`: the previous set of what follows.
  static OutputSet complete_run(const fs::path& out, int frames) {
    const auto done = run_to_end(replay_arguments(recording_, out, frames));
    EXPECT_EQ(describe_status(done.status), "exit 0") << done.output;
    return read_outputs(out);
  }

  static fs::path root_;
  static fs::path recording_;
  static std::map<int, OutputSet> references_;
};

fs::path OutputSetTest::root_;
fs::path OutputSetTest::recording_;
std::map<int, OutputSet> OutputSetTest::references_;

TEST_F(OutputSetTest, AnUnwritableOutIsRefusedBeforeTheRunNamingIt) {
  const fs::path plain = root_ / "plain-file";
  std::ofstream(plain) << "a regular file\n";
  const fs::path fresh = root_ / "fresh-out";
  struct Case {
    fs::path out;
    std::optional<rlim_t> file_size_limit;
    const char* what;
  };
  // As root no permission bits refuse a write: a path through a regular file, a regular file, a
  // directory that takes no file (/proc), a disk with no room from the first byte.
  const std::vector<Case> cases = {{plain / "out", std::nullopt, "--out below a regular file"},
                                   {plain, std::nullopt, "--out naming a regular file"},
                                   {"/proc/self", std::nullopt, "--out a directory that takes no file"},
                                   {fresh, rlim_t{0}, "--out on a full disk"}};
  for (const Case& c : cases) {
    const auto result = run_to_end(replay_arguments(recording_, c.out, kRecordingFrames), c.file_size_limit);
    EXPECT_EQ(describe_status(result.status), "exit 4") << c.what << "\n" << result.output;
    EXPECT_NE(result.output.find(c.out.string()), std::string::npos) << c.what << "\n" << result.output;
    // Refused at start-up: no frame was processed, so there is no summary.
    EXPECT_EQ(result.output.find("frames " + std::to_string(kRecordingFrames)), std::string::npos)
        << c.what << "\n" << result.output;
  }
  EXPECT_TRUE(fs::is_empty(fresh));
}

TEST_F(OutputSetTest, AFullDiskKeepsThePreviousSetAndLeavesNoTemporaryFile) {
  const fs::path out = root_ / "full-disk";
  const OutputSet previous = complete_run(out, kShortRunFrames);
  // Room for the small files, not for map.ply (about 100 KB).
  const auto result = run_to_end(replay_arguments(recording_, out, kRecordingFrames), rlim_t{48 * 1024});
  EXPECT_EQ(describe_status(result.status), "exit 4") << result.output;
  EXPECT_NE(result.output.find((out / "map.ply").string()), std::string::npos) << result.output;
  EXPECT_NE(result.output.find("File too large"), std::string::npos) << result.output;
  EXPECT_TRUE(read_outputs(out) == previous) << describe_against(read_outputs(out), previous);
  EXPECT_EQ(leftovers(out), std::vector<std::string>{});
}

TEST_F(OutputSetTest, SigtermInTheWritePhaseFinishesTheSetAndExits130) {
  const fs::path out = root_ / "sigterm-write";
  const OutputSet previous = complete_run(out, kShortRunFrames);
  CreationWatch watch(out);
  ASSERT_TRUE(watch.ok()) << "inotify unavailable";
  const pid_t pid = spawn_logged(replay_arguments(recording_, out, kRecordingFrames), root_ / "sigterm.log");
  ASSERT_TRUE(watch.created(120000)) << "the replay created nothing in " << out;
  ::kill(pid, SIGTERM);
  const int status = wait_status(pid);
  EXPECT_EQ(describe_status(status), "exit 130") << slurp(root_ / "sigterm.log");
  const OutputSet now = read_outputs(out);
  EXPECT_TRUE(is_whole_set_of_run(now, kRecordingFrames, reference(kRecordingFrames), previous))
      << describe_against(now, previous);
  EXPECT_FALSE(summarize_report(now.at("report.json")).value_or(ReportSummary{}).interrupted);
}

TEST_F(OutputSetTest, FiftyKillsAndSigtermsAcrossRunAndWritePhaseLeaveOneWholeSet) {
  const fs::path out = root_ / "faults";
  // The first complete run, timed: when its write phase starts and how long it takes.
  fs::create_directories(out);
  CreationWatch watch(out);
  ASSERT_TRUE(watch.ok()) << "inotify unavailable";
  const Clock::time_point started = Clock::now();
  const pid_t first = spawn_logged(replay_arguments(recording_, out, kRecordingFrames), root_ / "first.log");
  ASSERT_TRUE(watch.created(120000)) << "the replay created nothing in " << out;
  const Clock::time_point write_start = Clock::now();
  ASSERT_EQ(describe_status(wait_status(first)), "exit 0") << slurp(root_ / "first.log");
  const auto loop_us = std::chrono::duration_cast<std::chrono::microseconds>(write_start - started).count();
  const auto write_us =
      std::max<long long>(1000, std::chrono::duration_cast<std::chrono::microseconds>(Clock::now() - write_start).count());
  OutputSet previous = read_outputs(out);
  int previous_frames = kRecordingFrames;

  std::mt19937 random(20261127);
  std::bernoulli_distribution in_write_phase(0.5);
  std::bernoulli_distribution use_sigkill(0.5);
  constexpr int kTrials = 50;
  int write_phase = 0;
  int loop_phase = 0;
  int finished_first = 0;
  int kept_previous = 0;
  int took_new = 0;
  std::vector<std::string> failures;
  for (int trial = 0; trial < kTrials; ++trial) {
    const int frames = previous_frames == kRecordingFrames ? kShortRunFrames : kRecordingFrames;
    const bool aim_at_write = in_write_phase(random);
    const int kill_signal = use_sigkill(random) ? SIGKILL : SIGTERM;
    const long long delay_us = std::uniform_int_distribution<long long>(0, aim_at_write ? write_us : loop_us)(random);
    const fs::path trial_log = root_ / "trial.log";
    watch.drain();
    const pid_t pid = spawn_logged(replay_arguments(recording_, out, frames), trial_log);
    bool exited = false;
    int status = 0;
    if (aim_at_write) {
      // Wait for the write phase to start, unless the run ends first.
      while (!watch.created(5)) {
        if (::waitpid(pid, &status, WNOHANG) == pid) {
          exited = true;
          break;
        }
      }
    }
    std::this_thread::sleep_for(std::chrono::microseconds(delay_us));
    if (!exited && ::waitpid(pid, &status, WNOHANG) == pid) exited = true;
    const bool landed_in_write = watch.created(0);
    if (!exited) {
      ::kill(pid, kill_signal);
      status = wait_status(pid);
    }
    const std::string where = "trial " + std::to_string(trial) + " (" + (kill_signal == SIGKILL ? "kill -9" : "SIGTERM") +
                              ", " + std::to_string(frames) + " frames, " +
                              (exited ? "after the run ended" : landed_in_write ? "in the write phase" : "in the run") +
                              ", " + describe_status(status) + ")";
    if (exited) {
      ++finished_first;
    } else if (landed_in_write) {
      ++write_phase;
    } else {
      ++loop_phase;
    }
    // SIGTERM is deferred once the loop runs: the process finishes its set and exits 130 (0 when
    // the signal came after the set was published and the exit code decided).
    if (!exited && kill_signal == SIGTERM && landed_in_write &&
        !(WIFEXITED(status) && (WEXITSTATUS(status) == 130 || WEXITSTATUS(status) == 0))) {
      failures.push_back(where + ": SIGTERM in the write phase did not end in exit 130\n" + slurp(trial_log));
    }
    const OutputSet now = read_outputs(out);
    const bool finished = WIFEXITED(status) && (WEXITSTATUS(status) == 0 || WEXITSTATUS(status) == 130);
    if (now == previous) {
      ++kept_previous;
      if (finished) failures.push_back(where + ": the run finished but its set was not published");
    } else if (is_whole_set_of_run(now, frames, reference(frames), previous)) {
      ++took_new;
      previous = now;
      previous_frames = summarize_report(now.at("report.json"))->frames;
    } else {
      failures.push_back(where + ": a mixed set\n" + describe_against(now, previous));
      // The next trials compare against what is there now, so one failure is not counted again.
      previous = now;
      previous_frames = summarize_report(now.at("report.json")).value_or(ReportSummary{}).frames;
    }
  }
  const auto last = run_to_end(replay_arguments(recording_, out, kRecordingFrames));
  EXPECT_EQ(describe_status(last.status), "exit 0") << last.output;
  const std::vector<std::string> left = leftovers(out);

  std::cout << kTrials << " interruptions: " << write_phase << " in the write phase, " << loop_phase
            << " in the run before it, " << finished_first << " after the run ended; the set in --out afterwards: "
            << kept_previous << " the previous run's, " << took_new << " the new run's, " << failures.size()
            << " failures\n";
  RecordProperty("write_phase", write_phase);
  RecordProperty("loop_phase", loop_phase);
  for (const std::string& failure : failures) ADD_FAILURE() << failure;
  EXPECT_EQ(left, std::vector<std::string>{}) << "left after one more complete run";
  // Both phases were hit often enough for the result to mean something.
  EXPECT_GE(write_phase, 10);
  EXPECT_GE(loop_phase, 10);
}

}  // namespace
