#include <array>
#include <cstdio>
#include <string>
#include <string_view>

#include "rankslam/eval/metrics.hpp"

namespace rankslam::eval {
namespace {

constexpr int kKeyWidth = 26;

void append_line(std::string& text, std::string_view key, std::string_view value) {
  std::string line(key);
  if (line.size() < static_cast<std::size_t>(kKeyWidth))
    line.resize(kKeyWidth, ' ');
  else
    line += ' ';
  text += line;
  text += value;
  text += '\n';
}

std::string fixed(double value, int decimals = 6) {
  std::array<char, 64> buffer{};
  std::snprintf(buffer.data(), buffer.size(), "%.*f", decimals, value);
  return buffer.data();
}

}  // namespace

Result<EvalResult> evaluate(const Trajectory& ground_truth, const Trajectory& estimate,
                            const EvalOptions& options) {
  Result<AteResult> ate = compute_ate(ground_truth, estimate, options.ate);
  if (!ate.ok()) return Result<EvalResult>::failure("ATE: " + ate.error());
  EvalResult result;
  result.ate = std::move(ate).value();
  Result<RpeResult> rpe = compute_rpe(ground_truth, estimate, options.rpe);
  if (rpe.ok()) {
    result.rpe = std::move(rpe).value();
  } else {
    result.rpe_missing_reason = rpe.error();
  }
  return Result<EvalResult>::success(std::move(result));
}

std::string format_eval_text(const EvalResult& result) {
  std::string text;
  const ErrorStats& ate = result.ate.translation_m;
  append_line(text, "pairs", std::to_string(ate.count));
  append_line(text, "ate.rmse_m", fixed(ate.rmse));
  append_line(text, "ate.mean_m", fixed(ate.mean));
  append_line(text, "ate.median_m", fixed(ate.median));
  append_line(text, "ate.std_m", fixed(ate.stddev));
  append_line(text, "ate.min_m", fixed(ate.min));
  append_line(text, "ate.max_m", fixed(ate.max));
  if (!result.rpe) {
    append_line(text, "rpe",
                "none (" +
                    (result.rpe_missing_reason.empty() ? std::string("not computed")
                                                       : result.rpe_missing_reason) +
                    ")");
    return text;
  }
  const RpeResult& rpe = *result.rpe;
  append_line(text, "rpe.delta_s", fixed(rpe.delta_s, 3));
  append_line(text, "rpe.pairs", std::to_string(rpe.translation_m_per_s.count));
  append_line(text, "rpe.trans_rmse_m_per_s", fixed(rpe.translation_m_per_s.rmse));
  append_line(text, "rpe.trans_mean_m_per_s", fixed(rpe.translation_m_per_s.mean));
  append_line(text, "rpe.trans_median_m_per_s", fixed(rpe.translation_m_per_s.median));
  append_line(text, "rpe.trans_max_m_per_s", fixed(rpe.translation_m_per_s.max));
  append_line(text, "rpe.rot_rmse_deg_per_s", fixed(rpe.rotation_deg_per_s.rmse));
  append_line(text, "rpe.rot_mean_deg_per_s", fixed(rpe.rotation_deg_per_s.mean));
  append_line(text, "rpe.rot_median_deg_per_s", fixed(rpe.rotation_deg_per_s.median));
  append_line(text, "rpe.rot_max_deg_per_s", fixed(rpe.rotation_deg_per_s.max));
  return text;
}

}  // namespace rankslam::eval
