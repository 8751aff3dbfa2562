// Primal simplex with long steps for  min cᵀx + Σ_k |D_k x|  s.t.  G x ≥ h,  E x = f  (d small).
//
// The working set W holds d independent rows through x: equality rows, inequality rows at
// equality, absolute-value rows at their kink (D_k x = 0), and "free" unit rows that only
// complete the set while x is not yet a vertex. Off W each |D_k x| is s_k D_k x with
// s_k = sign(D_k x), so locally the objective is c̃ᵀx with c̃ = c + Σ_{k∉W} s_k D_kᵀ, and the
// multipliers λ of W solve Bᵀλ = c̃. x is optimal when inequality rows have λ ≥ 0,
// absolute-value rows |λ| ≤ 1 (λ = −μ) and free rows λ = 0. Otherwise the row with the largest
// violation leaves W: x moves along the edge dx (B dx = σ e_p) on which the objective falls
// at the rate λ_p σ (plus 1 for a released kink), and the line search passes every kink
// D_k x = 0 on the way (each raises the slope by 2|D_k dx|) until the slope turns ≥ 0, whose
// row enters W, or an inequality row blocks the edge (Barrodale–Roberts' long step for L1).
#include "common/dense_primal_simplex.h"

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

enum class Kind { Inequality, Equality, Abs, Free };
struct WorkingRow {
  Kind kind;
  int index;  // row of G, E or D; the coordinate of a free row
};

class DensePrimalSimplex {
 public:
  DensePrimalSimplex(const FewVariableLp& lp, const FewVariableLpOptions& options)
      : lp_(lp), d_(static_cast<int>(lp.c.size())), n_(static_cast<int>(lp.G.rows())),
        m_(static_cast<int>(lp.E.rows())), t_(static_cast<int>(lp.D.rows())) {
    max_iterations_ = std::min<long>(options.max_iterations, 100 + 20L * (n_ + m_ + t_ + d_));
    cost_scale_ = std::max(1.0, lp.c.cwiseAbs().maxCoeff());
    for (int k = 0; k < t_; ++k) cost_scale_ += lp.D.row(k).cwiseAbs().maxCoeff();
    g_norm_ = lp.G.rowwise().norm();
    d_norm_ = lp.D.rowwise().norm();
  }

  void solve(const FewVariableLpOptions& options, FewVariableLpResult& r) {
    x_ = options.x_hint;
    gx_ = lp_.G * x_;
    ax_ = lp_.D * x_;
    if (!start(r)) return;
    if (!iterate(r)) return;
    finish(r);
  }

 private:
  Eigen::RowVectorXd row(const WorkingRow& w) const {
    switch (w.kind) {
      case Kind::Inequality: return lp_.G.row(w.index);
      case Kind::Equality: return lp_.E.row(w.index);
      case Kind::Abs: return lp_.D.row(w.index);
      default: return Eigen::RowVectorXd::Unit(d_, w.index);
    }
  }
  double rhs(const WorkingRow& w) const {
    return w.kind == Kind::Inequality ? lp_.h(w.index) : w.kind == Kind::Equality ? lp_.f(w.index) : 0.0;
  }

  // ---- start: x_hint must be feasible; W = independent equality rows, then rows tight at x,
  //      then free rows ----
  bool start(FewVariableLpResult& r) {
    const double xmax = std::max(1.0, x_.cwiseAbs().maxCoeff());
    for (int j = 0; j < n_; ++j)
      if (gx_(j) < lp_.h(j) - 1e-9 * std::max(1.0, std::abs(lp_.h(j)))) {
        std::ostringstream os;
        os << "dense primal simplex: the start violates inequality row " << j;
        r.message = os.str();
        return false;
      }
    for (int i = 0; i < m_; ++i)
      if (std::abs(lp_.E.row(i).dot(x_) - lp_.f(i)) > 1e-9 * std::max(1.0, std::abs(lp_.f(i)))) {
        std::ostringstream os;
        os << "dense primal simplex: the start violates equality row " << i;
        r.message = os.str();
        return false;
      }
    in_w_.assign(n_, 0);
    abs_in_w_.assign(t_, 0);
    sign_.assign(t_, 1.0);
    Mat rows(0, d_);
    auto try_add = [&](const WorkingRow& w) {
      if (static_cast<int>(work_.size()) >= d_) return;
      Mat next(rows.rows() + 1, d_);
      next << rows, row(w);
      Eigen::FullPivLU<Mat> lu(next);
      lu.setThreshold(1e-10);
      if (lu.rank() != next.rows()) return;
      rows = std::move(next);
      work_.push_back(w);
      if (w.kind == Kind::Inequality) in_w_[w.index] = 1;
      if (w.kind == Kind::Abs) abs_in_w_[w.index] = 1;
    };
    for (int i = 0; i < m_; ++i) try_add({Kind::Equality, i});
    for (int j = 0; j < n_; ++j)
      if (gx_(j) - lp_.h(j) <= 1e-12 * std::max(1.0, std::abs(lp_.h(j))) + 1e-14 * g_norm_(j) * xmax)
        try_add({Kind::Inequality, j});
    for (int k = 0; k < t_; ++k)
      if (std::abs(ax_(k)) <= 1e-14 * d_norm_(k) * xmax) try_add({Kind::Abs, k});
    for (int k = 0; k < d_; ++k) try_add({Kind::Free, k});
    return factor(r);
  }

