// The polynomial core of OPnL: real critical points of J(s) = v(s)ᵀ G v(s) (see opnl_macaulay.hpp).
//
// The three half-gradient cubics f_k = v(s)ᵀ G ∂v/∂s_k (20 monomials of degree <= 3 each) are multiplied by every
// monomial of degree <= 4, giving the 105×120 Macaulay matrix M over the 120 monomials of degree <= 7 (the
// regularity degree of three cubics, 3·(3−1)+1). For generic data rank M = 93, and its null space is spanned by
// the monomial vectors of the 27 (Bézout) solutions. Null space Z from a column-pivoted QR of Mᵀ; with
// Z_lo = its rows for the 84 monomials of degree <= 6 and Z_sh the rows of g·m for a fixed linear form g,
// Z_sh = Z_lo A with A similar to diag(g(s_j)); the eigenvectors of A give Z_lo V = the monomial vectors.

#include "opnl_macaulay.hpp"

#include <Eigen/Dense>
#include <Eigen/Eigenvalues>

#include <array>
#include <cmath>
#include <complex>
#include <random>

namespace evpipe::pose::detail {
namespace {

constexpr int kMaxDeg = 7;
constexpr int kMonomials7 = 120;  // degree <= 7
constexpr int kMonomials6 = 84;   // degree <= 6
constexpr int kMonomials4 = 35;   // degree <= 4
constexpr int kMonomials3 = 20;   // degree <= 3
constexpr int kSolutions = 27;    // Bézout number 3·3·3
constexpr int kRows = 3 * kMonomials4;

// The shift's linear form g = Σ a_k s_k: fixed irrational-looking weights, so that two distinct solutions give
// the same eigenvalue only on a measure-zero set (deterministic runs, unlike a random draw).
constexpr std::array<double, 3> kShift{0.7548776662466927, 0.5698402909980532, 0.3247179572447460};

struct GradTerm {
  int i;     // index in v of the G row
  int j;     // index in v of the G column
  double c;  // derivative coefficient
  int mono;  // resulting cubic monomial (index < 20)
};

// Monomial bookkeeping, built once: graded order (degree, then descending exponent of s1, then of s2), so the
// first 4/10/20/35/84/120 monomials are those of degree <= 1/2/3/4/6/7 and v(s) is the first 10.
struct Tables {
  std::array<std::array<int, 3>, kMonomials7> expo{};
  std::array<std::array<std::array<int, kMaxDeg + 1>, kMaxDeg + 1>, kMaxDeg + 1> idx{};
  std::array<std::vector<GradTerm>, 3> grad;
  std::array<std::array<int, kMonomials3>, kMonomials4> shift{};  // column of (deg<=4 monomial)·(cubic monomial)
  std::array<std::array<int, 3>, kMonomials6> mul{};              // index of s_k · (deg<=6 monomial)

  Tables() {
    for (auto& a : idx) {
      for (auto& b : a) {
        b.fill(-1);
      }
    }
    int n = 0;
    for (int d = 0; d <= kMaxDeg; ++d) {
      for (int a = d; a >= 0; --a) {
        for (int b = d - a; b >= 0; --b) {
          const int c = d - a - b;
          expo[static_cast<std::size_t>(n)] = {a, b, c};
          idx[static_cast<std::size_t>(a)][static_cast<std::size_t>(b)][static_cast<std::size_t>(c)] = n;
          ++n;
        }
      }
    }
    for (int k = 0; k < 3; ++k) {
      for (int j = 0; j < 10; ++j) {
        std::array<int, 3> ej = expo[static_cast<std::size_t>(j)];
        const int p = ej[static_cast<std::size_t>(k)];
        if (p == 0) {
          continue;
        }
        ej[static_cast<std::size_t>(k)] -= 1;
        for (int i = 0; i < 10; ++i) {
          const std::array<int, 3>& ei = expo[static_cast<std::size_t>(i)];
          grad[static_cast<std::size_t>(k)].push_back(
              {i, j, static_cast<double>(p), at(ei[0] + ej[0], ei[1] + ej[1], ei[2] + ej[2])});
        }
      }
    }
    for (int m = 0; m < kMonomials4; ++m) {
      for (int c = 0; c < kMonomials3; ++c) {
        const auto& em = expo[static_cast<std::size_t>(m)];
        const auto& ec = expo[static_cast<std::size_t>(c)];
        shift[static_cast<std::size_t>(m)][static_cast<std::size_t>(c)] =
            at(em[0] + ec[0], em[1] + ec[1], em[2] + ec[2]);
      }
    }
    for (int m = 0; m < kMonomials6; ++m) {
      const auto& em = expo[static_cast<std::size_t>(m)];
      mul[static_cast<std::size_t>(m)] = {at(em[0] + 1, em[1], em[2]), at(em[0], em[1] + 1, em[2]),
                                          at(em[0], em[1], em[2] + 1)};
    }
  }

