// Thesis §4.5 / §4.6.1: energy-decreasing release of a plane rod. See plane_rod_release.h.
#include "strips/plane_rod_release.h"

#include <Eigen/Dense>
#include <algorithm>
#include <chrono>
#include <cmath>

#include "common/error.h"
#include "strips/plane_rod_discretization.h"

namespace parafab {

namespace {

using plane_rod::interpolate;

struct Model {
  int N = 0;
  double h = 0, mu = 0, kappa0 = 0, theta0 = 0, theta1 = 0;
  std::vector<double> w, K;
  bool act[2] = {true, true};
  bool constrained[2] = {true, true}, ref_start[2] = {true, true};
  std::vector<double> Q[2];
  Vec2 e{0, 0}, delta{0, 0};
  MomentLaw law;

  bool active(int k) const { return k == 0 ? act[0] : (k == N ? act[1] : true); }
  double angle(const Eigen::VectorXd& a, int j) const { return j < 0 ? theta0 : (j >= N ? theta1 : a(j)); }
  double kap(const Eigen::VectorXd& a, int k) const { return (angle(a, k) - angle(a, k - 1)) / w[k] - kappa0; }
  Vec2 chord(const Eigen::VectorXd& a) const {
    Vec2 c(0, 0);
    for (int j = 0; j < N; ++j) c += h * Vec2(std::cos(a(j)), std::sin(a(j)));
    return c - delta;
  }

  double energy(const Eigen::VectorXd& a) const {
    double E = 0;
    for (int k = 0; k <= N; ++k)
      if (active(k)) E += w[k] * K[k] * law.energy(kap(a, k));
    for (int j = 0; j < N; ++j)
      for (int d = 0; d < 2; ++d) E -= h * (d == 0 ? std::cos(a(j)) : std::sin(a(j))) * e(d) * Q[d][j];
    const Vec2 c = chord(a);
    for (int d = 0; d < 2; ++d)
      if (constrained[d]) E += 0.5 * mu * c(d) * c(d);
    return E;
  }