  bool factor(FewVariableLpResult& r) {
    B_.resize(d_, d_);
    for (int i = 0; i < d_; ++i) B_.row(i) = row(work_[i]);
    lu_.compute(B_);
    if (!(lu_.rcond() > 1e-14)) {
      std::ostringstream os;
      os << "dense primal simplex: working set singular (reciprocal condition " << lu_.rcond() << ")";
      r.message = os.str();
      return false;
    }
    return true;
  }

  // Signs of the absolute-value rows off W at x (D x = ax_), and the local cost c̃. A row at
  // its kink off W (it left W on a step of length 0) keeps the side it left towards.
  Vec cost() {
    Vec c = lp_.c;
    for (int k = 0; k < t_; ++k) {
      if (abs_in_w_[k]) continue;
      if (ax_(k) != 0) sign_[k] = ax_(k) < 0 ? -1.0 : 1.0;
      c.noalias() += sign_[k] * lp_.D.row(k).transpose();
    }
    return c;
  }
  // A fixed order of rows for Bland's rule: equality, inequality, absolute-value, free rows.
  static long label(const WorkingRow& w) { return static_cast<long>(w.kind) * (1L << 40) + w.index; }

  // ---- the steps ----
  bool iterate(FewVariableLpResult& r) {
    const double tol = 1e-12 * cost_scale_;
    int degenerate = 0;
    const int bland_after = 2 * d_ + 10;
    for (long it = 0;; ++it) {
      const Vec lambda = lu_.transpose().solve(cost());
      const bool bland = degenerate >= bland_after;
      // Leaving row: the largest violation of its multiplier's condition (Bland: the first).
      int p = -1;
      double best = tol;
      for (int i = 0; i < d_; ++i) {
        const double l = lambda(i);
        double v = 0;
        switch (work_[i].kind) {
          case Kind::Inequality: v = -l; break;
          case Kind::Abs: v = std::abs(l) - 1; break;
          case Kind::Free: v = std::abs(l); break;
          case Kind::Equality: v = 0; break;
        }
        if (bland) {  // the violated row of smallest label
          if (v > tol && (p < 0 || label(work_[i]) < label(work_[p]))) p = i;
          continue;
        }
        if (v <= best) continue;
        best = v, p = i;
      }
      if (p < 0) return true;
      if (it >= max_iterations_) {
        r.message = "dense primal simplex: iteration limit " + std::to_string(max_iterations_);
        return false;
      }
      r.iterations = static_cast<int>(it + 1);
      const WorkingRow left = work_[p];
      const double sigma = left.kind == Kind::Inequality ? 1.0 : lambda(p) > 0 ? -1.0 : 1.0;
      const Vec dx = lu_.solve(Vec::Unit(d_, p) * sigma);
      double slope = lambda(p) * sigma + (left.kind == Kind::Abs ? 1.0 : 0.0);  // < 0
      // Hard stop: the first inequality row the edge meets.
      gd_.noalias() = lp_.G * dx;
      const double dnorm = dx.norm();
      int block = -1;
      double tmax = INFINITY;
      for (int j = 0; j < n_; ++j) {
        if (in_w_[j] || gd_(j) >= -1e-13 * g_norm_(j) * dnorm) continue;
        const double t = std::max(0.0, gx_(j) - lp_.h(j)) / -gd_(j);
        if (t < tmax) tmax = t, block = j;
      }
      // Kinks before it, in order: each raises the slope by 2|D_k dx|.
      kinks_.clear();
      ad_.noalias() = lp_.D * dx;
      const Vec& ad = ad_;
      for (int k = 0; k < t_; ++k) {
        if (abs_in_w_[k] || sign_[k] * ad(k) >= -1e-13 * d_norm_(k) * dnorm) continue;
        const double t = std::max(0.0, sign_[k] * ax_(k)) / -(sign_[k] * ad(k));
        if (t <= tmax) kinks_.push_back({t, k});
      }
      std::sort(kinks_.begin(), kinks_.end());  // by step, ties by row: a fixed order
      WorkingRow enter{Kind::Inequality, block};
      double step = tmax;
      for (const auto& [t, k] : kinks_) {
        slope += 2 * std::abs(ad(k));
        if (slope >= 0) {
          enter = {Kind::Abs, k};
          step = t;
          break;
        }
      }
      if (enter.kind == Kind::Inequality && block < 0) {
        r.message = "dense primal simplex: the objective decreases without bound along an edge";
        return false;
      }
      degenerate = step <= 1e-14 * std::max(1.0, x_.cwiseAbs().maxCoeff()) / std::max(dnorm, 1e-300) ? degenerate + 1 : 0;
      x_ += step * dx;
      gx_ += step * gd_;  // G x and D x follow x (recomputed at the end)
      ax_ += step * ad_;
      if (left.kind == Kind::Inequality) in_w_[left.index] = 0;
      if (left.kind == Kind::Abs) abs_in_w_[left.index] = 0, sign_[left.index] = sigma;  // D_p dx = σ
      work_[p] = enter;
      if (enter.kind == Kind::Inequality) in_w_[enter.index] = 1;
      else abs_in_w_[enter.index] = 1;
      if (!factor(r)) return false;
    }
  }

