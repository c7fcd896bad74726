#include "rankslam/robust/scalar.hpp"

#include <cmath>

#include <Eigen/Core>

namespace rankslam::robust {

RobustStatus ScalarModel::set_values(std::span<const double> values) {
  values_ = {};
  for (const double v : values) {
    if (!std::isfinite(v) || v < 0.0) return RobustStatus::kInvalidInput;
  }
  values_ = values;
  return RobustStatus::kOk;
}

void ScalarModel::squared_residuals(const Params& /*params*/, int begin, int count,
                                    double* out) const {
  Eigen::Map<Eigen::ArrayXd> o(out, count);
  const Eigen::Map<const Eigen::ArrayXd> v(values_.data() + begin, count);
  if (kind_ == ScalarKind::kSquaredResidual) {
    o = v;
  } else {
    o = v.square();
  }
}

}  // namespace rankslam::robust
