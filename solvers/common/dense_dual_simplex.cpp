// Dense dual simplex for LPs with d ≲ 8 unknowns and many rows (strip Eq. 4.4 and 4.6 phase
// one: d = 4; rod Eq. 5.19: d = 7).
//
//   primal  min cᵀx  s.t.  G x ≥ h,  E x = f          dual  max hᵀy + fᵀz  s.t.  Gᵀy + Eᵀz = c,  y ≥ 0
//
// The primal simplex on the dual program, written in primal terms. A basis is d independent
// rows of [G; E] (every independent equality row plus inequality rows); x solves them as
// equalities (B x = h_B) and the multipliers solve Bᵀ y_B = c. The multipliers of basic
// inequality rows stay ≥ 0 (dual feasibility); each step brings in the most violated row
// (violation over row norm), and the basic inequality row whose multiplier reaches zero first
// leaves (ratio test on α = B⁻ᵀ G_qᵀ). No violated row left: x is optimal. No row can leave:
// the dual is unbounded, so the primal is infeasible.
//
// Absolute-value rows (objective term Σ_k |D_k x|) are dual columns with bounds μ_k ∈ [−1, 1]
// (the bounded dual simplex): a nonbasic one sits at μ_k = s_k = ±1 and adds s_k D_kᵀ to the
// cost, a basic one has D_k x = 0 and −μ_k = its multiplier in [−1, 1]. A nonbasic row with
// s_k D_k x < 0 is violated; entering, its multiplier runs from −s_k towards s_k, and if it
// gets there first the row just flips its sign (a bound flip, no basis change).
//
// The start is an artificial box: unit rows ±x_k ≥ −M complete the equality rows to a basis,
// their signs chosen so that their multipliers are ≥ 0. A box row still carrying a positive
// multiplier at the end means the objective keeps falling as M grows: unbounded. Degenerate
// steps switch to Bland's rule after a run of them (no cycling). x and y are computed at the
// end from the final basis in row order, so two runs that end on the same basis (a warm and
// a cold start) return the same bits.
#include "common/dense_dual_simplex.h"

#include <Eigen/LU>
#include <Eigen/QR>
#include <algorithm>
#include <cmath>
#include <sstream>
#include <vector>

namespace parafab {
namespace {

using Mat = Eigen::MatrixXd;
using Vec = Eigen::VectorXd;

class DenseDualSimplex {
 public:
  DenseDualSimplex(const FewVariableLp& lp, const FewVariableLpOptions& options)
      : lp_(lp), d_(static_cast<int>(lp.c.size())), n_(static_cast<int>(lp.G.rows())),
        m_(static_cast<int>(lp.E.rows())), t_(static_cast<int>(lp.D.rows())) {
    const double scale = std::max({1.0, n_ ? lp.h.cwiseAbs().maxCoeff() : 0.0,
                                   m_ ? lp.f.cwiseAbs().maxCoeff() : 0.0});
    M_ = 1e9 * scale;
    max_iterations_ = std::min<long>(options.max_iterations, 100 + 20L * (n_ + m_ + t_ + d_));
    norm_.resize(n_);
    for (int j = 0; j < n_; ++j) norm_(j) = std::max(lp.G.row(j).norm(), 1e-300);
    abs_norm_.resize(t_);
    for (int k = 0; k < t_; ++k) abs_norm_(k) = std::max(lp.D.row(k).norm(), 1e-300);
    abs_sign_.assign(t_, 1.0);
    if (t_ > 0 && options.x_hint.size() == d_) {
      const Vec dx = lp.D * options.x_hint;
      for (int k = 0; k < t_; ++k) abs_sign_[k] = dx(k) < 0 ? -1.0 : 1.0;
    }
  }

  void solve(const FewVariableLpOptions& options, FewVariableLpResult& r) {
    if (!start(options.basic_hint, r)) return;
    if (!iterate(r)) return;
    finish(r);
  }

 private:
  // ---- rows: j < n inequality, n ≤ j < n + m equality, n + m ≤ j absolute value row
  //      k = j − n − m, j < 0 box row k = −1 − j ----
  Eigen::RowVectorXd row(int j) const {
    if (j >= 0 && j < n_) return lp_.G.row(j);
    if (j >= n_ + m_) return lp_.D.row(j - n_ - m_);
    if (j >= n_) return lp_.E.row(j - n_);
    const int k = -1 - j;
    Eigen::RowVectorXd e = Eigen::RowVectorXd::Zero(d_);
    e(k) = box_sign_[k];
    return e;
  }
  double rhs(int j) const { return j < 0 ? -M_ : j < n_ ? lp_.h(j) : j < n_ + m_ ? lp_.f(j - n_) : 0.0; }
  bool is_equality(int j) const { return j >= n_ && j < n_ + m_; }
  bool is_abs(int j) const { return j >= n_ + m_; }