  // ---- the end: x from W when it is a vertex, multipliers, certificate ----
  void finish(FewVariableLpResult& r) {
    bool vertex = true;
    for (const auto& w : work_) vertex = vertex && w.kind != Kind::Free;
    if (vertex) {  // the rows of W exactly, in row order (the same bits for the same set)
      std::sort(work_.begin(), work_.end(), [](const WorkingRow& a, const WorkingRow& b) {
        return a.kind != b.kind ? a.kind < b.kind : a.index < b.index;
      });
      if (!factor(r)) return;
      Vec rhsB(d_);
      for (int i = 0; i < d_; ++i) rhsB(i) = rhs(work_[i]);
      x_ = lu_.solve(rhsB);
      x_ += lu_.solve(rhsB - B_ * x_);
    }
    ax_ = lp_.D * x_;
    const Vec lambda = lu_.transpose().solve(cost());
    r.x = x_;
    r.y = Vec::Zero(n_);
    r.z = Vec::Zero(m_);
    r.mu = Vec::Zero(t_);
    for (int k = 0; k < t_; ++k)
      if (!abs_in_w_[k]) r.mu(k) = sign_[k];
    const double tol = 1e-9 * cost_scale_;
    for (int i = 0; i < d_; ++i) {
      const WorkingRow& w = work_[i];
      const double l = lambda(i);
      if ((w.kind == Kind::Inequality && l < -tol) || (w.kind == Kind::Abs && std::abs(l) > 1 + 1e-9) ||
          (w.kind == Kind::Free && std::abs(l) > tol)) {
        std::ostringstream os;
        os << "dense primal simplex: multiplier " << l << " of a working row breaks optimality at the end";
        r.message = os.str();
        return;
      }
      switch (w.kind) {
        case Kind::Inequality: r.y(w.index) = std::max(0.0, l), r.basic.push_back(w.index); break;
        case Kind::Equality: r.z(w.index) = l, r.basic.push_back(n_ + w.index); break;
        case Kind::Abs: r.mu(w.index) = std::clamp(-l, -1.0, 1.0), r.basic.push_back(n_ + m_ + w.index); break;
        case Kind::Free: break;
      }
    }
    r.dual_objective = (n_ ? lp_.h.dot(r.y) : 0.0) + (m_ ? lp_.f.dot(r.z) : 0.0);
    r.status = LpStatus::Optimal;
  }

  const FewVariableLp& lp_;
  const int d_, n_, m_, t_;
  long max_iterations_ = 0;
  double cost_scale_ = 1;
  Vec x_, gx_, ax_, gd_, ad_;  // x, G x, D x, and G dx, D dx of the current edge
  Vec g_norm_, d_norm_;
  std::vector<WorkingRow> work_;
  std::vector<char> in_w_, abs_in_w_;
  std::vector<double> sign_;
  std::vector<std::pair<double, int>> kinks_;
  Mat B_;
  Eigen::PartialPivLU<Mat> lu_;
};

}  // namespace

void solve_dense_primal_simplex(const FewVariableLp& lp, const FewVariableLpOptions& options,
                                FewVariableLpResult& r) {
  r.status = LpStatus::Failed;
  if (options.x_hint.size() != lp.c.size()) {
    r.message = "dense primal simplex: no start point";
    return;
  }
  DensePrimalSimplex(lp, options).solve(options, r);
}

}  // namespace parafab