  [[nodiscard]] int at(int a, int b, int c) const {
    return idx[static_cast<std::size_t>(a)][static_cast<std::size_t>(b)][static_cast<std::size_t>(c)];
  }
};

const Tables& tables() {
  static const Tables t;
  return t;
}

// ∂v/∂s (10×3).
Eigen::Matrix<double, 10, 3> monomial_jacobian(const Eigen::Vector3d& s) {
  Eigen::Matrix<double, 10, 3> J = Eigen::Matrix<double, 10, 3>::Zero();
  J(1, 0) = 1.0;
  J(2, 1) = 1.0;
  J(3, 2) = 1.0;
  J(4, 0) = 2.0 * s.x();
  J(5, 0) = s.y();
  J(5, 1) = s.x();
  J(6, 0) = s.z();
  J(6, 2) = s.x();
  J(7, 1) = 2.0 * s.y();
  J(8, 1) = s.z();
  J(8, 2) = s.y();
  J(9, 2) = 2.0 * s.z();
  return J;
}

// Newton steps on the half-gradient Jvᵀ G v = 0 with the exact Hessian Jvᵀ G Jv + Σ_i (G v)_i ∇²v_i.
bool newton_polish(const Matrix10d& G, Eigen::Vector3d& s, int steps) {
  for (int it = 0; it < steps; ++it) {
    const Vector10d v = cgr_monomials(s);
    const Eigen::Matrix<double, 10, 3> Jv = monomial_jacobian(s);
    const Vector10d Gv = G * v;
    const Eigen::Vector3d g = Jv.transpose() * Gv;
    Eigen::Matrix3d H = Jv.transpose() * G * Jv;
    H(0, 0) += 2.0 * Gv(4);
    H(0, 1) += Gv(5);
    H(1, 0) += Gv(5);
    H(0, 2) += Gv(6);
    H(2, 0) += Gv(6);
    H(1, 1) += 2.0 * Gv(7);
    H(1, 2) += Gv(8);
    H(2, 1) += Gv(8);
    H(2, 2) += 2.0 * Gv(9);
    const Eigen::Vector3d step = H.fullPivLu().solve(g);
    if (!step.allFinite()) {
      break;  // singular Hessian: keep the eigenvalue solution
    }
    s -= step;
  }
  return s.allFinite();
}

Eigen::Matrix<double, 3, kMonomials3> cubic_coefficients(const Matrix10d& G) {
  const Tables& tb = tables();
  Eigen::Matrix<double, 3, kMonomials3> f = Eigen::Matrix<double, 3, kMonomials3>::Zero();
  for (int k = 0; k < 3; ++k) {
    for (const GradTerm& term : tb.grad[static_cast<std::size_t>(k)]) {
      f(k, term.mono) += term.c * G(term.i, term.j);
    }
  }
  return f;
}

// Mᵀ (columns = the rows m·f_k of M, column index 3·m + k).
Eigen::MatrixXd macaulay_transposed(const Eigen::Matrix<double, 3, kMonomials3>& f) {
  const Tables& tb = tables();
  Eigen::MatrixXd Mt = Eigen::MatrixXd::Zero(kMonomials7, kRows);
  for (int m = 0; m < kMonomials4; ++m) {
    for (int k = 0; k < 3; ++k) {
      for (int c = 0; c < kMonomials3; ++c) {
        Mt(tb.shift[static_cast<std::size_t>(m)][static_cast<std::size_t>(c)], 3 * m + k) = f(k, c);
      }
    }
  }
  return Mt;
}

// The fast path's elimination template, found once on a random instance: Gaussian elimination of M with
// partial pivoting, columns taken from the highest degree down, picks 93 independent rows and 93 pivot
// monomials; the 27 remaining monomials (all of degree <= 6) form a basis B of the quotient. For any instance
// where the 93×93 pivot block is invertible, the null space is Z = [−A⁻¹ B_cols; I] and the multiplication
// matrix of g on B is read from its rows g·b. The result is checked at run time (LU rcond) and the
// orthogonal (pivoted QR) path is used when the block is ill-conditioned.
struct Template {
  bool valid{false};
  std::vector<int> rows;                // 93 rows of M (3·m + k)
  std::vector<int> pivot_cols;          // 93 monomials
  std::vector<int> basis_cols;          // 27 monomials
  std::array<int, kMonomials7> slot{};  // position in pivot_cols (>= 0) or −1 − position in basis_cols

