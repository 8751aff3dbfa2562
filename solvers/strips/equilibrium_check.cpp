#include "strips/equilibrium_check.h"

#include <Eigen/Dense>
#include <cmath>
#include <sstream>

namespace parafab {

const char* to_code(Infeasibility reason) {
  switch (reason) {
    case Infeasibility::None: return "";
    case Infeasibility::FlatPiece: return "curvature_vanishes_on_interval";
    case Infeasibility::NotSecantBounded: return "not_secant_bounded";
    case Infeasibility::NotCollinear: return "inflections_not_collinear";
    case Infeasibility::LineTangentAtInflection: return "line_tangent_at_inflection";
    case Infeasibility::LineCrossesCurve: return "line_crosses_curve";
    case Infeasibility::NoLineAvoidsCurve: return "no_line_avoids_curve";
  }
  return "unknown";
}

namespace {
EquilibriumCheck fail(Infeasibility reason, double s, const std::string& message) {
  EquilibriumCheck c;
  c.reason = reason;
  c.where_s = s;
  c.message = message;
  return c;
}
double cross(const Vec2& a, const Vec2& b) { return a.x() * b.y() - a.y() * b.x(); }
}  // namespace

EquilibriumCheck check_equilibrium(const PlaneCurve& curve, const ZeroCurvatureResult& zeros,
                                   const EquilibriumCheckOptions& options) {
  const double l = curve.length();
  std::ostringstream os;
  if (zeros.straight) return {};
  if (zeros.flat_piece) {
    os << "the curvature vanishes on the whole interval s = [" << zeros.flat_from_s << ", "
       << zeros.flat_to_s << "] (a straight piece inside a bent curve): Theorem 1 needs finitely "
       << "many zero-curvature points; split the curve there";
    return fail(Infeasibility::FlatPiece, zeros.flat_from_s, os.str());
  }
  // Condition 2: secant-boundedness (for C¹ curvature: κ' ≠ 0 at every zero).
  for (const auto& z : zeros.points) {
    const double rel = std::abs(z.at.dkappa_ds) * l / zeros.kappa_scale;
    if (z.kind == ZeroKind::Touch || rel < options.secant_tolerance) {
      os << "the curvature is not secant-bounded at s = " << z.at.s << " (κ = " << z.at.kappa
         << ", κ' = " << z.at.dkappa_ds << (z.kind == ZeroKind::Touch ? ", κ does not change sign" : "")
         << "): no admissible stiffness is finite and positive there";
      return fail(Infeasibility::NotSecantBounded, z.at.s, os.str());
    }
  }
  EquilibriumCheck result;
  if (zeros.points.size() < 2) return result;  // the LP chooses the line direction

  // Condition 1a: collinearity. Total least squares line through the zeros.
  const size_t m = zeros.points.size();
  Vec2 mean = Vec2::Zero();
  for (const auto& z : zeros.points) mean += z.at.point;
  mean /= static_cast<double>(m);
  Eigen::Matrix2d cov = Eigen::Matrix2d::Zero();
  for (const auto& z : zeros.points) cov += (z.at.point - mean) * (z.at.point - mean).transpose();
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> eig(cov);
  const Vec2 dir = eig.eigenvectors().col(1).normalized();
  const Vec2 normal(-dir.y(), dir.x());
  double worst = 0;
  size_t worst_i = 0;
  for (size_t i = 0; i < m; ++i) {
    const double d = std::abs(normal.dot(zeros.points[i].at.point - mean));
    if (d > worst) worst = d, worst_i = i;
  }
  if (worst > options.collinear_tolerance * l) {
    os << "the " << m << " inflections are not collinear: the one at s = "
       << zeros.points[worst_i].at.s << " lies " << worst
       << " away from the best line through all of them (tolerance "
       << options.collinear_tolerance * l << ")";
    return fail(Infeasibility::NotCollinear, zeros.points[worst_i].at.s, os.str());
  }
  result.line_known = true;
  result.line_point = mean;
  result.line_direction = dir;
  result.collinearity_error = worst;
  // Condition 1b: the line is not tangent at any zero.
  for (const auto& z : zeros.points) {
    if (std::abs(cross(dir, z.at.tangent)) < options.tangent_tolerance) {
      os << "the inflection line is tangent to the curve at s = " << z.at.s
         << ": K would have to be zero or unbounded there";
      return fail(Infeasibility::LineTangentAtInflection, z.at.s, os.str());
    }
  }
  // An end on the line: K = d/κ vanishes there unless κ does too. With |κ| below
  // end_zero_tolerance·max|κ| the end is a zero at the end (the zero finder only takes |κ|·l
  // up to its zero_tolerance, which an interpolated curve misses); otherwise K would vanish.
  auto dist = [&](double uu) { return normal.dot(curve.bspline().point(uu) - mean); };
  bool end_on_line[2] = {false, false};
  for (int e = 0; e < 2; ++e) {
    const double ue = e == 0 ? curve.first_parameter() : curve.last_parameter();
    const double se = e == 0 ? 0.0 : l;
    bool listed = false;
    // A zero within 1e-3·length of the end stands for it (as for crossings below).
    for (const auto& z : zeros.points) listed |= std::abs(z.at.s - se) <= 1e-3 * l;
    if (listed) continue;
    ZeroCurvaturePoint z;
    z.at = curve.at_parameter(ue);
    z.at.kappa -= zeros.natural_curvature;
    z.kind = ZeroKind::AtEnd;
    const bool flat_end = std::abs(z.at.kappa) <= options.end_zero_tolerance * zeros.kappa_scale;
    // On the line: within the collinearity tolerance, or, where κ vanishes at the end too,
    // within end_zero_tolerance·l (the line fitted through interpolated inflections misses an
    // end that is a zero of the sampled shape by about the inflections' own error: 1.4e-6 l
    // for y = sin x from x = 0 at 401 points).
    const double d_end = std::abs(dist(ue));
    if (d_end > options.collinear_tolerance * l && !(flat_end && d_end <= options.end_zero_tolerance * l)) continue;
    end_on_line[e] = true;
    if (!flat_end) {
      os << "the inflection line passes through the " << (e == 0 ? "start" : "end") << " of the curve (s = "
         << se << "), where κ − κ₀ = " << z.at.kappa << " 1/m is not zero: K would vanish there";
      return fail(Infeasibility::LineCrossesCurve, se, os.str());
    }
    result.end_zeros.push_back(z);
    result.collinearity_error = std::max(result.collinearity_error, std::abs(dist(ue)));
  }
  // Condition 1c: the line meets the curve nowhere else. Along the curve, the signed distance
  // d to the line must change sign exactly where κ does, so d·κ keeps one sign.
  const auto& u = zeros.scan_parameters;
  // A sign change of d within 1e-3·length of a zero is that zero (the fitted line passes
  // within the collinearity tolerance of it, not exactly through it); a real crossing that
  // close to an inflection still makes the LP infeasible and is reported from there.
  auto near_zero = [&](double sc) {
    for (const auto& z : zeros.points)
      if (std::abs(z.at.s - sc) <= 1e-3 * l) return true;
    return (end_on_line[0] && sc <= 1e-3 * l) || (end_on_line[1] && sc >= l - 1e-3 * l);
  };
  double prev_d = dist(u.front());
  for (size_t i = 1; i < u.size(); ++i) {
    const double d = dist(u[i]);
    if ((d > 0) != (prev_d > 0)) {
      double lo = u[i - 1], hi = u[i], dlo = prev_d;  // refine the crossing by bisection on d
      for (int it = 0; it < 100; ++it) {
        const double mid = 0.5 * (lo + hi), dm = dist(mid);
        if ((dm > 0) == (dlo > 0)) lo = mid, dlo = dm; else hi = mid;
      }
      const double sc = curve.arc_length_at(0.5 * (lo + hi));
      if (!near_zero(sc)) {
        os << "the inflection line crosses the curve at s = " << sc
           << ", which is not an inflection: K would change sign there";
        return fail(Infeasibility::LineCrossesCurve, sc, os.str());
      }
    }
    prev_d = d;
  }
  return result;
}

}  // namespace parafab
