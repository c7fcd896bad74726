// deploy/can/rankslam.dbc against the codec and against itself: a small DBC reader decodes the
// codec's frames the generic way (start bit, length, byte order, sign, factor, offset from the
// SG_ lines), so the database and the code cannot drift apart; and the database is checked for
// what a DBC tool would trip over (cycle times, ranges, value tables, overlaps, its version).

#include "rankslam/nav/pose_broadcaster.hpp"
#include "rankslam/nav/pose_frames.hpp"
#include "rankslam/nav/wheel_frame.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <fstream>
#include <map>
#include <regex>
#include <sstream>
#include <string>
#include <vector>

namespace rankslam::nav {
namespace {

struct Signal {
  unsigned start = 0;
  unsigned length = 0;
  bool little_endian = true;  // @1
  bool is_signed = false;
  double factor = 1.0;
  double offset = 0.0;
  double min = 0.0;
  double max = 0.0;
};

struct Message {
  std::string name;
  unsigned length = 0;
  std::map<std::string, Signal> signals;
  std::optional<long> cycle_time_ms;
  /// VAL_ tables: signal → raw value → description.
  std::map<std::string, std::map<long long, std::string>> values;
};

struct Database {
  std::string version;
  bool cycle_time_defined = false;
  std::map<std::uint32_t, Message> messages;
  /// Problems found while reading: unparsed SG_ lines, VAL_/BA_ of unknown messages or signals.
  std::vector<std::string> problems;
};

Database read_dbc(const std::string& path) {
  Database db;
  std::ifstream in(path);
  EXPECT_TRUE(in) << path;
  const std::regex version(R"(^VERSION \"(.*)\")");
  const std::regex message(R"(^BO_ (\d+) (\w+): (\d+) \w+)");
  const std::regex signal(
      R"(^ SG_ (\w+) : (\d+)\|(\d+)@([01])([+-]) \(([-0-9.eE+]+),([-0-9.eE+]+)\) \[([-0-9.eE+]+)\|([-0-9.eE+]+)\] \"[^\"]*\" [\w,]+\s*$)");
  const std::regex cycle_definition(R"(^BA_DEF_ BO_ \"GenMsgCycleTime\" INT 0 65535;)");
  const std::regex cycle_time(R"(^BA_ \"GenMsgCycleTime\" BO_ (\d+) (\d+);)");
  const std::regex value_table(R"(^VAL_ (\d+) (\w+) (.*);\s*$)");
  const std::regex value_entry(R"((-?\d+) \"([^\"]*)\")");
  std::string line;
  std::uint32_t current = 0;
  bool in_message = false;
  std::smatch m;
  while (std::getline(in, line)) {
    if (std::regex_search(line, m, version)) {
      db.version = m[1];
    } else if (std::regex_search(line, m, message)) {
      current = static_cast<std::uint32_t>(std::stoul(m[1]));
      db.messages[current].name = m[2];
      db.messages[current].length = static_cast<unsigned>(std::stoul(m[3]));
      in_message = true;
    } else if (line.rfind(" SG_ ", 0) == 0) {
      if (!in_message || !std::regex_search(line, m, signal)) {
        db.problems.push_back("unparsed signal line: " + line);
        continue;
      }
      Signal s;
      s.start = static_cast<unsigned>(std::stoul(m[2]));
      s.length = static_cast<unsigned>(std::stoul(m[3]));
      s.little_endian = m[4] == "1";
      s.is_signed = m[5] == "-";
      s.factor = std::stod(m[6]);
      s.offset = std::stod(m[7]);
      s.min = std::stod(m[8]);
      s.max = std::stod(m[9]);
      db.messages[current].signals[m[1]] = s;
    } else if (std::regex_search(line, m, cycle_definition)) {
      db.cycle_time_defined = true;
    } else if (std::regex_search(line, m, cycle_time)) {
      const auto id = static_cast<std::uint32_t>(std::stoul(m[1]));
      if (!db.messages.contains(id)) db.problems.push_back("cycle time of unknown message: " + line);
      db.messages[id].cycle_time_ms = std::stol(m[2]);
    } else if (std::regex_search(line, m, value_table)) {
      const auto id = static_cast<std::uint32_t>(std::stoul(m[1]));
      const std::string name = m[2];
      if (!db.messages.contains(id) || !db.messages[id].signals.contains(name)) {
        db.problems.push_back("value table of unknown signal: " + line);
        continue;
      }
      const std::string entries = m[3];
      for (std::sregex_iterator it(entries.begin(), entries.end(), value_entry), end; it != end; ++it) {
        db.messages[id].values[name][std::stoll((*it)[1])] = (*it)[2];
      }
    } else {
      in_message = in_message && !line.empty();
    }
  }
  return db;
}

const Database& dbc() {
  static const Database db = read_dbc(std::string(RANKSLAM_SOURCE_DIR) + "/deploy/can/rankslam.dbc");
  return db;
}

const Signal& signal_of(std::uint32_t id, const std::string& name) {
  static const Signal none;
  const auto message = dbc().messages.find(id);
  if (message == dbc().messages.end() || !message->second.signals.contains(name)) {
    ADD_FAILURE() << "no signal " << name << " in message " << id;
    return none;
  }
  return message->second.signals.at(name);
}

/// The raw value of `signal` in `frame` (little-endian, two's complement when signed).
long long raw_value(const hal::CanFrame& frame, const Signal& signal) {
  std::uint64_t word = 0;
  for (std::size_t i = 0; i < 8; ++i) word |= static_cast<std::uint64_t>(frame.data[i]) << (8U * i);
  const std::uint64_t mask = signal.length >= 64 ? ~std::uint64_t{0} : (std::uint64_t{1} << signal.length) - 1;
  const std::uint64_t raw = (word >> signal.start) & mask;
  if (signal.is_signed && (raw >> (signal.length - 1)) != 0) {
    return static_cast<long long>(raw) - static_cast<long long>(std::uint64_t{1} << signal.length);
  }
  return static_cast<long long>(raw);
}

/// The physical value the DBC says `frame` carries: raw · factor + offset.
double physical(const hal::CanFrame& frame, std::uint32_t id, const std::string& name) {
  const Signal& signal = signal_of(id, name);
  return static_cast<double>(raw_value(frame, signal)) * signal.factor + signal.offset;
}

/// The raw value's meaning from the VAL_ table ("" when it has none).
std::string described(const hal::CanFrame& frame, std::uint32_t id, const std::string& name) {
  const Message& message = dbc().messages.at(id);
  const auto table = message.values.find(name);
  if (table == message.values.end()) return {};
  const auto entry = table->second.find(raw_value(frame, signal_of(id, name)));
  return entry == table->second.end() ? std::string() : entry->second;
}

TEST(Dbc, ParsesWithoutProblems) {
  for (const std::string& problem : dbc().problems) ADD_FAILURE() << problem;
  EXPECT_GE(dbc().messages.size(), 8U);
}

TEST(Dbc, VersionIsTheSoftwareVersion) {
  // One version for the database, the package and `rankslam --version`: the project's.
  EXPECT_EQ(dbc().version, std::string("rankslam ") + RANKSLAM_VERSION);
}

TEST(Dbc, EveryMessageHasItsCycleTime) {
  EXPECT_TRUE(dbc().cycle_time_defined);
  const PoseOutputConfig defaults;
  const auto pose_ms = std::lround(1000.0 / defaults.pose_rate_hz);
  const auto heartbeat_ms = std::lround(1000.0 / defaults.heartbeat_rate_hz);
  for (const auto& [id, message] : dbc().messages) {
    ASSERT_TRUE(message.cycle_time_ms) << message.name;
    if (id >= kPoseXYYawId && id <= kPoseVelocityId) {
      EXPECT_EQ(*message.cycle_time_ms, pose_ms) << message.name;
    }
  }
  EXPECT_EQ(*dbc().messages.at(kHeartbeatId).cycle_time_ms, heartbeat_ms);
  EXPECT_EQ(*dbc().messages.at(0x101).cycle_time_ms, 10);
}

TEST(Dbc, SignalsFitTheirBitsAndDoNotOverlap) {
  for (const auto& [id, message] : dbc().messages) {
    EXPECT_EQ(message.length, 8U) << message.name;
    std::uint64_t used = 0;
    for (const auto& [name, s] : message.signals) {
      const std::string where = message.name + "." + name;
      EXPECT_TRUE(s.little_endian) << where;
      ASSERT_GE(s.length, 1U) << where;
      ASSERT_LE(s.start + s.length, 64U) << where;
      const std::uint64_t bits = (s.length == 64 ? ~std::uint64_t{0} : (std::uint64_t{1} << s.length) - 1) << s.start;
      EXPECT_EQ(used & bits, 0U) << where << " overlaps another signal";
      used |= bits;
      // The stated range is reachable: it lies within what the raw bits can carry.
      const double raw_min = s.is_signed ? -std::ldexp(1.0, static_cast<int>(s.length) - 1) : 0.0;
      const double raw_max = s.is_signed ? std::ldexp(1.0, static_cast<int>(s.length) - 1) - 1.0
                                         : std::ldexp(1.0, static_cast<int>(s.length)) - 1.0;
      const double lo = std::min(raw_min * s.factor, raw_max * s.factor) + s.offset;
      const double hi = std::max(raw_min * s.factor, raw_max * s.factor) + s.offset;
      const double tolerance = 1e-9 * std::max(1.0, std::abs(hi));
      EXPECT_LE(s.min, s.max) << where;
      EXPECT_GE(s.min, lo - tolerance) << where;
      EXPECT_LE(s.max, hi + tolerance) << where;
    }
  }
}

TEST(Dbc, ValueTablesNameRawValuesTheSignalsCanCarry) {
  int tables = 0;
  for (const auto& [id, message] : dbc().messages) {
    for (const auto& [name, table] : message.values) {
      ++tables;
      const Signal& s = message.signals.at(name);
      const long long raw_min = s.is_signed ? -(1LL << (s.length - 1)) : 0;
      const long long raw_max = s.is_signed ? (1LL << (s.length - 1)) - 1 : (1LL << s.length) - 1;
      for (const auto& [raw, text] : table) {
        EXPECT_GE(raw, raw_min) << message.name << "." << name;
        EXPECT_LE(raw, raw_max) << message.name << "." << name;
        EXPECT_FALSE(text.empty()) << message.name << "." << name;
      }
    }
  }
  // Status and every "unknown" raw value are described.
  EXPECT_EQ(dbc().messages.at(kPoseQualityId).values.at("Status").size(), 4U);
  EXPECT_EQ(dbc().messages.at(kHeartbeatId).values.at("Status").size(), 4U);
  for (const char* name : {"PositionSigma", "YawSigma", "InlierRatio"}) {
    EXPECT_TRUE(dbc().messages.at(kPoseQualityId).values.contains(name)) << name;
  }
  for (const char* name : {"Vx", "Vy", "YawRate"}) {
    EXPECT_TRUE(dbc().messages.at(kPoseVelocityId).values.contains(name)) << name;
  }
  EXPECT_GE(tables, 8);
}

TEST(Dbc, CodecIdentifiersAreTheDatabasesMessages) {
  const std::map<std::uint32_t, std::string> expected = {
      {0x101, "WheelTicks"},        {kPoseXYYawId, "PoseXYYaw"},         {kPoseZRollPitchId, "PoseZRollPitch"},
      {kPoseQualityId, "PoseQuality"}, {kMapOdomXYYawId, "MapOdomXYYaw"}, {kMapOdomZRollPitchId, "MapOdomZRollPitch"},
      {kPoseVelocityId, "PoseVelocity"}, {kHeartbeatId, "Heartbeat"}};
  for (const auto& [id, name] : expected) {
    ASSERT_TRUE(dbc().messages.contains(id)) << name;
    EXPECT_EQ(dbc().messages.at(id).name, name);
  }
  EXPECT_EQ(dbc().messages.size(), expected.size());
}

TEST(Dbc, PoseVelocityRoundTripsThroughTheDatabase) {
  const hal::CanFrame frame = encode_pose_velocity(PoseVelocity{0.305, -0.021, -12.34, 6}, 0);
  EXPECT_EQ(frame.id, kPoseVelocityId);
  EXPECT_NEAR(physical(frame, kPoseVelocityId, "Vx"), 0.305, 1e-9);
  EXPECT_NEAR(physical(frame, kPoseVelocityId, "Vy"), -0.021, 1e-9);
  EXPECT_NEAR(physical(frame, kPoseVelocityId, "YawRate"), -12.34, 1e-9);
  EXPECT_EQ(physical(frame, kPoseVelocityId, "CycleCounter"), 6.0);
  EXPECT_EQ(described(frame, kPoseVelocityId, "Vx"), "");
  // Saturated at the DBC's range, never on the unknown value.
  const hal::CanFrame fast = encode_pose_velocity(PoseVelocity{50.0, -50.0, 1000.0, 0}, 0);
  EXPECT_NEAR(physical(fast, kPoseVelocityId, "Vx"), signal_of(kPoseVelocityId, "Vx").max, 1e-9);
  EXPECT_NEAR(physical(fast, kPoseVelocityId, "Vy"), signal_of(kPoseVelocityId, "Vy").min, 1e-9);
  EXPECT_NEAR(physical(fast, kPoseVelocityId, "YawRate"), signal_of(kPoseVelocityId, "YawRate").max, 1e-9);
  const hal::CanFrame unknown = encode_pose_velocity(PoseVelocity{}, 0);
  for (const char* name : {"Vx", "Vy", "YawRate"}) EXPECT_EQ(described(unknown, kPoseVelocityId, name), "UNKNOWN") << name;
}

TEST(Dbc, PoseQualitySigmasRoundTripThroughTheDatabase) {
  PoseQuality quality;
  quality.status = PoseStatus::kDegraded;
  quality.position_sigma_m = 0.1234;
  quality.yaw_sigma_deg = 2.46;
  quality.inlier_percent = 57;
  hal::CanFrame frame = encode_pose_quality(quality, 0);
  EXPECT_NEAR(physical(frame, kPoseQualityId, "PositionSigma"), 0.1234, 1e-9);
  EXPECT_NEAR(physical(frame, kPoseQualityId, "YawSigma"), 2.46, 1e-9);
  EXPECT_EQ(physical(frame, kPoseQualityId, "InlierRatio"), 57.0);
  EXPECT_EQ(described(frame, kPoseQualityId, "Status"), "DEGRADED");
  EXPECT_EQ(described(frame, kPoseQualityId, "PositionSigma"), "");
  // Saturation: at the top of the DBC range, below the unknown value.
  quality.position_sigma_m = 100.0;
  quality.yaw_sigma_deg = 45.0;
  frame = encode_pose_quality(quality, 0);
  EXPECT_NEAR(physical(frame, kPoseQualityId, "PositionSigma"), signal_of(kPoseQualityId, "PositionSigma").max, 1e-9);
  EXPECT_NEAR(physical(frame, kPoseQualityId, "YawSigma"), signal_of(kPoseQualityId, "YawSigma").max, 1e-9);
  quality.position_sigma_m.reset();
  quality.yaw_sigma_deg.reset();
  quality.inlier_percent.reset();
  frame = encode_pose_quality(quality, 0);
  for (const char* name : {"PositionSigma", "YawSigma", "InlierRatio"}) {
    EXPECT_EQ(described(frame, kPoseQualityId, name), "UNKNOWN") << name;
  }
}

}  // namespace
}  // namespace rankslam::nav
