#include "rankslam/graph/local_bundle.hpp"

#include "edge_residual.hpp"
#include "rankslam/core/lie.hpp"

#include <ceres/ceres.h>
#include <omp.h>

#include <exception>
#include <new>

namespace rankslam::graph {
namespace {

constexpr int kMaxLimit = 1 << 22;

// r = S · (q_w_c⁻¹ · (p_w − t_w_c) − point_cam).
class ObservationResidual {
 public:
  ObservationResidual(const Eigen::Vector3d& point_cam, const Eigen::Matrix3d& sqrt_information)
      : point_cam_(point_cam), sqrt_information_(sqrt_information) {}

  template <typename T>
  bool operator()(const T* q_w_c_data, const T* t_w_c_data, const T* p_w_data, T* residual_data) const {
    const Eigen::Map<const Eigen::Quaternion<T>> q_w_c(q_w_c_data);
    const Eigen::Map<const Eigen::Matrix<T, 3, 1>> t_w_c(t_w_c_data);
    const Eigen::Map<const Eigen::Matrix<T, 3, 1>> p_w(p_w_data);
    const Eigen::Matrix<T, 3, 1> p_c = q_w_c.conjugate() * (p_w - t_w_c);
    Eigen::Map<Eigen::Matrix<T, 3, 1>> residual(residual_data);
    residual = sqrt_information_.template cast<T>() * (p_c - point_cam_.template cast<T>());
    return true;
  }