  // The cost of the current piece of the objective: c + Σ over nonbasic absolute-value rows of
  // s_k D_kᵀ (summed afresh, so it does not drift over the steps).
  Vec cost() const {
    Vec c = lp_.c;
    for (int k = 0; k < t_; ++k)
      if (!abs_in_basis_[k]) c += abs_sign_[k] * lp_.D.row(k).transpose();
    return c;
  }

  // ---- start: independent equality rows, then hinted rows, then box rows ----
  bool start(const std::vector<int>& hint, FewVariableLpResult& r) {
    box_sign_.assign(d_, 1.0);
    basis_.clear();
    dependent_.clear();
    if (m_ > 0) {
      Eigen::ColPivHouseholderQR<Mat> qr(lp_.E.transpose());
      qr.setThreshold(1e-12);
      const int rank = static_cast<int>(qr.rank());
      for (int i = 0; i < rank; ++i) basis_.push_back(n_ + qr.colsPermutation().indices()(i));
      for (int i = rank; i < m_; ++i) dependent_.push_back(n_ + qr.colsPermutation().indices()(i));
    }
    auto try_add = [&](int j) {
      if (static_cast<int>(basis_.size()) >= d_) return;
      Mat rows(basis_.size() + 1, d_);
      for (size_t i = 0; i < basis_.size(); ++i) rows.row(i) = row(basis_[i]);
      rows.row(basis_.size()) = row(j);
      Eigen::FullPivLU<Mat> lu(rows);
      lu.setThreshold(1e-10);
      if (lu.rank() == static_cast<Eigen::Index>(basis_.size()) + 1) basis_.push_back(j);
    };
    for (int j : hint)
      if (j >= 0 && j < n_ && std::find(basis_.begin(), basis_.end(), j) == basis_.end()) try_add(j);
    for (int k = 0; k < d_; ++k) try_add(-1 - k);
    if (static_cast<int>(basis_.size()) != d_) {
      r.message = "dense simplex: no starting basis";  // cannot happen for d unit rows
      return false;
    }
    // Multipliers of the start; box rows take the sign that makes theirs ≥ 0. A hinted row
    // with a negative multiplier is not dual feasible: start cold instead.
    abs_in_basis_.assign(t_, 0);
    if (!factor(r)) return false;
    Vec y = lu_.transpose().solve(cost());
    bool feasible = true;
    for (int i = 0; i < d_; ++i) {
      if (basis_[i] < 0 && y(i) < 0) box_sign_[-1 - basis_[i]] = -1.0;
      else if (basis_[i] >= 0 && basis_[i] < n_ && y(i) < -dual_tolerance()) feasible = false;
    }
    if (!feasible) return start({}, r);
    in_basis_.assign(n_, 0);
    for (int j : basis_)
      if (j >= 0 && j < n_) in_basis_[j] = 1;
    return factor(r);
  }

  // The size of the cost c + Σ s_k D_kᵀ of any piece, for the tolerances of the multipliers.
  double cost_scale() const {
    double scale = std::max(1.0, lp_.c.cwiseAbs().maxCoeff());
    for (int k = 0; k < t_; ++k) scale += lp_.D.row(k).cwiseAbs().maxCoeff();
    return scale;
  }
  double dual_tolerance() const { return 1e-12 * cost_scale(); }

  bool factor(FewVariableLpResult& r) {
    B_.resize(d_, d_);
    hB_.resize(d_);
    for (int i = 0; i < d_; ++i) B_.row(i) = row(basis_[i]), hB_(i) = rhs(basis_[i]);
    lu_.compute(B_);
    if (!(lu_.rcond() > 1e-14)) {
      std::ostringstream os;
      os << "dense simplex: basis singular (reciprocal condition " << lu_.rcond() << ")";
      r.message = os.str();
      return false;
    }
    return true;
  }

