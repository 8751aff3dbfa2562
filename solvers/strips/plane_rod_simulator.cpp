#include "strips/plane_rod_simulator.h"

#include <Eigen/SparseCore>
#include <Eigen/SparseLU>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <sstream>

#include "common/error.h"
#include "strips/plane_rod_discretization.h"

namespace parafab {

namespace {

using plane_rod::interpolate;

struct Rod {
  int N = 0;
  double h = 0;
  std::vector<double> w, W;          // Voronoi weights and stiffness at nodes 0..N
  bool node_active[2] = {true, true};  // node 0 / node N carry a clamp term
  double theta0 = 0, theta1 = 0;
  std::vector<double> kappa0;        // natural curvature at nodes 0..N
  MomentLaw law;
  Vec2 e{0, 0};
  bool ref_start[2] = {true, true};  // positions of coordinate d referenced to the start
  bool constrained[2] = {true, true};
  Vec2 delta{0, 0};                  // end − start
  std::vector<double> Q[2];          // gravity weights per edge and coordinate
  int nc = 0;
  int cidx[2] = {-1, -1};

  bool active(int k) const {
    if (k == 0) return node_active[0];
    if (k == N) return node_active[1];
    return true;
  }
  double angle(const Eigen::VectorXd& a, int j) const {
    return j < 0 ? theta0 : (j >= N ? theta1 : a(j));
  }
  double node_curvature(const Eigen::VectorXd& a, int k) const {
    return (angle(a, k) - angle(a, k - 1)) / w[k];
  }

  double energy(const Eigen::VectorXd& a) const {
    double E = 0;
    for (int k = 0; k <= N; ++k)
      if (active(k)) E += w[k] * W[k] * law.energy(node_curvature(a, k) - kappa0[k]);
    for (int j = 0; j < N; ++j) {
      const Vec2 t(std::cos(a(j)), std::sin(a(j)));
      for (int d = 0; d < 2; ++d) E -= h * t(d) * e(d) * Q[d][j];
    }
    return E;
  }