  Template() {
    std::mt19937_64 rng(0x5eed0b1);
    std::normal_distribution<double> g(0.0, 1.0);
    Eigen::Matrix<double, 12, 10> E;
    for (int i = 0; i < E.size(); ++i) {
      E(i) = g(rng);
    }
    const Matrix10d G = E.transpose() * E;
    Eigen::MatrixXd M = macaulay_transposed(cubic_coefficients(G / G.cwiseAbs().maxCoeff())).transpose();
    std::vector<bool> used(kRows, false);
    const double tol = 1e-9 * M.cwiseAbs().maxCoeff();
    for (int c = kMonomials7 - 1; c >= 0; --c) {
      int best = -1;
      double best_v = tol;
      for (int r = 0; r < kRows; ++r) {
        if (!used[static_cast<std::size_t>(r)] && std::abs(M(r, c)) > best_v) {
          best_v = std::abs(M(r, c));
          best = r;
        }
      }
      if (best < 0 || static_cast<int>(pivot_cols.size()) == kMonomials7 - kSolutions) {
        basis_cols.push_back(c);
        continue;
      }
      used[static_cast<std::size_t>(best)] = true;
      rows.push_back(best);
      pivot_cols.push_back(c);
      for (int r = 0; r < kRows; ++r) {
        if (!used[static_cast<std::size_t>(r)] && M(r, c) != 0.0) {
          M.row(r) -= (M(r, c) / M(best, c)) * M.row(best);
        }
      }
    }
    valid = static_cast<int>(basis_cols.size()) == kSolutions;
    for (const int b : basis_cols) {
      const auto& e = tables().expo[static_cast<std::size_t>(b)];
      valid = valid && e[0] + e[1] + e[2] <= kMaxDeg - 1;
    }
    for (std::size_t i = 0; i < pivot_cols.size(); ++i) {
      slot[static_cast<std::size_t>(pivot_cols[i])] = static_cast<int>(i);
    }
    for (std::size_t j = 0; j < basis_cols.size(); ++j) {
      slot[static_cast<std::size_t>(basis_cols[j])] = -1 - static_cast<int>(j);
    }
  }
};

const Template& elimination_template() {
  static const Template t;
  return t;
}

// Fast path: the multiplication matrix of g on the template basis, and the null space Z (120×27) it belongs to.
// False when the pivot block is ill-conditioned for this instance.
bool template_solve(const Eigen::Matrix<double, 3, kMonomials3>& f, Eigen::MatrixXd& Z, Eigen::MatrixXd& A,
                    double* rcond_out) {
  const Template& tp = elimination_template();
  if (!tp.valid) {
    return false;
  }
  const Tables& tb = tables();
  constexpr int kPiv = kMonomials7 - kSolutions;
  Eigen::MatrixXd P = Eigen::MatrixXd::Zero(kPiv, kPiv);
  Eigen::MatrixXd B = Eigen::MatrixXd::Zero(kPiv, kSolutions);
  for (int i = 0; i < kPiv; ++i) {
    const int row = tp.rows[static_cast<std::size_t>(i)];
    const int m = row / 3;
    const int k = row % 3;
    for (int c = 0; c < kMonomials3; ++c) {
      const int col = tb.shift[static_cast<std::size_t>(m)][static_cast<std::size_t>(c)];
      const int slot = tp.slot[static_cast<std::size_t>(col)];
      if (slot >= 0) {
        P(i, slot) = f(k, c);
      } else {
        B(i, -1 - slot) = f(k, c);
      }
    }
  }
  const Eigen::PartialPivLU<Eigen::MatrixXd> lu(P);
  const double rcond = lu.rcond();
  *rcond_out = rcond;
  if (!(rcond > 1e-13)) {
    return false;
  }
  const Eigen::MatrixXd X = lu.solve(B);
  if (!X.allFinite()) {
    return false;
  }
  Z.setZero(kMonomials7, kSolutions);
  A.resize(kSolutions, kSolutions);
  for (int i = 0; i < kPiv; ++i) {
    Z.row(tp.pivot_cols[static_cast<std::size_t>(i)]) = -X.row(i);
  }
  for (int j = 0; j < kSolutions; ++j) {
    Z(tp.basis_cols[static_cast<std::size_t>(j)], j) = 1.0;
  }
  for (int j = 0; j < kSolutions; ++j) {
    const auto& mk = tb.mul[static_cast<std::size_t>(tp.basis_cols[static_cast<std::size_t>(j)])];
    A.row(j) = kShift[0] * Z.row(mk[0]) + kShift[1] * Z.row(mk[1]) + kShift[2] * Z.row(mk[2]);
  }
  return true;
}

}  // namespace

Vector10d cgr_monomials(const Eigen::Vector3d& s) {
  Vector10d v;
  v << 1.0, s.x(), s.y(), s.z(), s.x() * s.x(), s.x() * s.y(), s.x() * s.z(), s.y() * s.y(), s.y() * s.z(),
      s.z() * s.z();
  return v;
}

std::vector<Eigen::Vector3d> cgr_critical_points(const Matrix10d& G_in, double imag_tol, int newton_steps,
                                                 CriticalPointStats* stats) {
  const Tables& tb = tables();
  std::vector<Eigen::Vector3d> out;
  CriticalPointStats st;
  const double g_scale = G_in.cwiseAbs().maxCoeff();
  if (!(g_scale > 0.0) || !std::isfinite(g_scale)) {
    if (stats != nullptr) {
      *stats = st;
    }
    return out;
  }
  const Matrix10d G = G_in / g_scale;

  const Eigen::Matrix<double, 3, kMonomials3> f = cubic_coefficients(G);
  const int generic_rank = kMonomials7 - kSolutions;  // 93
  Eigen::MatrixXd Z;
  // Dynamic sizes for the 27×27 eigenproblem: as fixed-size types, EigenSolver and the complex products took a
  // third of this file's compile time (43 -> 27 s at -O2), for no measurable run time.
  Eigen::MatrixXd A;
  if (template_solve(f, Z, A, &st.template_rcond)) {
    st.rank = generic_rank;
  } else {
    // Robust path: orthonormal null space from the column-pivoted QR of Mᵀ.
    st.robust_path = true;
    const Eigen::ColPivHouseholderQR<Eigen::MatrixXd> qr(macaulay_transposed(f));
    const auto diag = qr.matrixQR().diagonal().cwiseAbs();
    const double r0 = diag(0);
    int rank = 0;
    for (int i = 0; i < kRows; ++i) {
      rank += diag(i) > 1e-13 * r0 ? 1 : 0;
    }
    st.rank = rank;
    st.rank_ratio = r0 > 0.0 ? diag(generic_rank) / r0 : 0.0;
    if (rank != generic_rank) {
      if (stats != nullptr) {
        *stats = st;
      }
      return out;
    }
    // Null space of M = the last 27 columns of Q.
    Eigen::MatrixXd E = Eigen::MatrixXd::Zero(kMonomials7, kSolutions);
    E.bottomRows(kSolutions).setIdentity();
    Z = qr.householderQ() * E;
    Eigen::MatrixXd Zsh(kMonomials6, kSolutions);
    for (int r = 0; r < kMonomials6; ++r) {
      const auto& mk = tb.mul[static_cast<std::size_t>(r)];
      Zsh.row(r) = kShift[0] * Z.row(mk[0]) + kShift[1] * Z.row(mk[1]) + kShift[2] * Z.row(mk[2]);
    }
    A = Z.topRows(kMonomials6).colPivHouseholderQr().solve(Zsh);
  }
  const Eigen::EigenSolver<Eigen::MatrixXd> es(A, true);
  if (es.info() != Eigen::Success) {
    if (stats != nullptr) {
      *stats = st;
    }
    return out;
  }
  // Only the rows of 1, s1, s2, s3 of the monomial vectors are needed.
  const Eigen::MatrixXcd W = Z.topRows(4).cast<std::complex<double>>() * es.eigenvectors();
  out.reserve(kSolutions);
  for (int j = 0; j < kSolutions; ++j) {
    const std::complex<double> w0 = W(0, j);
    if (!(std::abs(w0) > 1e-12 * W.col(j).norm())) {
      continue;  // at (or near) infinity in this frame: another pre-rotation covers it
    }
    const Eigen::Matrix<std::complex<double>, 3, 1> sc = W.col(j).tail<3>() / w0;
    Eigen::Vector3d s = sc.real();
    if (!s.allFinite() || sc.imag().norm() > imag_tol * (1.0 + s.norm())) {
      ++st.complex_solutions;
      continue;
    }
    if (!newton_polish(G, s, newton_steps)) {
      continue;
    }
    out.push_back(s);
  }
  if (stats != nullptr) {
    *stats = st;
  }
  return out;
}

}  // namespace evpipe::pose::detail