  // ---- the simplex steps ----
  bool iterate(FewVariableLpResult& r) {
    int degenerate = 0;
    const int bland_after = 2 * d_ + 10;
    for (long it = 0;; ++it) {
      const Vec y = lu_.transpose().solve(cost());
      x_ = lu_.solve(hB_);
      const double xmax = std::max(1.0, x_.cwiseAbs().maxCoeff());
      const bool bland = degenerate >= bland_after;
      // Entering row: the largest violation over the row norm (Bland: the first violated).
      int q = -1;
      double best = 0;
      const Vec gx = lp_.G * x_;
      for (int j = 0; j < n_; ++j) {
        if (in_basis_[j]) continue;
        const double v = lp_.h(j) - gx(j);
        const double tol = 1e-12 * std::max(1.0, std::abs(lp_.h(j))) + 1e-14 * norm_(j) * xmax;
        if (v <= tol) continue;
        if (bland) { q = j; break; }
        if (v / norm_(j) > best) best = v / norm_(j), q = j;
      }
      if (t_ > 0 && !(bland && q >= 0)) {
        const Vec dx = lp_.D * x_;
        for (int k = 0; k < t_; ++k) {
          if (abs_in_basis_[k]) continue;
          const double v = -abs_sign_[k] * dx(k);  // > 0: the row has the wrong sign
          if (v <= 1e-14 * abs_norm_(k) * xmax) continue;
          if (bland) { q = n_ + m_ + k; break; }
          if (v / abs_norm_(k) > best) best = v / abs_norm_(k), q = n_ + m_ + k;
        }
      }
      if (q < 0) return true;
      if (it >= max_iterations_) {
        r.message = "dense simplex: iteration limit " + std::to_string(max_iterations_);
        return false;
      }
      r.iterations = static_cast<int>(it + 1);
      // Ratio test: the entering multiplier runs from λ_q0 in direction δ (an inequality row
      // from 0 up; an absolute-value row from −s_q towards s_q, at most 2), and the basic
      // ones follow λ_B(t) = λ_B − t δ α: inequality and box rows stay ≥ 0, absolute-value
      // rows in [−1, 1].
      const bool q_abs = is_abs(q);
      const double delta = q_abs ? abs_sign_[q - n_ - m_] : 1.0;
      const Vec aq = row(q).transpose();
      Vec alpha = lu_.transpose().solve(aq);
      alpha *= delta;
      const double amax = std::max(alpha.cwiseAbs().maxCoeff(), 1e-300);
      auto limit = [&](int i) -> double {  // the step at which basic row i reaches its bound (∞: never)
        const int j = basis_[i];
        if (is_equality(j) || std::abs(alpha(i)) <= 1e-11 * amax) return INFINITY;
        if (is_abs(j)) return alpha(i) > 0 ? std::max(0.0, y(i) + 1) / alpha(i) : std::max(0.0, 1 - y(i)) / -alpha(i);
        return alpha(i) > 0 ? std::max(0.0, y(i)) / alpha(i) : INFINITY;
      };
      double tmin = q_abs ? 2.0 : static_cast<double>(INFINITY);
      for (int i = 0; i < d_; ++i) tmin = std::min(tmin, limit(i));
      const double ttol = 1e-12 * std::max(1.0, tmin);
      if (q_abs && tmin >= 2.0 - ttol) {  // bound flip: μ_q goes to the other end, same basis
        abs_sign_[q - n_ - m_] = -abs_sign_[q - n_ - m_];
        degenerate = 0;
        continue;
      }
      if (!std::isfinite(tmin)) {
        r.status = LpStatus::Infeasible;
        std::ostringstream os;
        os << "dense simplex: row " << q << " cannot be satisfied with the rows of the basis "
           << "(the dual is unbounded, the constraints are infeasible)";
        r.message = os.str();
        return false;
      }
      // Among the rows reaching their bound with tmin (to round-off): box rows first, then the
      // largest |α| (the stablest pivot), or under Bland's rule the smallest row index.
      int p = -1;
      for (int i = 0; i < d_; ++i) {
        if (limit(i) > tmin + ttol) continue;
        if (p < 0) { p = i; continue; }
        const bool box_i = basis_[i] < 0, box_p = basis_[p] < 0;
        if (box_i != box_p) { if (box_i) p = i; continue; }
        if (bland ? basis_[i] < basis_[p] : std::abs(alpha(i)) > std::abs(alpha(p))) p = i;
      }
      degenerate = tmin <= 1e-14 ? degenerate + 1 : 0;
      const int leaving = basis_[p];
      if (leaving >= 0 && leaving < n_) in_basis_[leaving] = 0;
      if (is_abs(leaving)) {  // leaves at the end of [−1, 1] it reached: μ = −λ = ∓1
        abs_in_basis_[leaving - n_ - m_] = 0;
        abs_sign_[leaving - n_ - m_] = alpha(p) > 0 ? 1.0 : -1.0;
      }
      basis_[p] = q;
      if (q_abs) abs_in_basis_[q - n_ - m_] = 1;
      else in_basis_[q] = 1;
      if (!factor(r)) return false;
    }
  }