  // Residual of the KKT system at z = (α, λ), and optionally its Jacobian.
  void residual(const Eigen::VectorXd& z, Eigen::VectorXd& r,
                Eigen::SparseMatrix<double>* J) const {
    const Eigen::VectorXd a = z.head(N);
    r.setZero(N + nc);
    std::vector<Eigen::Triplet<double>> tr;
    if (J) tr.reserve(3 * N + 4 * N);
    for (int k = 0; k <= N; ++k) {
      if (!active(k)) continue;
      const double kap = node_curvature(a, k) - kappa0[k];
      const double m = W[k] * law.moment(kap), dm = W[k] * law.slope(kap) / w[k];
      // κ_k depends on α_k (+) and α_{k−1} (−).
      if (k < N) r(k) += m;
      if (k >= 1) r(k - 1) -= m;
      if (J) {
        if (k < N) tr.emplace_back(k, k, dm);
        if (k >= 1) tr.emplace_back(k - 1, k - 1, dm);
        if (k >= 1 && k < N) tr.emplace_back(k, k - 1, -dm), tr.emplace_back(k - 1, k, -dm);
      }
    }
    for (int j = 0; j < N; ++j) {
      const Vec2 t(std::cos(a(j)), std::sin(a(j))), tp(-t.y(), t.x());
      double diag = 0;
      for (int d = 0; d < 2; ++d) {
        r(j) -= h * tp(d) * e(d) * Q[d][j];
        diag += h * t(d) * e(d) * Q[d][j];
      }
      for (int d = 0; d < 2; ++d) {
        if (!constrained[d]) continue;
        const double lam = z(N + cidx[d]);
        r(j) += lam * h * tp(d);
        diag -= lam * h * t(d);
        r(N + cidx[d]) += h * t(d);
        if (J) tr.emplace_back(j, N + cidx[d], h * tp(d)), tr.emplace_back(N + cidx[d], j, h * tp(d));
      }
      if (J) tr.emplace_back(j, j, diag);
    }
    for (int d = 0; d < 2; ++d)
      if (constrained[d]) r(N + cidx[d]) -= delta(d);
    if (J) {
      J->resize(N + nc, N + nc);
      J->setFromTriplets(tr.begin(), tr.end());
    }
  }
};

}  // namespace

PlaneRodResult simulate_plane_rod(const PlaneRodProblem& p, const PlaneRodOptions& o) {
  const auto t0 = std::chrono::steady_clock::now();
  PARAFAB_VERIFY(std::isfinite(p.length) && p.length > 0, "rod.length must be positive, got " << p.length);
  PARAFAB_VERIFY(o.edges >= 4, "simulation.edges must be >= 4, got " << o.edges);
  PARAFAB_VERIFY(p.stiffness_s.size() == p.stiffness.size() && !p.stiffness.empty(),
                 "rod.stiffness: " << p.stiffness.size() << " values for " << p.stiffness_s.size()
                                   << " arc lengths");
  for (size_t i = 0; i < p.stiffness.size(); ++i) {
    PARAFAB_VERIFY(std::isfinite(p.stiffness[i]) && p.stiffness[i] > 0,
                   "rod.stiffness[" << i << "] must be positive, got " << p.stiffness[i]);
    PARAFAB_VERIFY(i == 0 || p.stiffness_s[i] >= p.stiffness_s[i - 1],
                   "rod.stiffness_s must be sorted; entry " << i << " is " << p.stiffness_s[i]);
  }
  PARAFAB_VERIFY(p.initial_angles.empty() || static_cast<int>(p.initial_angles.size()) == o.edges,
                 "rod.initial_angles has " << p.initial_angles.size() << " entries for "
                                           << o.edges << " edges");
  p.law.validate();
  Rod rod;
  const int N = o.edges;
  rod.N = N;
  rod.h = p.length / N;
  rod.w.assign(N + 1, rod.h);
  rod.w[0] = rod.w[N] = 0.5 * rod.h;
  rod.W.resize(N + 1);
  for (int k = 0; k <= N; ++k) rod.W[k] = interpolate(p.stiffness_s, p.stiffness, k * rod.h);
  PARAFAB_VERIFY(p.weight_ratio.empty() || p.weight_ratio.size() == p.stiffness.size(),
                 "rod.weight_ratio: " << p.weight_ratio.size() << " values for " << p.stiffness.size()
                                      << " stiffness samples");
  std::vector<double> weight(rod.W);  // weight per length / |e| at the nodes
  if (!p.weight_ratio.empty())
    for (int k = 0; k <= N; ++k) weight[k] *= interpolate(p.stiffness_s, p.weight_ratio, k * rod.h);
  rod.node_active[0] = !p.boundary.start.free_angle;
  rod.node_active[1] = !p.boundary.end.free_angle;
  rod.theta0 = p.start_angle;
  rod.theta1 = p.end_angle;
  PARAFAB_VERIFY(p.natural_curvature_s.size() == p.natural_curvature_field.size(),
                 "rod.natural_curvature_field: " << p.natural_curvature_field.size() << " values for "
                                                 << p.natural_curvature_s.size() << " arc lengths");
  rod.kappa0.assign(N + 1, p.natural_curvature);
  if (!p.natural_curvature_s.empty())
    for (int k = 0; k <= N; ++k)
      rod.kappa0[k] += interpolate(p.natural_curvature_s, p.natural_curvature_field, k * rod.h);
  rod.law = p.law;
  rod.delta = p.end_point - p.start_point;
  // Node positions referenced to the start or the end, and the load weights Q per edge.
  const plane_rod::EndReferences ends = plane_rod::end_references(p.boundary, weight, rod.w, N);
  for (int d = 0; d < 2; ++d) {
    rod.constrained[d] = ends.constrained[d];
    rod.ref_start[d] = ends.ref_start[d];
    rod.Q[d] = ends.Q[d];
    if (rod.constrained[d]) rod.cidx[d] = rod.nc++;
  }
  const double Wmax = *std::max_element(rod.W.begin(), rod.W.end());
  const double mscale = Wmax / p.length, pscale = p.length;

  Eigen::VectorXd z = Eigen::VectorXd::Zero(N + rod.nc);
  for (int j = 0; j < N; ++j)
    z(j) = p.initial_angles.empty() ? p.start_angle + (p.end_angle - p.start_angle) * (j + 0.5) / N
                                    : p.initial_angles[j];
  PlaneRodResult out;
  auto scaled_norm = [&](const Eigen::VectorXd& r) {
    double m = 0;
    for (int i = 0; i < N; ++i) m = std::max(m, std::abs(r(i)) / mscale);
    for (int i = N; i < N + rod.nc; ++i) m = std::max(m, std::abs(r(i)) / pscale);
    return m;
  };
  auto merit = [&](const Eigen::VectorXd& r) {
    double s = 0;
    for (int i = 0; i < N; ++i) s += std::pow(r(i) / mscale, 2);
    for (int i = N; i < N + rod.nc; ++i) s += std::pow(r(i) / pscale, 2);
    return s;
  };
  // Newton at the current load; returns true when converged.
  const Vec2 e_full = p.load;
  Eigen::SparseLU<Eigen::SparseMatrix<double>> lu;
  bool analyzed = false;
  auto newton = [&](Eigen::VectorXd& zz) {
    Eigen::VectorXd r;
    Eigen::SparseMatrix<double> J;
    for (int it = 0; it < o.max_iterations; ++it) {
      rod.residual(zz, r, &J);
      out.residual = scaled_norm(r);
      if (out.residual <= o.tolerance) return true;
      J.makeCompressed();
      if (!analyzed) lu.analyzePattern(J), analyzed = true;
      lu.factorize(J);
      if (lu.info() != Eigen::Success) {
        out.message = "singular KKT matrix (a zero tangent stiffness, e.g. ideal plasticity "
                      "with zero hardening?)";
        return false;
      }
      const Eigen::VectorXd dz = lu.solve(-r);
      ++out.iterations;
      const double phi0 = merit(r);
      double t = 1;
      Eigen::VectorXd rn;
      bool accepted = false;
      for (int ls = 0; ls < 40; ++ls, t *= 0.5) {
        rod.residual(zz + t * dz, rn, nullptr);
        if (merit(rn) <= (1 - 1e-4 * t) * phi0) { accepted = true; break; }
      }
      if (!accepted) {
        // Round-off floor: accept a full step if the residual is already tiny.
        if (out.residual <= 1e3 * o.tolerance) { zz += dz; return true; }
        out.message = "line search failed";
        return false;
      }
      zz += t * dz;
      if (t * dz.head(N).cwiseAbs().maxCoeff() < 1e-15) {
        rod.residual(zz, r, nullptr);
        out.residual = scaled_norm(r);
        return out.residual <= 1e3 * o.tolerance;
      }
    }
    out.message = "no convergence within max_iterations";
    return false;
  };
  // Continuation in t ∈ [0, 1]: the weight grows as t·e and a finite curvature limit falls
  // geometrically from above the initial curvatures to its value. Start at t = 1; on
  // failure, go back to the last converged state and take smaller steps.
  const double klim = p.law.curvature_limit;
  double khi = klim;
  if (std::isfinite(klim)) {
    double kmax = 0;
    for (int k = 0; k <= N; ++k)
      if (rod.active(k)) kmax = std::max(kmax, std::abs(rod.node_curvature(z.head(N), k) - rod.kappa0[k]));
    khi = std::max(klim, 1.05 * kmax);
  }
  auto apply = [&](double t) {
    rod.e = e_full * t;
    if (std::isfinite(klim)) rod.law.curvature_limit = khi * std::pow(klim / khi, t);
  };
  const bool homotopy = e_full.norm() > 0 || khi > klim;
  double done = homotopy ? 0.0 : 1.0, step = 1.0;
  Eigen::VectorXd z_ok = z;
  if (!homotopy) {
    out.converged = newton(z);
    out.load_steps = 1;
  } else {
    while (done < 1.0) {
      const double target = std::min(1.0, done + step);
      apply(target);
      Eigen::VectorXd zt = z_ok;
      ++out.load_steps;
      if (newton(zt)) {
        z_ok = zt;
        done = target;
        step = std::min(1.0, 2 * step);
      } else {
        step *= 0.5;
        if (step < 1.0 / o.max_load_steps) break;
      }
    }
    out.converged = done >= 1.0;
    if (!out.converged) {
      std::ostringstream os;
      os << out.message << " (continuation in load and curvature limit reached t = " << done << ")";
      out.message = os.str();
    }
    z = z_ok;
    apply(1.0);
  }
  if (out.converged) out.message.clear();
  // Outputs.
  const Eigen::VectorXd a = z.head(N);
  out.edge_angles.assign(a.data(), a.data() + N);
  out.node_s.resize(N + 1);
  out.nodes.assign(N + 1, Vec2::Zero());
  out.curvature.resize(N + 1);
  for (int k = 0; k <= N; ++k) {
    out.node_s[k] = k * rod.h;
    out.curvature[k] = rod.active(k) ? rod.node_curvature(a, k) : 0.0;
  }
  for (int d = 0; d < 2; ++d) {
    if (rod.ref_start[d]) {
      double x = p.start_point(d);
      out.nodes[0](d) = x;
      for (int j = 0; j < N; ++j) x += rod.h * (d == 0 ? std::cos(a(j)) : std::sin(a(j))), out.nodes[j + 1](d) = x;
    } else {
      double x = p.end_point(d);
      out.nodes[N](d) = x;
      for (int j = N - 1; j >= 0; --j) x -= rod.h * (d == 0 ? std::cos(a(j)) : std::sin(a(j))), out.nodes[j](d) = x;
    }
    if (rod.constrained[d]) out.multiplier(d) = z(N + rod.cidx[d]);
  }
  out.end_force = -out.multiplier;
  out.energy = rod.energy(a);
  out.constraints = rod.nc;
  if (o.hessian) {
    Eigen::VectorXd r;
    rod.residual(z, r, &out.kkt);
    out.kkt.makeCompressed();
  }
  out.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return out;
}

}  // namespace parafab
