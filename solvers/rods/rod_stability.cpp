// Thesis §4.5.1 eigenvalue condition on the discrete elastic rod (§5.7.4). See rod_stability.h.
#include "rods/rod_stability.h"

#include <Eigen/Dense>
#include <chrono>
#include <cmath>

#include "common/error.h"

namespace parafab {

RodStability rod_stability(const DiscreteRodModel& m, const RodStabilityOptions& o) {
  const auto t0 = std::chrono::steady_clock::now();
  const int N = static_cast<int>(m.material_normal.size());
  PARAFAB_VERIFY(N >= 4 && static_cast<int>(m.nodes.size()) == N + 1,
                 "rod_stability: a rod of at least 4 edges with N + 1 nodes is needed, got "
                     << m.nodes.size() << " nodes and " << N << " edges");
  const int n = 3 * (N + 1) + N;
  Eigen::VectorXd g;
  Eigen::MatrixXd H;
  discrete_rod_energy(m, Eigen::VectorXd::Zero(n), &g, &H);
  // Free DOFs: nodes 2..N−2 and material angles 1..N−2 (as in simulate_discrete_rod).
  std::vector<int> free;
  for (int k = 6; k < 3 * (N - 1); ++k) free.push_back(k);
  for (int j = 1; j <= N - 2; ++j) free.push_back(3 * (N + 1) + j);
  const int nf = static_cast<int>(free.size());
  Eigen::MatrixXd Hf(nf, nf);
  for (int a = 0; a < nf; ++a)
    for (int b = 0; b < nf; ++b) Hf(a, b) = H(free[a], free[b]);
  Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> es(Hf, Eigen::EigenvaluesOnly);
  const Eigen::VectorXd ev = es.eigenvalues();
  const double scale = ev.cwiseAbs().maxCoeff();
  RodStability out;
  out.free_dofs = nf;
  for (int i = 0; i < nf; ++i) {
    if (std::abs(ev(i)) <= o.zero_tolerance * scale) ++out.zero;
    else if (ev(i) < 0) ++out.negative;
    else ++out.positive;
  }
  out.min_eigenvalue = ev(0);
  out.min_relative = ev(0) / Hf.diagonal().maxCoeff();
  out.stable = out.negative == 0 && out.zero == 0;
  if (out.negative > 0)
    out.message = std::to_string(out.negative) + " negative eigenvalue(s): an unstable equilibrium";
  out.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return out;
}

RodStability rod_stability_at_equilibrium(const DiscreteRodModel& m, const RodEquilibriumStabilityOptions& o) {
  const auto t0 = std::chrono::steady_clock::now();
  const DiscreteRodResult r = simulate_discrete_rod(m, o.simulation);
  RodStability out = rod_stability_at_equilibrium(m, r, o);
  out.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return out;
}

RodStability rod_stability_at_equilibrium(const DiscreteRodModel& m, const DiscreteRodResult& r,
                                          const RodEquilibriumStabilityOptions& o) {
  const auto t0 = std::chrono::steady_clock::now();
  PARAFAB_VERIFY(o.max_distance > 0, "rod_stability_at_equilibrium: max_distance must be > 0, got " << o.max_distance);
  PARAFAB_VERIFY(r.nodes.size() == m.nodes.size() && r.material_normal.size() == m.material_normal.size(),
                 "rod_stability_at_equilibrium: the equilibrium has " << r.nodes.size() << " nodes, the model "
                                                                     << m.nodes.size());
  double length = 0;
  for (size_t i = 1; i < m.nodes.size(); ++i) length += (m.nodes[i] - m.nodes[i - 1]).norm();
  const double distance = max_node_distance(r.nodes, m.nodes) / length;
  RodStability out;
  if (r.ok() && distance <= o.max_distance) {
    DiscreteRodModel at = m;
    at.nodes = r.nodes;
    at.material_normal = r.material_normal;
    out = rod_stability(at, o.hessian);
  } else {
    out.stable = false;
    if (distance > o.max_distance)
      out.message = "the discrete rod leaves the target: " +
                    std::string(r.ok() ? "its equilibrium lies " : "the simulation, not converged, is ") +
                    std::to_string(distance) + " of the length away (an unstable design)";
    else
      out.message = "the forward simulation from the target did not converge (" + r.message + ")";
  }
  out.method = "hessian_at_equilibrium";
  out.equilibrium_distance = distance;
  out.equilibrium_converged = r.ok();
  out.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return out;
}

}  // namespace parafab
