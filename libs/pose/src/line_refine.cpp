// Geometric line cost and its Ceres Levenberg-Marquardt refinement (see line_refine.hpp).

#include "evpipe/pose/line_refine.hpp"

#include <ceres/ceres.h>
#include <ceres/manifold.h>

#include <Eigen/Geometry>

#include <cmath>
#include <limits>
#include <memory>

namespace evpipe::pose {
namespace {

constexpr double kMinResidualDepth_m = 1e-9;

// Both endpoints of one model segment against one measured image line: two residuals.
struct LineResidual {
  Eigen::Vector3d l;  // image line scaled by sqrt(weight)
  Eigen::Vector3d a_m;
  Eigen::Vector3d b_m;

  template <typename T>
  bool operator()(const T* q_xyzw, const T* t, T* residual) const {
    const Eigen::Map<const Eigen::Quaternion<T>> q(q_xyzw);
    const Eigen::Map<const Eigen::Matrix<T, 3, 1>> tt(t);
    const Eigen::Matrix<T, 3, 1> xa = q * a_m.cast<T>() + tt;
    const Eigen::Matrix<T, 3, 1> xb = q * b_m.cast<T>() + tt;
    // Reject steps through the camera plane: the projection folds there and the cost would be meaningless.
    if (xa.z() < T(kMinResidualDepth_m) || xb.z() < T(kMinResidualDepth_m)) {
      return false;
    }
    residual[0] = T(l.x()) * xa.x() / xa.z() + T(l.y()) * xa.y() / xa.z() + T(l.z());
    residual[1] = T(l.x()) * xb.x() / xb.z() + T(l.y()) * xb.y() / xb.z() + T(l.z());
    return true;
  }
};

bool finite_pose(const camera::Pose& T) {
  return T.q_cam_model.coeffs().allFinite() && T.t_cam_model_m.allFinite() && T.q_cam_model.norm() > 1e-12;
}

}  // namespace

Eigen::Vector3d image_line_n(const LineObservation& obs) {
  const Eigen::Vector3d l =
      Eigen::Vector3d(obs.a_n.x(), obs.a_n.y(), 1.0).cross(Eigen::Vector3d(obs.b_n.x(), obs.b_n.y(), 1.0));
  const double s = l.head<2>().norm();
  if (!(s > 0.0) || !std::isfinite(s)) {
    return Eigen::Vector3d::Zero();
  }
  return l / s;
}

double line_cost(std::span<const LineCorrespondence> lines, const camera::Pose& T_cam_model) {
  const Eigen::Matrix3d R = T_cam_model.rotation();
  const Eigen::Vector3d& t = T_cam_model.t_cam_model_m;
  double cost = 0.0;
  for (const LineCorrespondence& c : lines) {
    const Eigen::Vector3d l = image_line_n(c.image);
    for (const Eigen::Vector3d* p : {&c.model.a_m, &c.model.b_m}) {
      const Eigen::Vector3d x = R * *p + t;
      if (!(std::abs(x.z()) >= 1e-12)) {
        return std::numeric_limits<double>::infinity();
      }
      const double r = l.x() * x.x() / x.z() + l.y() * x.y() / x.z() + l.z();
      cost += c.weight * r * r;
    }
  }
  return std::isfinite(cost) ? cost : std::numeric_limits<double>::infinity();
}

double line_rms(std::span<const LineCorrespondence> lines, const camera::Pose& T_cam_model) {
  double w_sum = 0.0;
  for (const LineCorrespondence& c : lines) {
    w_sum += c.weight;
  }
  if (!(w_sum > 0.0)) {
    return std::numeric_limits<double>::infinity();
  }
  return std::sqrt(line_cost(lines, T_cam_model) / (2.0 * w_sum));
}

bool all_in_front(std::span<const LineCorrespondence> lines, const camera::Pose& T_cam_model, double min_depth_m) {
  const Eigen::Matrix3d R = T_cam_model.rotation();
  for (const LineCorrespondence& c : lines) {
    const double za = R.row(2).dot(c.model.a_m) + T_cam_model.t_cam_model_m.z();
    const double zb = R.row(2).dot(c.model.b_m) + T_cam_model.t_cam_model_m.z();
    if (!(za > min_depth_m) || !(zb > min_depth_m)) {
      return false;
    }
  }
  return true;
}

RefineResult refine_pose_lines(std::span<const LineCorrespondence> lines, const camera::Pose& T_init,
                               const RefineOptions& options) {
  RefineResult out;
  out.T_cam_model = T_init;
  if (lines.empty()) {
    out.message = "no lines to refine on";
    return out;
  }
  if (!finite_pose(T_init)) {
    out.message = "start pose is not finite";
    return out;
  }
  out.initial_cost = line_cost(lines, T_init);
  out.final_cost = out.initial_cost;
  out.rms_n = line_rms(lines, T_init);
  out.cheiral = all_in_front(lines, T_init, kMinResidualDepth_m);
  if (!out.cheiral || !std::isfinite(out.initial_cost)) {
    out.message = "start pose has model endpoints behind the camera";
    return out;
  }

  Eigen::Quaterniond q = T_init.q_cam_model.normalized();
  Eigen::Vector3d t = T_init.t_cam_model_m;
  ceres::Problem problem;
  for (const LineCorrespondence& c : lines) {
    const Eigen::Vector3d l = image_line_n(c.image);
    if (!c.model.a_m.allFinite() || !c.model.b_m.allFinite() || !l.allFinite() || !(c.weight > 0.0) ||
        !std::isfinite(c.weight)) {
      out.message = "a correspondence is not finite or has weight <= 0";
      return out;
    }
    auto* cost = new ceres::AutoDiffCostFunction<LineResidual, 2, 4, 3>(
        new LineResidual{l * std::sqrt(c.weight), c.model.a_m, c.model.b_m});
    ceres::LossFunction* loss = nullptr;
    if (options.loss == RefineOptions::Loss::huber) {
      loss = new ceres::HuberLoss(options.loss_scale_n);
    } else if (options.loss == RefineOptions::Loss::cauchy) {
      loss = new ceres::CauchyLoss(options.loss_scale_n);
    }
    problem.AddResidualBlock(cost, loss, q.coeffs().data(), t.data());
  }
  problem.SetManifold(q.coeffs().data(), new ceres::EigenQuaternionManifold());

  ceres::Solver::Options so;
  so.linear_solver_type = ceres::DENSE_QR;
  so.minimizer_type = ceres::TRUST_REGION;
  so.trust_region_strategy_type = ceres::LEVENBERG_MARQUARDT;
  so.max_num_iterations = options.max_iterations;
  so.function_tolerance = options.function_tolerance;
  so.gradient_tolerance = options.gradient_tolerance;
  so.parameter_tolerance = options.parameter_tolerance;
  so.num_threads = 1;
  so.logging_type = ceres::SILENT;
  so.minimizer_progress_to_stdout = false;
  ceres::Solver::Summary summary;
  ceres::Solve(so, &problem, &summary);

  camera::Pose refined;
  refined.q_cam_model = q.normalized();
  refined.t_cam_model_m = t;
  out.iterations = static_cast<int>(summary.iterations.size()) - 1;
  if (!finite_pose(refined) || summary.termination_type == ceres::FAILURE) {
    out.message = "refinement failed: " + summary.message;
    return out;
  }
  const double cost = line_cost(lines, refined);
  if (!std::isfinite(cost)) {
    out.message = "refinement produced a non-finite cost";
    return out;
  }
  // A robust loss can trade plain cost for inlier fit; without one, never return something worse than the start.
  if (options.loss == RefineOptions::Loss::none && cost > out.initial_cost) {
    out.ok = true;
    return out;
  }
  out.ok = true;
  out.T_cam_model = refined;
  out.final_cost = cost;
  out.rms_n = line_rms(lines, refined);
  out.cheiral = all_in_front(lines, refined, kMinResidualDepth_m);
  return out;
}

}  // namespace evpipe::pose
