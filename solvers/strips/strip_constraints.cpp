#include "strips/strip_constraints.h"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <sstream>

#include "common/error.h"
#include "common/gauss_legendre.h"

namespace parafab {

namespace {
// |κ'| l² below which a Newton stall is blamed on the inflection (a curve's inflections have
// |κ'| l² of order 1–10; the rows' round-off reaches the tolerance near 1e-4).
constexpr double kDegenerateInflection = 1e-3;

double det(const Vec2& a, const Vec2& b) { return a.x() * b.y() - a.y() * b.x(); }

// det(γ', γ'') and its u-derivative det(γ', γ''') at u.
std::pair<double, double> det_and_slope(const BSplineCurve2& c, double u) {
  const auto d = c.derivatives(u);
  return {det(d[1], d[2]), det(d[1], d[3])};
}
}  // namespace

std::vector<double> inflection_parameters(const BSplineCurve2& curve, int scan_per_span) {
  const std::vector<double> bp = curve.breakpoints();
  std::vector<double> u;
  u.push_back(bp.front());
  for (size_t k = 0; k + 1 < bp.size(); ++k)
    for (int j = 1; j <= scan_per_span; ++j) u.push_back(bp[k] + (bp[k + 1] - bp[k]) * j / scan_per_span);
  std::vector<double> D(u.size());
  double scale = 0;
  for (size_t i = 0; i < u.size(); ++i) scale = std::max(scale, std::abs(D[i] = det_and_slope(curve, u[i]).first));
  const double eps = 1e-13 * scale;
  std::vector<double> out;
  int last_sign = 0;
  double last_u = u.front();
  for (size_t i = 0; i < u.size(); ++i) {
    const int sg = D[i] > eps ? 1 : (D[i] < -eps ? -1 : 0);
    if (sg == 0) continue;
    if (last_sign != 0 && sg != last_sign) {
      double lo = last_u, hi = u[i], flo = det_and_slope(curve, lo).first;
      for (int it = 0; it < 200 && hi - lo > 1e-15 * (bp.back() - bp.front()); ++it) {
        const double mid = 0.5 * (lo + hi), fm = det_and_slope(curve, mid).first;
        if (fm == 0) { lo = hi = mid; break; }
        if ((fm < 0) == (flo < 0)) lo = mid, flo = fm;
        else hi = mid;
      }
      out.push_back(0.5 * (lo + hi));
    }
    last_sign = sg;
    last_u = u[i];
  }
  return out;
}

Eigen::VectorXd poles_vector(const BSplineCurve2& curve) {
  Eigen::VectorXd q(2 * curve.pole_count());
  for (int i = 0; i < curve.pole_count(); ++i) q.segment<2>(2 * i) = curve.poles()[i];
  return q;
}

void set_poles_vector(BSplineCurve2& curve, const Eigen::VectorXd& q) {
  PARAFAB_VERIFY(q.size() == 2 * curve.pole_count(),
                 "pole vector has " << q.size() << " entries, curve needs " << 2 * curve.pole_count());
  std::vector<Vec2> P(curve.pole_count());
  for (int i = 0; i < curve.pole_count(); ++i) P[i] = q.segment<2>(2 * i);
  curve.set_poles(std::move(P));
}

StripConstraints::StripConstraints(const BSplineCurve2& ref, double a, const Vec2& b,
                                   std::vector<double> inflection_u, const StripConstraintOptions& o)
    : o_(o), infl_(std::move(inflection_u)) {
  PARAFAB_VERIFY(!ref.rational(), "EnforceConstraints needs a non-rational B-spline");
  set_line(a, b);
  const double u0 = ref.first_parameter(), u1 = ref.last_parameter();
  const auto d0 = ref.derivatives(u0), d1 = ref.derivatives(u1);
  p0_ = d0[0], p1_ = d1[0];
  speed0_ = d0[1].norm(), speed1_ = d1[1].norm();
  PARAFAB_VERIFY(speed0_ > 0 && speed1_ > 0, "curve has zero speed at an end");
  n0_ = Vec2(-d0[1].y(), d0[1].x()) / speed0_;
  n1_ = Vec2(-d1[1].y(), d1[1].x()) / speed1_;
  const std::vector<double> bp = ref.breakpoints();
  const int m = std::max(1, o_.length_intervals_per_span);
  for (size_t k = 0; k + 1 < bp.size(); ++k)
    for (int j = 0; j < m; ++j) {
      const double lo = bp[k] + (bp[k + 1] - bp[k]) * j / m, hi = bp[k] + (bp[k + 1] - bp[k]) * (j + 1) / m;
      for (int g = 0; g < 8; ++g) {
        quad_u_.push_back(0.5 * (lo + hi) + 0.5 * (hi - lo) * kGauss8X[g]);
        quad_w_.push_back(0.5 * (hi - lo) * kGauss8W[g]);
      }
    }
  length_ = 0;
  for (size_t k = 0; k < quad_u_.size(); ++k) length_ += quad_w_[k] * ref.derivatives(quad_u_[k])[1].norm();
}

void StripConstraints::set_line(double a, const Vec2& b) {
  const double nb = b.norm();
  PARAFAB_VERIFY(std::isfinite(nb) && std::isfinite(a), "inflection line: a and b must be finite");
  if (nb == 0) {
    PARAFAB_VERIFY(infl_.empty() || !o_.inflections_on_line,
                   "inflection line: b = 0 but " << infl_.size() << " inflections must lie on it");
    a_ = 0, b_ = Vec2(0, 1);
    return;
  }
  a_ = a / nb, b_ = b / nb;
}

int StripConstraints::rows() const {
  return (o_.fix_end_points ? 4 : 0) + (o_.fix_end_tangents ? 2 : 0) + (o_.fix_length ? 1 : 0) +
         (o_.inflections_on_line ? static_cast<int>(infl_.size()) : 0);
}

bool StripConstraints::evaluate(const BSplineCurve2& curve, Eigen::VectorXd& G, Eigen::MatrixXd& J,
                                std::string* message) {
  const int n = 2 * curve.pole_count(), N = rows();
  G.setZero(N);
  J.setZero(N, n);
  const double u0 = curve.first_parameter(), u1 = curve.last_parameter();
  int r = 0;
  if (o_.fix_end_points || o_.fix_end_tangents) {
    const BSplineCurve2::Basis B0 = curve.basis(u0), B1 = curve.basis(u1);
    const auto d0 = curve.derivatives(u0), d1 = curve.derivatives(u1);
    if (o_.fix_end_points) {
      for (int c = 0; c < 2; ++c) {
        G(r + c) = d0[0](c) - p0_(c);
        G(r + 2 + c) = d1[0](c) - p1_(c);
        for (int j = 0; j <= curve.degree(); ++j) {
          J(r + c, 2 * (B0.first + j) + c) += B0.N[0][j];
          J(r + 2 + c, 2 * (B1.first + j) + c) += B1.N[0][j];
        }
      }
      r += 4;
    }
    if (o_.fix_end_tangents) {  // ⟨γ', n⟩ · l₀/|γ'₀|: length units
      const double f0 = length_ / speed0_, f1 = length_ / speed1_;
      G(r) = f0 * d0[1].dot(n0_);
      G(r + 1) = f1 * d1[1].dot(n1_);
      for (int j = 0; j <= curve.degree(); ++j)
        for (int c = 0; c < 2; ++c) {
          J(r, 2 * (B0.first + j) + c) += f0 * B0.N[1][j] * n0_(c);
          J(r + 1, 2 * (B1.first + j) + c) += f1 * B1.N[1][j] * n1_(c);
        }
      r += 2;
    }
  }
  if (o_.fix_length) {
    double l = 0;
    for (size_t k = 0; k < quad_u_.size(); ++k) {
      const BSplineCurve2::Basis B = curve.basis(quad_u_[k]);
      Vec2 d1 = Vec2::Zero();
      for (int j = 0; j <= curve.degree(); ++j) d1 += B.N[1][j] * curve.poles()[B.first + j];
      const double v = d1.norm();
      l += quad_w_[k] * v;
      const Vec2 t = d1 / v;
      for (int j = 0; j <= curve.degree(); ++j)
        for (int c = 0; c < 2; ++c) J(r, 2 * (B.first + j) + c) += quad_w_[k] * B.N[1][j] * t(c);
    }
    G(r++) = l - length_;
  }
  if (o_.inflections_on_line) {
    const double range = u1 - u0;
    for (size_t k = 0; k < infl_.size(); ++k) {
      double u = infl_[k];
      bool ok = false;
      for (int it = 0; it < 40; ++it) {  // Newton on det(γ', γ'') = 0
        const auto [D2, D3] = det_and_slope(curve, u);
        if (D3 == 0) break;
        const double du = std::clamp(-D2 / D3, -0.05 * range, 0.05 * range);
        u += du;
        if (u <= u0 || u >= u1) break;
        if (std::abs(du) <= 1e-15 * range) { ok = true; break; }
      }
      if (!ok) {
        const auto [D2, D3] = det_and_slope(curve, u);
        ok = u > u0 && u < u1 && std::abs(D2) <= 1e-12 * std::abs(D3) * range;
      }
      if (!ok) {
        if (message) {
          std::ostringstream os;
          os << "inflection " << k << " (last at u = " << infl_[k]
             << ") cannot be tracked: κ' vanishes there or it left the curve";
          *message = os.str();
        }
        return false;
      }
      infl_[k] = u;
      const BSplineCurve2::Basis B = curve.basis(u);
      const auto d = curve.derivatives(u);
      const double D3 = det(d[1], d[3]);
      G(r) = a_ + b_.dot(d[0]);
      const double bt = b_.dot(d[1]);
      for (int j = 0; j <= curve.degree(); ++j)
        for (int c = 0; c < 2; ++c) {
          Vec2 e = Vec2::Zero();
          e(c) = 1;
          const double dD2 = det(B.N[1][j] * e, d[2]) + det(d[1], B.N[2][j] * e);
          const double dt0 = -dD2 / D3;
          J(r, 2 * (B.first + j) + c) += b_(c) * B.N[0][j] + bt * dt0;
        }
      ++r;
    }
  }
  return true;
}

EnforceResult StripConstraints::enforce(BSplineCurve2& curve) {
  EnforceResult res;
  const Eigen::VectorXd q0 = poles_vector(curve);
  Eigen::VectorXd q = q0, G;
  Eigen::MatrixXd J;
  const double tol = o_.tolerance * length_;
  for (int it = 0;; ++it) {
    std::string msg;
    if (!evaluate(curve, G, J, &msg)) {
      res.message = msg;
      break;
    }
    res.residual = G.size() ? G.cwiseAbs().maxCoeff() : 0.0;
    res.iterations = it;
    if (res.residual <= tol) {
      res.converged = true;
      break;
    }
    if (it >= o_.max_iterations || !std::isfinite(res.residual)) {
      std::ostringstream os;
      os << "max |G| = " << res.residual << " after " << it << " Newton steps";
      if (o_.inflections_on_line && !infl_.empty()) {
        // The inflection rows' round-off grows like 1/κ' at the inflection: name the worst one,
        // so a stall on a degenerating inflection says so.
        size_t worst = 0;
        double worst_dk = INFINITY;
        for (size_t k = 0; k < infl_.size(); ++k) {
          const double dk = std::abs(pole_jet(curve, infl_[k]).dkappa_ds) * length_ * length_;
          if (dk < worst_dk) worst_dk = dk, worst = k;
        }
        os << "; inflection " << worst << " (at u = " << infl_[worst] << ") has |κ'| l² = " << worst_dk;
        if (worst_dk < kDegenerateInflection)
          os << ": it cannot be tracked to the tolerance, κ' vanishes there";
      }
      res.message = os.str();
      break;
    }
    Eigen::CompleteOrthogonalDecomposition<Eigen::MatrixXd> cod(J);
    q -= cod.solve(G);  // least-norm solution of J Δq = −G
    set_poles_vector(curve, q);
  }
  res.move = (poles_vector(curve) - q0).norm();
  return res;
}

Eigen::VectorXd StripConstraints::project_to_tangent(const BSplineCurve2& curve, const Eigen::VectorXd& v) {
  Eigen::VectorXd G;
  Eigen::MatrixXd J;
  evaluate(curve, G, J);
  if (J.rows() == 0) return v;
  Eigen::CompleteOrthogonalDecomposition<Eigen::MatrixXd> cod(J);
  return v - cod.solve(J * v);
}

Eigen::MatrixXd StripConstraints::tangent_basis(const BSplineCurve2& curve) {
  Eigen::VectorXd G;
  Eigen::MatrixXd J;
  evaluate(curve, G, J);
  const int n = static_cast<int>(J.cols());
  if (J.rows() == 0) return Eigen::MatrixXd::Identity(n, n);
  Eigen::ColPivHouseholderQR<Eigen::MatrixXd> qr(J.transpose());
  const int rank = static_cast<int>(qr.rank());
  const Eigen::MatrixXd Q = qr.householderQ() * Eigen::MatrixXd::Identity(n, n);
  return Q.rightCols(n - rank);
}

PNormRatio pnorm_ratio(const BSplineCurve2& curve, double a, const Vec2& b,
                       const std::vector<double>& sample_u, double p, double length, double skip_kappa) {
  PNormRatio r;
  const int n = 2 * curve.pole_count();
  std::vector<double> K;
  std::vector<PoleJet> jets;
  K.reserve(sample_u.size());
  jets.reserve(sample_u.size());
  for (double u : sample_u) {
    PoleJet J = pole_jet(curve, u);
    if (std::abs(J.kappa) * length <= skip_kappa) continue;
    const double k = (a + b.dot(J.d[0])) / J.kappa;
    if (!(k > 0)) return r;  // invalid: K changes sign
    K.push_back(k);
    jets.push_back(J);
  }
  if (K.empty()) return r;
  const double kmax = *std::max_element(K.begin(), K.end()), kmin = *std::min_element(K.begin(), K.end());
  // S₊ = mean (K/kmax)^p, S₋ = mean (kmin/K)^p; R_p = (kmax/kmin) S₊^{1/p} S₋^{1/p}.
  double Sp = 0, Sm = 0;
  for (double k : K) Sp += std::pow(k / kmax, p), Sm += std::pow(kmin / k, p);
  const double m = static_cast<double>(K.size());
  Sp /= m, Sm /= m;
  r.valid = true;
  r.K_min = kmin, r.K_max = kmax, r.R = kmax / kmin;
  r.value = r.R * std::pow(Sp, 1 / p) * std::pow(Sm, 1 / p);
  // d log R_p / dK_i = (K_i/kmax)^{p} / (m S₊ K_i) − (kmin/K_i)^{p} / (m S₋ K_i)
  r.gradient.setZero(n);
  for (size_t i = 0; i < K.size(); ++i) {
    const double k = K[i];
    const double dlog = (std::pow(k / kmax, p) / Sp - std::pow(kmin / k, p) / Sm) / (m * k);
    if (dlog == 0) continue;
    const PoleJet& J = jets[i];
    // K = (a + ⟨b, γ⟩)/κ: ∂K/∂P_j = (b N_j − K ∂κ/∂P_j)/κ
    for (int j = 0; j < J.count; ++j) {
      const Vec2 dK = (b * J.basis.N[0][j] - k * J.dkappa[j]) / J.kappa;
      r.gradient.segment<2>(2 * (J.basis.first + j)) += r.value * dlog * dK;
    }
  }
  return r;
}

Eigen::VectorXd project_step(const Eigen::VectorXd& dq, double R, const Eigen::VectorXd& grad_R, double R_max) {
  const double pred = R + grad_R.dot(dq);
  const double g2 = grad_R.squaredNorm();
  if (pred <= R_max || g2 == 0) return dq;
  return dq - ((pred - R_max) / g2) * grad_R;
}

}  // namespace parafab
