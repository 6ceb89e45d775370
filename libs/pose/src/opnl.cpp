// OPnL (Yu, Xu, Cheng 2020) in C++/Eigen: CGR parameterisation, algebraic cost J(s) = v(s)ᵀ G v(s), its three
// optimality cubics solved by the Macaulay/eigenvalue method (opnl_macaulay.cpp), from three pre-rotated model
// frames, selection by the geometric line cost, Ceres refinement and a 24-start fallback. docs/algorithms.md, OPnL.

#include "evpipe/pose/opnl.hpp"

#include "evpipe/pose/line_refine.hpp"
#include "opnl_macaulay.hpp"

#include <fmt/format.h>

#include <Eigen/Dense>
#include <Eigen/Geometry>

#include <algorithm>
#include <cmath>
#include <numbers>
#include <optional>

namespace evpipe::pose {
namespace {

using detail::Matrix10d;
using detail::Vector10d;

// Coefficients of n ᵀ R̄(s) P in the monomials v(s), with R̄(s) = (1 − sᵀs) I + 2 s sᵀ + 2 [s]×
// (= (1 + sᵀs) R for the CGR vector s).
Eigen::Matrix<double, 1, 10> cgr_row(const Eigen::Vector3d& n, const Eigen::Vector3d& P) {
  const Eigen::Vector3d pxn = P.cross(n);  // nᵀ [e_k]× P = (P × n)_k
  Eigen::Matrix<double, 1, 10> q;
  const double xx = n.x() * P.x();
  const double yy = n.y() * P.y();
  const double zz = n.z() * P.z();
  q << xx + yy + zz, 2.0 * pxn.x(), 2.0 * pxn.y(), 2.0 * pxn.z(), xx - yy - zz, 2.0 * (n.x() * P.y() + n.y() * P.x()),
      2.0 * (n.x() * P.z() + n.z() * P.x()), -xx + yy - zz, 2.0 * (n.y() * P.z() + n.z() * P.y()), -xx - yy + zz;
  return q;
}

// Checks the input; returns the reason when OPnL cannot give a unique answer for geometric reasons.
std::optional<std::string> validate(std::span<const LineCorrespondence> lines) {
  const std::size_t n = lines.size();
  for (std::size_t i = 0; i < n; ++i) {
    const LineCorrespondence& c = lines[i];
    if (!c.image.a_n.allFinite() || !c.image.b_n.allFinite()) {
      return fmt::format("line {}: image endpoint is not finite", i);
    }
    if (!c.model.a_m.allFinite() || !c.model.b_m.allFinite()) {
      return fmt::format("line {}: model endpoint is not finite", i);
    }
    if (!std::isfinite(c.weight) || !(c.weight > 0.0)) {
      return fmt::format("line {}: weight {} is not finite and > 0", i, c.weight);
    }
    if (!((c.image.b_n - c.image.a_n).norm() > 1e-12)) {
      return fmt::format("line {}: image segment has zero length", i);
    }
    if (!(c.model.length_m() >= camera::kMinSegmentLength_m)) {
      return fmt::format("line {}: model segment has zero length", i);
    }
  }
  // All model lines parallel: the scatter of the unit directions has rank 1 (translation along them and the
  // rotation about them are unobservable).
  Eigen::Matrix3d D = Eigen::Matrix3d::Zero();
  Eigen::Matrix3d A = Eigen::Matrix3d::Zero();
  Eigen::Vector3d b = Eigen::Vector3d::Zero();
  double extent_m = 0.0;
  for (const LineCorrespondence& c : lines) {
    const Eigen::Vector3d d = (c.model.b_m - c.model.a_m).normalized();
    D += d * d.transpose();
    const Eigen::Matrix3d Pp = Eigen::Matrix3d::Identity() - d * d.transpose();
    A += Pp;
    b += Pp * c.model.a_m;
    extent_m =
        std::max({extent_m, (c.model.a_m - lines[0].model.a_m).norm(), (c.model.b_m - lines[0].model.a_m).norm()});
  }
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> ed(D);
  if (ed.eigenvalues()(1) < 1e-12 * ed.eigenvalues()(2)) {
    return std::string("all model lines are parallel: the pose is not observable");
  }
  // All model lines through one point: the depth of that point is unobservable.
  const Eigen::Vector3d X = A.fullPivLu().solve(b);
  double max_dist_m = 0.0;
  for (const LineCorrespondence& c : lines) {
    const Eigen::Vector3d d = (c.model.b_m - c.model.a_m).normalized();
    const Eigen::Vector3d r = X - c.model.a_m;
    max_dist_m = std::max(max_dist_m, (r - d * d.dot(r)).norm());
  }
  if (X.allFinite() && max_dist_m <= 1e-9 * std::max(extent_m, 1e-9)) {
    return std::string("all model lines pass through one point: the depth is not observable");
  }
  // Image lines through one common point (parallel or concurrent 3D lines, or lines coplanar with the optical
  // centre): the interpretation-plane normals span only a plane, so the translation is not determined.
  Eigen::Matrix3d NtN = Eigen::Matrix3d::Zero();
  for (const LineCorrespondence& c : lines) {
    const Eigen::Vector3d l = image_line_n(c.image).normalized();
    NtN += l * l.transpose();
  }
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> en(NtN);
  if (!(en.eigenvalues()(0) > 1e-12 * en.eigenvalues()(2))) {
    return std::string("all image lines pass through one point: the translation is not observable");
  }
  return std::nullopt;
}

// The algebraic system of one (pre-rotated, centred) model frame: G and the translation map τ = C v(s).
struct FrameSystem {
  Matrix10d G;
  Eigen::Matrix<double, 3, 10> C;
};

FrameSystem build_system(std::span<const LineCorrespondence> lines, const std::vector<Eigen::Vector3d>& normals,
                         const Eigen::ColPivHouseholderQR<Eigen::MatrixXd>& n_qr, const Eigen::MatrixXd& N,
                         const Eigen::Matrix3d& R_k, const Eigen::Vector3d& centroid) {
  const Eigen::Index rows = static_cast<Eigen::Index>(2 * lines.size());
  Eigen::Matrix<double, Eigen::Dynamic, 10> Q(rows, 10);
  for (std::size_t i = 0; i < lines.size(); ++i) {
    const double sw = std::sqrt(lines[i].weight);
    const auto r = static_cast<Eigen::Index>(2 * i);
    Q.row(r) = sw * cgr_row(normals[i], R_k * (lines[i].model.a_m - centroid));
    Q.row(r + 1) = sw * cgr_row(normals[i], R_k * (lines[i].model.b_m - centroid));
  }
  // Rows: Q v(s) + N τ = 0 → τ = −N⁺ Q v(s) = C v(s); the residual is E v(s) with E = Q + N C.
  FrameSystem sys;
  sys.C = -n_qr.solve(Q);
  const Eigen::Matrix<double, Eigen::Dynamic, 10> E = Q + N * sys.C;
  sys.G = E.transpose() * E;
  return sys;
}

Eigen::Matrix3d rot_axis(int axis, double angle) {
  return Eigen::AngleAxisd(angle, Eigen::Vector3d::Unit(axis)).toRotationMatrix();
}

// The 24 rotations of the cube: signed permutation matrices with determinant +1.
std::vector<Eigen::Matrix3d> cube_rotations() {
  std::vector<Eigen::Matrix3d> out;
  const std::array<std::array<int, 3>, 6> perms{{{0, 1, 2}, {0, 2, 1}, {1, 0, 2}, {1, 2, 0}, {2, 0, 1}, {2, 1, 0}}};
  for (const auto& p : perms) {
    for (int signs = 0; signs < 8; ++signs) {
      Eigen::Matrix3d R = Eigen::Matrix3d::Zero();
      for (int r = 0; r < 3; ++r) {
        R(r, p[static_cast<std::size_t>(r)]) = ((signs >> r) & 1) != 0 ? -1.0 : 1.0;
      }
      if (R.determinant() > 0.0) {
        out.push_back(R);
      }
    }
  }
  return out;
}

bool same_pose(const camera::Pose& a, const camera::Pose& b, double tol) {
  const double angle_rad = camera::rotation_angle_deg(a, b) * std::numbers::pi / 180.0;
  const double dt = (a.t_cam_model_m - b.t_cam_model_m).norm();
  return angle_rad <= tol && dt <= tol * std::max(1e-9, a.t_cam_model_m.norm());
}

// 24-start LM: each start R is a cube rotation, t the linear least squares of nᵢᵀ(R P + t) = 0.
std::optional<RefineResult> multi_start(std::span<const LineCorrespondence> lines,
                                        const std::vector<Eigen::Vector3d>& normals,
                                        const Eigen::ColPivHouseholderQR<Eigen::MatrixXd>& n_qr,
                                        const Eigen::Vector3d& centroid, double radius_m, const OpnlOptions& options) {
  static const std::vector<Eigen::Matrix3d> starts = cube_rotations();
  RefineOptions ro = options.refine_options;
  ro.max_iterations = options.fallback_max_iterations;
  std::optional<RefineResult> best;
  const Eigen::Index rows = static_cast<Eigen::Index>(2 * lines.size());
  Eigen::VectorXd rhs(rows);
  for (const Eigen::Matrix3d& R : starts) {
    for (std::size_t i = 0; i < lines.size(); ++i) {
      const double sw = std::sqrt(lines[i].weight);
      rhs(static_cast<Eigen::Index>(2 * i)) = -sw * normals[i].dot(R * lines[i].model.a_m);
      rhs(static_cast<Eigen::Index>(2 * i + 1)) = -sw * normals[i].dot(R * lines[i].model.b_m);
    }
    camera::Pose start;
    start.q_cam_model = Eigen::Quaterniond(R);
    start.t_cam_model_m = n_qr.solve(rhs);
    if ((R * centroid + start.t_cam_model_m).z() < 0.0) {
      start.t_cam_model_m = -start.t_cam_model_m;
    }
    // LM keeps every endpoint in front of the camera, so it must start there: push the model forward if needed.
    double min_z = std::numeric_limits<double>::infinity();
    for (const LineCorrespondence& c : lines) {
      min_z =
          std::min({min_z, (R * c.model.a_m + start.t_cam_model_m).z(), (R * c.model.b_m + start.t_cam_model_m).z()});
    }
    if (!(min_z > 0.0)) {
      start.t_cam_model_m.z() += -min_z + radius_m;
    }
    if (!start.t_cam_model_m.allFinite()) {
      continue;
    }
    RefineResult r = refine_pose_lines(lines, start, ro);
    if (!r.ok || !r.cheiral || !all_in_front(lines, r.T_cam_model, options.min_depth_m)) {
      continue;
    }
    if (!best || r.final_cost < best->final_cost) {
      best = r;
    }
  }
  return best;
}

}  // namespace

OpnlResult solve_opnl(std::span<const LineCorrespondence> lines, const OpnlOptions& options) {
  OpnlResult out;
  const std::size_t n = lines.size();
  if (n < 3) {
    out.message = fmt::format("n = {} < 4 lines", n);
    return out;
  }
  if (auto why = validate(lines)) {
    out.message = *why;
    return out;
  }

  // Unit interpretation-plane normals and the translation system N (weighted rows, shared by all frames).
  std::vector<Eigen::Vector3d> normals(n);
  Eigen::MatrixXd N(static_cast<Eigen::Index>(2 * n), 3);
  Eigen::Vector3d centroid = Eigen::Vector3d::Zero();
  for (std::size_t i = 0; i < n; ++i) {
    normals[i] = image_line_n(lines[i].image).normalized();
    const double sw = std::sqrt(lines[i].weight);
    N.row(static_cast<Eigen::Index>(2 * i)) = sw * normals[i].transpose();
    N.row(static_cast<Eigen::Index>(2 * i + 1)) = sw * normals[i].transpose();
    centroid += lines[i].model.a_m + lines[i].model.b_m;
  }
  centroid /= static_cast<double>(2 * n);
  double radius_m = 0.0;
  for (const LineCorrespondence& c : lines) {
    radius_m = std::max({radius_m, (c.model.a_m - centroid).norm(), (c.model.b_m - centroid).norm()});
  }
  const Eigen::ColPivHouseholderQR<Eigen::MatrixXd> n_qr(N);

  // Three pre-rotated frames (π/2 about x, y, z, about the centroid): at least one is far from the CGR
  // singularity at 180°, whatever the true rotation. Candidates of all three are pooled.
  out.macaulay_rank_min = options.algebraic ? 1 << 20 : 0;
  for (int axis = 0; axis < 3 && options.algebraic; ++axis) {
    const Eigen::Matrix3d R_k = rot_axis(axis, std::numbers::pi / 2.0);
    const FrameSystem sys = build_system(lines, normals, n_qr, N, R_k, centroid);
    detail::CriticalPointStats stats;
    const std::vector<Eigen::Vector3d> sols =
        detail::cgr_critical_points(sys.G, options.imag_tol, options.newton_steps, &stats);
    out.macaulay_rank_min = std::min(out.macaulay_rank_min, stats.rank);
    out.robust_solves += stats.robust_path ? 1 : 0;
    const Eigen::Quaterniond q_k(R_k);
    for (const Eigen::Vector3d& s : sols) {
      const double h = 1.0 + s.squaredNorm();
      // CGR s = q_vec / q_w.
      const Eigen::Quaterniond q_frame = Eigen::Quaterniond(1.0, s.x(), s.y(), s.z()).normalized();
      const Eigen::Vector3d t_frame = sys.C * detail::cgr_monomials(s) / h;
      OpnlCandidate cand;
      cand.T_cam_model.q_cam_model = (q_frame * q_k).normalized();
      cand.T_cam_model.t_cam_model_m = t_frame - cand.T_cam_model.q_cam_model * centroid;
      if (!cand.T_cam_model.q_cam_model.coeffs().allFinite() || !cand.T_cam_model.t_cam_model_m.allFinite()) {
        continue;
      }
      if (!all_in_front(lines, cand.T_cam_model, options.min_depth_m)) {
        continue;
      }
      cand.cost = line_cost(lines, cand.T_cam_model);
      if (std::isfinite(cand.cost)) {
        out.candidates.push_back(cand);
      }
    }
  }
  std::sort(out.candidates.begin(), out.candidates.end(),
            [](const OpnlCandidate& a, const OpnlCandidate& b) { return a.cost < b.cost; });
  std::vector<OpnlCandidate> unique;
  for (const OpnlCandidate& c : out.candidates) {
    const bool dup = std::any_of(unique.begin(), unique.end(), [&](const OpnlCandidate& u) {
      return same_pose(u.T_cam_model, c.T_cam_model, options.duplicate_tol);
    });
    if (!dup) {
      unique.push_back(c);
    }
  }
  out.candidates = std::move(unique);

  bool have = false;
  double best_cost = std::numeric_limits<double>::infinity();
  if (!out.candidates.empty()) {
    have = true;
    out.T_cam_model = out.candidates.front().T_cam_model;
    best_cost = out.candidates.front().cost;
    if (options.refine) {
      const RefineResult r = refine_pose_lines(lines, out.T_cam_model, options.refine_options);
      if (r.ok && r.cheiral && all_in_front(lines, r.T_cam_model, options.min_depth_m) &&
          (r.final_cost <= best_cost || options.refine_options.loss != RefineOptions::Loss::none)) {
        out.T_cam_model = r.T_cam_model;
        best_cost = r.final_cost;
      }
    }
  }

  const bool ill_conditioned = options.algebraic && out.macaulay_rank_min != 93;
  const double rms = have ? std::sqrt(best_cost / (2.0 *
                                                   [&] {
                                                     double w = 0.0;
                                                     for (const LineCorrespondence& c : lines) {
                                                       w += c.weight;
                                                     }
                                                     return w;
                                                   }()))
                          : std::numeric_limits<double>::infinity();
  if ((options.fallback || !options.algebraic) && (!have || ill_conditioned || !(rms <= options.fallback_rms_n))) {
    if (auto fb = multi_start(lines, normals, n_qr, centroid, radius_m, options)) {
      // A relative margin: the fallback often reaches the same minimum, and round-off must not decide.
      if (!have || fb->final_cost < best_cost * (1.0 - 1e-6)) {
        have = true;
        out.used_fallback = true;
        out.T_cam_model = fb->T_cam_model;
        best_cost = fb->final_cost;
        out.candidates.insert(out.candidates.begin(), OpnlCandidate{fb->T_cam_model, fb->final_cost});
      }
    }
  }

  if (!have) {
    out.T_cam_model = camera::Pose::identity();
    out.message = "no real solution with the model in front of the camera";
    return out;
  }
  if (!out.T_cam_model.q_cam_model.coeffs().allFinite() || !out.T_cam_model.t_cam_model_m.allFinite()) {
    out.T_cam_model = camera::Pose::identity();
    out.candidates.clear();
    out.message = "numerical failure: non-finite pose";
    return out;
  }
  out.rms_n = line_rms(lines, out.T_cam_model);
  if (n == 3) {
    out.message = "n = 3 < 4 lines: the pose is ambiguous (P3L has up to 8 solutions); candidates are returned";
    return out;
  }
  out.ok = true;
  return out;
}

}  // namespace evpipe::pose