  void derivatives(const Eigen::VectorXd& a, Eigen::VectorXd& g, Eigen::MatrixXd& H) const {
    g.setZero(N);
    H.setZero(N, N);
    for (int k = 0; k <= N; ++k) {
      if (!active(k)) continue;
      const double kk = kap(a, k);
      const double m = K[k] * law.moment(kk), dm = K[k] * law.slope(kk) / w[k];
      if (k < N) g(k) += m, H(k, k) += dm;
      if (k >= 1) g(k - 1) -= m, H(k - 1, k - 1) += dm;
      if (k >= 1 && k < N) H(k, k - 1) -= dm, H(k - 1, k) -= dm;
    }
    const Vec2 c = chord(a);
    Eigen::MatrixXd U(N, 2);
    for (int j = 0; j < N; ++j) {
      const Vec2 t(std::cos(a(j)), std::sin(a(j))), tp(-t.y(), t.x());
      for (int d = 0; d < 2; ++d) {
        g(j) -= h * tp(d) * e(d) * Q[d][j];
        H(j, j) += h * t(d) * e(d) * Q[d][j];
        U(j, d) = constrained[d] ? h * tp(d) : 0.0;
        if (constrained[d]) {
          g(j) += mu * c(d) * h * tp(d);
          H(j, j) -= mu * c(d) * h * t(d);
        }
      }
    }
    H.noalias() += mu * U * U.transpose();
  }
};

}  // namespace

PlaneRodReleaseResult release_plane_rod(const PlaneRodProblem& p, const PlaneRodReleaseOptions& o) {
  const auto t0 = std::chrono::steady_clock::now();
  const int N = o.edges;
  PARAFAB_VERIFY(N >= 4, "release.edges must be >= 4, got " << N);
  PARAFAB_VERIFY(std::isfinite(p.length) && p.length > 0, "rod.length must be positive, got " << p.length);
  PARAFAB_VERIFY(static_cast<int>(p.initial_angles.size()) == N,
                 "release: rod.initial_angles has " << p.initial_angles.size() << " entries for " << N << " edges");
  PARAFAB_VERIFY(p.stiffness_s.size() == p.stiffness.size() && !p.stiffness.empty(),
                 "rod.stiffness: " << p.stiffness.size() << " values for " << p.stiffness_s.size() << " arc lengths");
  PARAFAB_VERIFY(o.penalty > 0, "release.penalty must be positive, got " << o.penalty);
  p.law.validate();
  Model m;
  m.N = N;
  m.h = p.length / N;
  m.w.assign(N + 1, m.h);
  m.w[0] = m.w[N] = 0.5 * m.h;
  m.K.resize(N + 1);
  for (int k = 0; k <= N; ++k) {
    m.K[k] = interpolate(p.stiffness_s, p.stiffness, k * m.h);
    PARAFAB_VERIFY(m.K[k] > 0, "rod.stiffness must be positive, got " << m.K[k] << " at s = " << k * m.h);
  }
  m.act[0] = !p.boundary.start.free_angle;
  m.act[1] = !p.boundary.end.free_angle;
  m.theta0 = p.start_angle;
  m.theta1 = p.end_angle;
  m.kappa0 = p.natural_curvature;
  m.law = p.law;
  m.e = p.load;
  m.delta = p.end_point - p.start_point;
  const double Kmax = *std::max_element(m.K.begin(), m.K.end());
  m.mu = o.penalty * Kmax / std::pow(p.length, 3);
  const plane_rod::EndReferences ends = plane_rod::end_references(p.boundary, m.K, m.w, N);
  for (int d = 0; d < 2; ++d) m.constrained[d] = ends.constrained[d], m.ref_start[d] = ends.ref_start[d], m.Q[d] = ends.Q[d];
  Eigen::VectorXd a = Eigen::Map<const Eigen::VectorXd>(p.initial_angles.data(), N);
  PlaneRodReleaseResult out;
  double E = m.energy(a);
  out.initial_energy = E;
  const double gscale = Kmax / p.length;
  Eigen::VectorXd g;
  Eigen::MatrixXd H;
  double tau = 0;
  for (int it = 0; it < o.max_iterations; ++it) {
    m.derivatives(a, g, H);
    if (g.cwiseAbs().maxCoeff() <= o.tolerance * gscale) {
      out.converged = true;
      break;
    }
    // Hessian modification: H + τ I positive definite.
    const double hscale = H.diagonal().cwiseAbs().maxCoeff();
    tau = 0;
    Eigen::LLT<Eigen::MatrixXd> llt;
    for (int s = 0; s < 80; ++s) {
      Eigen::MatrixXd Ht = H;
      Ht.diagonal().array() += tau;
      llt.compute(Ht);
      if (llt.info() == Eigen::Success) break;
      tau = tau == 0 ? 1e-8 * hscale : 4 * tau;
    }
    if (tau > 0) ++out.hessian_shifts;
    const Eigen::VectorXd dir = llt.solve(-g);
    const double slope = g.dot(dir);
    double step = 1;
    bool accepted = false, stalled = false;
    for (int ls = 0; ls < 60; ++ls, step *= 0.5) {
      const Eigen::VectorXd trial = a + step * dir;
      const double Et = m.energy(trial);
      if (Et <= E + 1e-4 * step * slope) {
        if (!(Et <= E)) out.monotone = false;
        stalled = E - Et <= 1e-14 * std::abs(E);
        a = trial;
        E = Et;
        accepted = true;
        break;
      }
    }
    ++out.iterations;
    if (accepted && stalled && g.cwiseAbs().maxCoeff() <= 1e3 * o.tolerance * gscale) {
      out.converged = true;  // round-off floor of the penalty: E no longer decreases
      break;
    }
    if (!accepted) {
      // Round-off floor: the energy cannot be lowered any further.
      out.converged = g.cwiseAbs().maxCoeff() <= 1e3 * o.tolerance * gscale;
      if (!out.converged) out.message = "line search failed";
      break;
    }
  }
  if (!out.converged && out.message.empty()) out.message = "no convergence within max_iterations";
  out.energy = E;
  out.edge_angles.assign(a.data(), a.data() + N);
  out.nodes.assign(N + 1, Vec2::Zero());
  for (int d = 0; d < 2; ++d) {
    if (m.ref_start[d]) {
      double x = p.start_point(d);
      out.nodes[0](d) = x;
      for (int j = 0; j < N; ++j) x += m.h * (d == 0 ? std::cos(a(j)) : std::sin(a(j))), out.nodes[j + 1](d) = x;
    } else {
      double x = p.end_point(d);
      out.nodes[N](d) = x;
      for (int j = N - 1; j >= 0; --j) x -= m.h * (d == 0 ? std::cos(a(j)) : std::sin(a(j))), out.nodes[j](d) = x;
    }
  }
  const Vec2 c = m.chord(a);
  out.end_point_error = std::hypot(m.constrained[0] ? c(0) : 0.0, m.constrained[1] ? c(1) : 0.0);
  out.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return out;
}

}  // namespace parafab