  // ---- the end: unboundedness, degenerate box rows, x and y from the basis in row order ----
  void finish(FewVariableLpResult& r) {
    Vec y = lu_.transpose().solve(cost());
    for (int i = 0; i < d_; ++i) {
      if (basis_[i] >= 0) continue;
      if (y(i) > dual_tolerance()) {
        r.status = LpStatus::Unbounded;
        r.message = "dense simplex: the objective decreases without bound along x_" +
                    std::to_string(-1 - basis_[i]);
        return;
      }
      // A box row with multiplier 0: move along the edge that frees it (other basic rows stay
      // active, the objective does not change) to the first row that becomes active, or the
      // first absolute-value row that reaches 0 (beyond it the objective would rise).
      const Vec dx = lu_.solve(Vec::Unit(d_, i));
      const Vec gx = lp_.G * x_, gd = lp_.G * dx;
      int q = -1;
      double tbest = INFINITY;
      for (int j = 0; j < n_; ++j) {
        if (in_basis_[j] || gd(j) >= -1e-12 * norm_(j) * dx.norm()) continue;
        const double t = std::max(0.0, gx(j) - lp_.h(j)) / -gd(j);
        if (t < tbest) tbest = t, q = j;
      }
      if (t_ > 0) {
        const Vec ax = lp_.D * x_, ad = lp_.D * dx;
        for (int k = 0; k < t_; ++k) {
          const double sd = abs_sign_[k] * ad(k);
          if (abs_in_basis_[k] || sd >= -1e-12 * abs_norm_(k) * dx.norm()) continue;
          const double t = std::max(0.0, abs_sign_[k] * ax(k)) / -sd;
          if (t < tbest) tbest = t, q = n_ + m_ + k;
        }
      }
      if (q < 0) continue;  // the optimal set is unbounded along this edge; keep the vertex
      basis_[i] = q;
      if (is_abs(q)) abs_in_basis_[q - n_ - m_] = 1;
      else in_basis_[q] = 1;
      if (!factor(r)) return;
      x_ = lu_.solve(hB_);
      y = lu_.transpose().solve(cost());
    }
    std::sort(basis_.begin(), basis_.end(), [](int a, int b) {
      return (a < 0) != (b < 0) ? a >= 0 : a < b;  // real rows in index order, then box rows
    });
    if (!factor(r)) return;
    x_ = lu_.solve(hB_);
    x_ += lu_.solve(hB_ - B_ * x_);  // one step of iterative refinement
    y = lu_.transpose().solve(cost());
    r.x = x_;
    r.y = Vec::Zero(n_);
    r.z = Vec::Zero(m_);
    r.mu = Vec::Zero(t_);
    for (int k = 0; k < t_; ++k)
      if (!abs_in_basis_[k]) r.mu(k) = abs_sign_[k];
    for (int i = 0; i < d_; ++i) {
      const int j = basis_[i];
      if (j < 0) continue;
      if (is_abs(j)) {
        if (std::abs(y(i)) > 1 + 1e-9) {
          std::ostringstream os;
          os << "dense simplex: multiplier of absolute-value row " << j - n_ - m_ << " is " << -y(i)
             << ", outside [-1, 1] at the end";
          r.message = os.str();
          return;
        }
        r.mu(j - n_ - m_) = std::clamp(-y(i), -1.0, 1.0);
      } else if (j < n_) {
        if (y(i) < -1e-9 * cost_scale()) {
          std::ostringstream os;
          os << "dense simplex: multiplier of row " << j << " is " << y(i) << " < 0 at the end";
          r.message = os.str();
          return;
        }
        r.y(j) = std::max(0.0, y(i));
      } else {
        r.z(j - n_) = y(i);
      }
      r.basic.push_back(j);
    }
    r.dual_objective = (n_ ? lp_.h.dot(r.y) : 0.0) + (m_ ? lp_.f.dot(r.z) : 0.0);
    // Equality rows left out as dependent must hold at x, or the program is infeasible.
    for (int j : dependent_) {
      const double v = std::abs(lp_.E.row(j - n_).dot(x_) - lp_.f(j - n_));
      if (v > 1e-9 * std::max(1.0, std::abs(lp_.f(j - n_)))) {
        r.status = LpStatus::Infeasible;
        std::ostringstream os;
        os << "dense simplex: equality row " << j - n_ << " contradicts the others (residual " << v << ")";
        r.message = os.str();
        return;
      }
    }
    r.status = LpStatus::Optimal;
  }

  const FewVariableLp& lp_;
  const int d_, n_, m_, t_;
  double M_ = 1e9;
  long max_iterations_ = 0;
  Vec norm_;
  std::vector<int> basis_, dependent_;
  std::vector<char> in_basis_;
  std::vector<double> box_sign_;
  Vec abs_norm_;
  std::vector<char> abs_in_basis_;    // absolute-value rows in the basis (D_k x = 0)
  std::vector<double> abs_sign_;      // s_k = μ_k of a nonbasic absolute-value row
  Mat B_;
  Vec hB_, x_;
  Eigen::PartialPivLU<Mat> lu_;
};

}  // namespace

void solve_dense_dual_simplex(const FewVariableLp& lp, const FewVariableLpOptions& options,
                              FewVariableLpResult& r) {
  r.status = LpStatus::Failed;
  DenseDualSimplex(lp, options).solve(options, r);
}

}  // namespace parafab
