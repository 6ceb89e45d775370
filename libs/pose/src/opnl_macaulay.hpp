#pragma once
// Private to libs/pose: the polynomial core of OPnL. Finds the real critical points of the CGR quartic
// J(s) = v(s)ᵀ G v(s), v(s) = [1, s1, s2, s3, s1², s1s2, s1s3, s2², s2s3, s3²], i.e. the real solutions of the three
// cubics ∂J/∂s_k = 0, by the Macaulay-matrix null space + shift eigenvalue method (fast path: a fixed elimination
// template of the same matrix) (docs/algorithms.md, OPnL).

#include <Eigen/Core>

#include <vector>

namespace evpipe::pose::detail {

using Matrix10d = Eigen::Matrix<double, 10, 10>;
using Vector10d = Eigen::Matrix<double, 10, 1>;

/// v(s) above.
[[nodiscard]] Vector10d cgr_monomials(const Eigen::Vector3d& s);

struct CriticalPointStats {
  int rank{0};                 ///< numerical rank of the 105×120 Macaulay matrix (93 for generic data)
  double rank_ratio{0.0};      ///< |r_93| / |r_1| of its pivoted QR: small = the 27-dimensional null space is clean
  int complex_solutions{0};    ///< eigenvalue solutions rejected as complex
  bool robust_path{false};     ///< the elimination template was ill-conditioned: pivoted-QR null space used
  double template_rcond{0.0};  ///< reciprocal condition estimate of the template's 93×93 pivot block
};

/// Real critical points of J, each polished by `newton_steps` Newton steps on ∇J = 0. `imag_tol` is relative:
/// a solution is real when |Im s| <= imag_tol · (1 + |s|). Returns nothing (and stats->rank != 93) when the
/// Macaulay matrix does not have the generic rank; never throws, never returns non-finite values.
[[nodiscard]] std::vector<Eigen::Vector3d> cgr_critical_points(const Matrix10d& G, double imag_tol, int newton_steps,
                                                               CriticalPointStats* stats);

}  // namespace evpipe::pose::detail
