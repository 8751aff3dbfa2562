#include "strips/curve_fairing.h"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>

#include "common/error.h"
#include "common/gauss_legendre.h"
#include "common/plane_curve.h"
#include "strips/strip_constraints.h"

namespace parafab {

namespace {
struct Penalty {
  double lo, hi, weight;  ///< ∫_lo^hi weight·|γ'''|² du
};

std::vector<double> uniform_knots(int n, int p) {
  std::vector<double> U(n + p + 1, 0.0);
  for (int i = n; i < n + p + 1; ++i) U[i] = 1.0;
  for (int j = 1; j < n - p; ++j) U[j + p] = static_cast<double>(j) / (n - p);
  return U;
}

// Least squares with ∫|γ''|² (global) and local ∫|γ'''|² terms; end poles = end points.
BSplineCurve2 solve_fit(const std::vector<Vec2>& P, const std::vector<double>& t, int n, int p,
                        double fairness, const std::vector<Penalty>& local) {
  const int N = static_cast<int>(P.size());
  const std::vector<double> U = uniform_knots(n, p);
  std::vector<Vec2> zero(n, Vec2::Zero());
  const BSplineCurve2 shape(p, U, zero);
  Eigen::MatrixXd M = Eigen::MatrixXd::Zero(n, n), rhs = Eigen::MatrixXd::Zero(n, 2);
  for (int i = 0; i < N; ++i) {
    const BSplineCurve2::Basis B = shape.basis(t[i]);
    for (int a = 0; a <= p; ++a) {
      rhs.row(B.first + a) += B.N[0][a] * P[i].transpose() / N;
      for (int c = 0; c <= p; ++c) M(B.first + a, B.first + c) += B.N[0][a] * B.N[0][c] / N;
    }
  }
  const std::vector<double> bp = shape.breakpoints();
  for (size_t k = 0; k + 1 < bp.size(); ++k)
    for (int g = 0; g < 8; ++g) {
      const double u = 0.5 * (bp[k] + bp[k + 1]) + 0.5 * (bp[k + 1] - bp[k]) * kGauss8X[g];
      const double w = 0.5 * (bp[k + 1] - bp[k]) * kGauss8W[g];
      double w3 = 0;
      for (const auto& pen : local)
        if (u >= pen.lo && u <= pen.hi) w3 += pen.weight;
      const BSplineCurve2::Basis B = shape.basis(u);
      for (int a = 0; a <= p; ++a)
        for (int c = 0; c <= p; ++c)
          M(B.first + a, B.first + c) += w * (fairness * B.N[2][a] * B.N[2][c] + w3 * B.N[3][a] * B.N[3][c]);
    }
  // Fix the end poles to the end points, solve for the interior.
  Eigen::MatrixXd Q(n, 2);
  Q.row(0) = P.front().transpose();
  Q.row(n - 1) = P.back().transpose();
  const int m = n - 2;
  Eigen::MatrixXd r = rhs.middleRows(1, m) - M.block(1, 0, m, 1) * Q.row(0) - M.block(1, n - 1, m, 1) * Q.row(n - 1);
  Q.middleRows(1, m) = M.block(1, 1, m, m).ldlt().solve(r);
  std::vector<Vec2> poles(n);
  for (int i = 0; i < n; ++i) poles[i] = Q.row(i).transpose();
  return BSplineCurve2(p, U, poles);
}

double project(const BSplineCurve2& c, const Vec2& x, double u) {
  for (int it = 0; it < 20; ++it) {
    const auto d = c.derivatives(u);
    const double g = (d[0] - x).dot(d[1]), h = d[1].squaredNorm() + (d[0] - x).dot(d[2]);
    if (h <= 0) break;
    const double un = std::clamp(u - g / h, 0.0, 1.0);
    if (std::abs(un - u) < 1e-14) return un;
    u = un;
  }
  return u;
}

FairFitResult fit_with(const std::vector<Vec2>& P, const FairFitOptions& o, const std::vector<Penalty>& local) {
  const int N = static_cast<int>(P.size());
  std::vector<double> t(N, 0.0);
  double total = 0;
  for (int i = 1; i < N; ++i) total += (P[i] - P[i - 1]).norm();
  for (int i = 1; i < N; ++i) t[i] = t[i - 1] + (P[i] - P[i - 1]).norm() / total;
  t[N - 1] = 1.0;
  // Scale-free fairness: lengths measured in units of the chord.
  const double f = o.fairness;  // both terms are in length² (u ∈ [0, 1])
  BSplineCurve2 c = solve_fit(P, t, o.poles, o.degree, f, local);
  for (int k = 0; k < o.parameter_corrections; ++k) {
    for (int i = 1; i + 1 < N; ++i) t[i] = project(c, P[i], t[i]);
    c = solve_fit(P, t, o.poles, o.degree, f, local);
  }
  FairFitResult r(c);
  double s2 = 0;
  for (int i = 0; i < N; ++i) {
    const double e = (c.point(project(c, P[i], t[i])) - P[i]).norm();
    r.max_error = std::max(r.max_error, e);
    s2 += e * e;
  }
  r.rms_error = std::sqrt(s2 / N);
  return r;
}

void check_points(const std::vector<Vec2>& P, const FairFitOptions& o) {
  PARAFAB_VERIFY(o.degree >= 2 && o.degree <= 7, "fit.degree must be 2..7, got " << o.degree);
  PARAFAB_VERIFY(o.poles >= o.degree + 1, "fit.poles must be at least degree + 1 = " << o.degree + 1 << ", got " << o.poles);
  PARAFAB_VERIFY(static_cast<int>(P.size()) >= o.poles,
                 "curve.points: a fit with " << o.poles << " poles needs at least as many points, got " << P.size());
  PARAFAB_VERIFY(std::isfinite(o.fairness) && o.fairness >= 0, "fit.fairness must be >= 0, got " << o.fairness);
  for (size_t i = 0; i < P.size(); ++i) {
    if (!P[i].allFinite()) PARAFAB_INPUT_ERROR("curve.points[" << i << "] is not finite");
    if (i > 0 && P[i] == P[i - 1]) PARAFAB_INPUT_ERROR("curve.points[" << i << "] repeats curve.points[" << i - 1 << "]");
  }
}
}  // namespace

FairFitResult fit_fair_bspline(const std::vector<Vec2>& points, const FairFitOptions& o) {
  check_points(points, o);
  return fit_with(points, o, {});
}

SpuriousInflectionResult fair_section_curve(const std::vector<Vec2>& points, const SpuriousInflectionOptions& o) {
  check_points(points, o.fit);
  PARAFAB_VERIFY(o.min_separation > 0 && o.min_separation < 1,
                 "min_separation must lie in (0, 1) (a fraction of the length), got " << o.min_separation);
  std::vector<Penalty> local;
  FairFitResult fit = fit_with(points, o.fit, local);
  SpuriousInflectionResult res(fit.curve);
  for (int round = 0;; ++round) {
    const PlaneCurve pc(fit.curve);
    const double l = pc.length();
    const std::vector<double> infl = inflection_parameters(fit.curve);
    if (round == 0) res.inflections_before = static_cast<int>(infl.size());
    std::vector<double> s;
    for (double u : infl) s.push_back(pc.arc_length_at(u));
    // Lobes to flatten: consecutive inflections closer than the threshold (and, optionally,
    // inflections too close to an end).
    std::vector<std::pair<double, double>> lobes;
    for (size_t k = 0; k + 1 < s.size(); ++k)
      if (s[k + 1] - s[k] < o.min_separation * l) lobes.push_back({infl[k], infl[k + 1]}), ++k;
    if (o.end_separation > 0)
      for (size_t k = 0; k < s.size(); ++k) {
        if (s[k] < o.end_separation * l) lobes.push_back({0.0, infl[k]});
        if (l - s[k] < o.end_separation * l) lobes.push_back({infl[k], 1.0});
      }
    res.curve = fit.curve;
    res.inflections = static_cast<int>(infl.size());
    res.inflection_s = s;
    res.max_error = fit.max_error;
    res.rounds = round;
    if (lobes.empty()) {
      res.done = true;
      break;
    }
    if (round >= o.max_rounds) {
      res.message = "spurious inflection pairs remain after the maximal number of rounds";
      break;
    }
    // A penalty on each lobe widened by its own width; raise existing ones.
    for (const auto& [lo, hi] : lobes) {
      const double w = std::max(hi - lo, 1.0 / o.fit.poles);
      const double a = std::max(0.0, lo - w), b = std::min(1.0, hi + w);
      bool found = false;
      for (auto& pen : local)
        if (pen.lo <= b && pen.hi >= a) {
          pen.lo = std::min(pen.lo, a), pen.hi = std::max(pen.hi, b), pen.weight *= o.growth;
          found = true;
        }
      if (!found) local.push_back({a, b, std::max(o.fit.fairness, 1e-8)});
    }
    fit = fit_with(points, o.fit, local);
  }
  return res;
}

}  // namespace parafab
