#include <sstream>
#include <string>

#include <gtest/gtest.h>

#include "rankslam/eval/metrics.hpp"
#include "test_support.hpp"

namespace rankslam::eval {
namespace {

/// The value printed after `key` at the start of a line, or "" when there is no such line.
std::string value_of(const std::string& text, const std::string& key) {
  std::istringstream lines(text);
  std::string line;
  while (std::getline(lines, line)) {
    std::istringstream fields(line);
    std::string first;
    fields >> first;
    if (first == key) {
      std::string rest;
      std::getline(fields >> std::ws, rest);
      return rest;
    }
  }
  return "";
}

Trajectory shifted(const Trajectory& trajectory, const Eigen::Vector3d& offset_m) {
  Trajectory result = trajectory;
  for (std::size_t k = 0; k < result.size(); ++k) {
    // Alternate the sign so the offset cannot be aligned away: every error is |offset|.
    result[k].T_world_cam.translation() += (k % 2 == 0 ? 1.0 : -1.0) * offset_m;
  }
  return result;
}

TEST(EvalReport, PrintsAteAndRpe) {
  const Trajectory truth = test::helix(10.0, 15.0, 100.0);
  const Trajectory estimate = shifted(truth, {0.0, 0.02, 0.0});
  const Result<EvalResult> result = evaluate(truth, estimate);
  ASSERT_TRUE(result.ok()) << result.error();
  ASSERT_TRUE(result.value().rpe.has_value()) << result.value().rpe_missing_reason;
  const std::string text = format_eval_text(result.value());

  EXPECT_EQ(value_of(text, "pairs"), std::to_string(truth.size()));
  EXPECT_NEAR(std::stod(value_of(text, "ate.rmse_m")), result.value().ate.translation_m.rmse, 1e-6);
  EXPECT_NEAR(std::stod(value_of(text, "ate.rmse_m")), 0.02, 1e-4);
  for (const char* key :
       {"ate.mean_m", "ate.median_m", "ate.std_m", "ate.min_m", "ate.max_m", "rpe.delta_s",
        "rpe.pairs", "rpe.trans_rmse_m_per_s", "rpe.trans_mean_m_per_s", "rpe.trans_median_m_per_s",
        "rpe.trans_max_m_per_s", "rpe.rot_rmse_deg_per_s", "rpe.rot_mean_deg_per_s",
        "rpe.rot_median_deg_per_s", "rpe.rot_max_deg_per_s"}) {
    EXPECT_FALSE(value_of(text, key).empty()) << key << " missing in\n" << text;
  }
  EXPECT_NEAR(std::stod(value_of(text, "rpe.trans_rmse_m_per_s")),
              result.value().rpe->translation_m_per_s.rmse, 1e-6);
  EXPECT_EQ(value_of(text, "rpe.delta_s"), "1.000");
}

TEST(EvalReport, ShortTrajectoryHasNoRpeAndSaysWhy) {
  const Trajectory truth = test::helix(10.0, 0.5, 100.0);
  const Result<EvalResult> result = evaluate(truth, truth);
  ASSERT_TRUE(result.ok()) << result.error();
  EXPECT_FALSE(result.value().rpe.has_value());
  const std::string text = format_eval_text(result.value());
  EXPECT_NE(value_of(text, "rpe").find("none (no pose pairs"), std::string::npos) << text;
  EXPECT_TRUE(value_of(text, "rpe.trans_rmse_m_per_s").empty());
  EXPECT_EQ(value_of(text, "ate.rmse_m"), "0.000000");
}

TEST(EvalReport, FailsWhenAteFails) {
  const Result<EvalResult> result =
      evaluate(test::helix(0.0, 2.0, 100.0), test::helix(50.0, 2.0, 30.0));
  ASSERT_FALSE(result.ok());
  EXPECT_EQ(result.error().rfind("ATE: ", 0), 0U) << result.error();
}

}  // namespace
}  // namespace rankslam::eval
