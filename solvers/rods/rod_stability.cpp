// Thesis §4.5.1 eigenvalue condition on the discrete elastic rod (§5.7.4). See rod_stability.h.
#include "rods/rod_stability.h"

#include <Eigen/Dense>
#include <chrono>
#include <cmath>
#include <cstdio>

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
  else if (out.zero > 0)
    out.message = std::to_string(out.zero) + " zero eigenvalue(s): no verdict from second order";
  out.verdict = out.stable ? "stable" : "unstable";
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
  const bool moved_away = distance > o.max_distance;
  // The inertia at the equilibrium the rod reached, wherever it lies (before, a rod farther than
  // max_distance was declared unstable with no Hessian computed: negative 0 reported, and a
  // stable rod at a coarse discretization, 1.3e-3 L off the target, was called unstable).
  if (r.ok()) {
    DiscreteRodModel at = m;
    at.nodes = r.nodes;
    at.material_normal = r.material_normal;
    out = rod_stability(at, o.hessian);
  }
  out.equilibrium_stable = r.ok() && out.stable;
  out.stable = out.equilibrium_stable && !moved_away;
  out.moved_away = moved_away;
  out.verdict = out.stable ? "stable" : out.equilibrium_stable ? "moved_away" : "unstable";
  // Settled stably far away: an unstable target (the rod left it for a buckled state) or a
  // coarse rod whose equilibrium is off the target. The target's own Hessian tells them apart
  // when it is indefinite (it can be barely positive near a bifurcation: then "moved_away").
  std::string target_note;
  if (out.verdict == "moved_away") {
    const RodStability at_target = rod_stability(m, o.hessian);
    if (!at_target.stable) {
      out.verdict = "unstable";
      target_note = "; the target itself is unstable (" +
                    (at_target.message.empty() ? std::string("not positive definite") : at_target.message) + ")";
    }
  }
  char dist[32];
  std::snprintf(dist, sizeof dist, "%.3g", distance);
  if (!r.ok()) {
    out.message = "the forward simulation from the target did not converge (" + r.message + ")" +
                  (moved_away ? std::string("; it stopped ") + dist + " of the length away: the rod leaves the target"
                              : std::string());
  } else if (moved_away) {
    const std::string where = std::string("the discrete rod moved away from the target: its equilibrium lies ") +
                              dist + " of the length away";
    out.message = out.verdict == "unstable"
                      ? where + (out.equilibrium_stable ? std::string(", stable there")
                                                         : " and " + out.message + " there") +
                            ": the rod leaves the target" + target_note
                      : where + " and is stable there (positive definite Hessian), the target's Hessian too: "
                                "the discretization error of a coarse rod (then more edges bring it back) or "
                                "another state near a bifurcation";
  }
  out.method = "hessian_at_equilibrium";
  out.equilibrium_distance = distance;
  out.equilibrium_converged = r.ok();
  out.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return out;
}

}  // namespace parafab