 private:
  Eigen::Vector3d point_cam_;
  Eigen::Matrix3d sqrt_information_;
};

}  // namespace

std::string LocalBundle::configure(const LocalBundleCapacity& capacity) {
  const auto check = [](const char* name, int value, int min) -> std::string {
    if (value < min || value > kMaxLimit) {
      return std::string("local bundle ") + name + " must be in [" + std::to_string(min) + ", " +
             std::to_string(kMaxLimit) + "], got " + std::to_string(value);
    }
    return {};
  };
  for (const std::string& error : {check("max_poses", capacity.max_poses, 2), check("max_landmarks", capacity.max_landmarks, 1),
                                   check("max_observations", capacity.max_observations, 2),
                                   check("max_edges", capacity.max_edges, 0)}) {
    if (!error.empty()) return error;
  }
  capacity_ = capacity;
  pose_parameters_.assign(7 * static_cast<std::size_t>(capacity.max_poses), 0.0);
  landmark_parameters_.assign(3 * static_cast<std::size_t>(capacity.max_landmarks), 0.0);
  observations_.assign(static_cast<std::size_t>(capacity.max_observations), Observation{});
  priors_.assign(static_cast<std::size_t>(capacity.max_edges), Prior{});
  inlier_.assign(static_cast<std::size_t>(capacity.max_observations), 0);
  clear();
  return {};
}

void LocalBundle::clear() {
  pose_count_ = 0;
  landmark_count_ = 0;
  observation_count_ = 0;
  prior_count_ = 0;
}

int LocalBundle::add_pose(const Eigen::Isometry3d& T_world_cam) {
  if (pose_count_ >= capacity_.max_poses || !lie::is_finite_rigid(T_world_cam)) return -1;
  double* parameters = &pose_parameters_[7 * static_cast<std::size_t>(pose_count_)];
  Eigen::Map<Eigen::Quaterniond> q_world_cam(parameters);
  Eigen::Map<Eigen::Vector3d> t_world_cam(parameters + 4);
  q_world_cam = Eigen::Quaterniond(T_world_cam.linear()).normalized();
  t_world_cam = T_world_cam.translation();
  return pose_count_++;
}

int LocalBundle::add_landmark(const Eigen::Vector3d& p_world) {
  if (landmark_count_ >= capacity_.max_landmarks || !p_world.allFinite()) return -1;
  Eigen::Map<Eigen::Vector3d> position(&landmark_parameters_[3 * static_cast<std::size_t>(landmark_count_)]);
  position = p_world;
  return landmark_count_++;
}

bool LocalBundle::add_observation(int pose, int landmark, const Eigen::Vector3d& point_cam,
                                  const Eigen::Matrix3d& sqrt_information) {
  if (observation_count_ >= capacity_.max_observations || pose < 0 || pose >= pose_count_ || landmark < 0 ||
      landmark >= landmark_count_ || !point_cam.allFinite() || !sqrt_information.allFinite()) {
    return false;
  }
  observations_[static_cast<std::size_t>(observation_count_++)] = {pose, landmark, point_cam, sqrt_information};
  return true;
}

bool LocalBundle::add_edge(int from, int to, const Eigen::Isometry3d& T_from_to, const Matrix6d& information) {
  if (prior_count_ >= capacity_.max_edges || from < 0 || from >= pose_count_ || to < 0 || to >= pose_count_ ||
      from == to || !lie::is_finite_rigid(T_from_to)) {
    return false;
  }
  Prior& prior = priors_[static_cast<std::size_t>(prior_count_)];
  double log_det = 0.0;
  if (!lie::sqrt_information(0.5 * (information + information.transpose()), prior.sqrt_information, log_det)) {
    return false;
  }
  prior.from = from;
  prior.to = to;
  prior.T_from_to = T_from_to;
  ++prior_count_;
  return true;
}

Eigen::Isometry3d LocalBundle::pose(int index) const {
  const double* parameters = &pose_parameters_[7 * static_cast<std::size_t>(index)];
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = Eigen::Map<const Eigen::Quaterniond>(parameters).normalized().toRotationMatrix();
  T.translation() = Eigen::Map<const Eigen::Vector3d>(parameters + 4);
  return T;
}

Eigen::Vector3d LocalBundle::landmark(int index) const {
  return Eigen::Map<const Eigen::Vector3d>(&landmark_parameters_[3 * static_cast<std::size_t>(index)]);
}

Eigen::Vector3d LocalBundle::whitened_error(const Observation& observation) const {
  const Eigen::Isometry3d T_world_cam = pose(observation.pose);
  return observation.sqrt_information * (T_world_cam.inverse() * landmark(observation.landmark) - observation.point_cam);
}

LocalBundleSummary LocalBundle::solve(int max_iterations, double huber) {
  LocalBundleSummary result;
  if (pose_count_ < 2 || observation_count_ == 0) {
    result.message = "nothing to adjust";
    return result;
  }
  // Like the pose graph's solve: SuiteSparse and Eigen stay on this thread.
  omp_set_max_active_levels(0);
  ceres::Solver::Summary summary;
  double initial_cost = 0.0;
  const auto solve = [&]() -> bool {
    ceres::EigenQuaternionManifold quaternion_manifold;
    ceres::HuberLoss huber_loss(huber);
    ceres::Problem::Options problem_options;
    problem_options.manifold_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
    problem_options.loss_function_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
    ceres::Problem problem(problem_options);
    std::vector<ceres::ResidualBlockId> blocks(static_cast<std::size_t>(observation_count_));
    const auto pose_block = [&](int index) { return &pose_parameters_[7 * static_cast<std::size_t>(index)]; };
    for (int i = 0; i < observation_count_; ++i) {
      const Observation& observation = observations_[static_cast<std::size_t>(i)];
      double* camera = pose_block(observation.pose);
      auto* cost = new ceres::AutoDiffCostFunction<ObservationResidual, 3, 4, 3, 3>(
          new ObservationResidual(observation.point_cam, observation.sqrt_information));
      blocks[static_cast<std::size_t>(i)] = problem.AddResidualBlock(
          cost, &huber_loss, camera, camera + 4, &landmark_parameters_[3 * static_cast<std::size_t>(observation.landmark)]);
      problem.SetManifold(camera, &quaternion_manifold);
    }
    for (int i = 0; i < prior_count_; ++i) {
      const Prior& prior = priors_[static_cast<std::size_t>(i)];
      double* a = pose_block(prior.from);
      double* b = pose_block(prior.to);
      auto* cost = new ceres::AutoDiffCostFunction<EdgeResidual, 6, 4, 3, 4, 3>(
          new EdgeResidual(prior.T_from_to, prior.sqrt_information));
      problem.AddResidualBlock(cost, nullptr, a, a + 4, b, b + 4);
      problem.SetManifold(a, &quaternion_manifold);
      problem.SetManifold(b, &quaternion_manifold);
    }
    if (!problem.HasParameterBlock(pose_block(0))) return false;
    problem.SetParameterBlockConstant(pose_block(0));
    problem.SetParameterBlockConstant(pose_block(0) + 4);
    ceres::Solver::Options options;
    options.minimizer_type = ceres::TRUST_REGION;
    options.trust_region_strategy_type = ceres::LEVENBERG_MARQUARDT;
    options.linear_solver_type = ceres::DENSE_SCHUR;
    options.max_num_iterations = max_iterations;
    options.num_threads = 1;
    options.logging_type = ceres::SILENT;
    options.minimizer_progress_to_stdout = false;
    std::string options_error;
    if (!options.IsValid(&options_error)) return false;
    ceres::Solve(options, &problem, &summary);
    initial_cost = summary.initial_cost;
    if (!summary.IsSolutionUsable()) return true;
    // Observations the first solve leaves beyond the Huber threshold are mismatches (a repeated
    // texture, a depth read across an edge): their bounded pull still biases the poses, so the
    // solve is repeated without them.
    int removed = 0;
    for (int i = 0; i < observation_count_; ++i) {
      if (whitened_error(observations_[static_cast<std::size_t>(i)]).norm() <= huber) continue;
      problem.RemoveResidualBlock(blocks[static_cast<std::size_t>(i)]);
      ++removed;
    }
    if (removed > 0) ceres::Solve(options, &problem, &summary);
    return true;
  };
  try {
    if (!solve()) {
      result.message = "the first pose has no residuals";
      return result;
    }
  } catch (const std::bad_alloc&) {
    result.message = "out of memory in the solver";
    return result;
  } catch (const std::exception&) {
    result.message = "the solver threw";
    return result;
  }
  result.iterations = summary.num_successful_steps + summary.num_unsuccessful_steps;
  result.initial_cost = initial_cost;
  result.final_cost = summary.final_cost;
  if (!summary.IsSolutionUsable()) {
    result.message = "solver failed";
    return result;
  }
  if (!Eigen::Map<const Eigen::VectorXd>(pose_parameters_.data(), 7 * pose_count_).allFinite() ||
      !Eigen::Map<const Eigen::VectorXd>(landmark_parameters_.data(), 3 * landmark_count_).allFinite()) {
    result.message = "solver returned non-finite values";
    return result;
  }
  for (int i = 0; i < observation_count_; ++i) {
    const bool within = whitened_error(observations_[static_cast<std::size_t>(i)]).norm() <= huber;
    inlier_[static_cast<std::size_t>(i)] = within ? 1 : 0;
    result.inlier_observations += within ? 1 : 0;
  }
  result.ok = true;
  result.message = summary.termination_type == ceres::CONVERGENCE ? "converged" : "iteration limit reached";
  return result;
}

}  // namespace rankslam::graph
