#include "xfem/nonlinear_xfem.h"

#include <Eigen/LU>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <chrono>
#include <cmath>
#include <limits>

#include "common/error.h"
#include "xfem/sparse_cholesky.h"

namespace parafab::xfem {

namespace {

struct Evaluation {
  double energy = 0;
  Eigen::VectorXd gradient;
  Eigen::SparseMatrix<double> hessian;
  bool finite = true;
};

template <int NN>
void shape(const Box3& box, const Vec3& X, Eigen::Matrix<double, NN, 1>& N, Eigen::Matrix<double, NN, 3>& G) {
  if constexpr (NN == 8) trilinear_shape(box, X, N, G);
  else triquadratic_shape(box, X, N, G);
}

// Bulk terms: Σ ∫ Ψ(F), its gradient and Hessian (vec(F) column-major: F(i, a) ↔ i + 3a), for
// elements with NN = 8 (hex8) or 27 (hex27) nodes. Elements in parallel (TBB), a chunk at a
// time; energies, gradients and Hessian entries are gathered in element order, so the result
// is bit-identical for every thread count.
template <int NN>
Evaluation evaluate_bulk(const std::vector<GridElement>& elements, const std::vector<std::vector<int>>& node,
                         const Material& material, const Eigen::VectorXd& u, bool with_hessian) {
  constexpr int n = 3 * NN;
  Evaluation ev;
  ev.gradient = Eigen::VectorXd::Zero(u.size());
  for (size_t e = 0; e < elements.size(); ++e)
    PARAFAB_VERIFY(static_cast<int>(node[e].size()) == NN, "element " << e << " has " << node[e].size() << " nodes");
  // Element e's energy, gradient and Hessian; false if Ψ is not finite (J ≤ 0).
  auto element = [&](size_t e, double& energy, Eigen::VectorXd& ge, Eigen::MatrixXd& He) {
    const GridElement& el = elements[e];
    Eigen::Matrix<double, n, 1> ue;
    for (int k = 0; k < NN; ++k) ue.template segment<3>(3 * k) = u.segment<3>(3 * node[e][k]);
    energy = 0;
    ge.setZero(n);
    if (with_hessian) He.setZero(n, n);
    Eigen::Matrix<double, NN, 1> N;
    Eigen::Matrix<double, NN, 3> G;
    for (size_t q = 0; q < el.rule.points.size(); ++q) {
      const double w = el.rule.weights[q];
      shape<NN>(el.box, el.rule.points[q], N, G);
      Eigen::Matrix3d F = Eigen::Matrix3d::Identity();
      for (int k = 0; k < NN; ++k) F += ue.template segment<3>(3 * k) * G.row(k);
      const double psi = material.energy(F);
      if (!std::isfinite(psi)) return false;
      energy += w * psi;
      const Eigen::Matrix3d P = material.stress(F);
      for (int k = 0; k < NN; ++k) ge.template segment<3>(3 * k) += w * P * G.row(k).transpose();
      if (with_hessian) {
        const Eigen::Matrix<double, 9, 9> A = material.tangent(F);
        // dF/du_(k,i) = e_i ⊗ ∇N_k → vec index i + 3a with weight G(k, a).
        Eigen::Matrix<double, 9, n> dF = Eigen::Matrix<double, 9, n>::Zero();
        for (int k = 0; k < NN; ++k)
          for (int i = 0; i < 3; ++i)
            for (int a = 0; a < 3; ++a) dF(i + 3 * a, 3 * k + i) = G(k, a);
        const Eigen::Matrix<double, 9, n> AdF = A * dF;
        He.noalias() += w * dF.transpose() * AdF;
      }
    }
    return true;
  };
  SparseAccumulator hessian(static_cast<int>(u.size()), static_cast<int>(u.size()));
  const size_t count = elements.size(), chunk = NN == 8 ? 4096 : 512;
  std::vector<double> energy(std::min(count, chunk));
  std::vector<char> finite(std::min(count, chunk));
  std::vector<Eigen::VectorXd> ge(std::min(count, chunk));
  std::vector<Eigen::MatrixXd> He(std::min(count, chunk));
  for (size_t begin = 0; begin < count; begin += chunk) {
    const size_t end = std::min(count, begin + chunk);
    tbb::parallel_for(tbb::blocked_range<size_t>(begin, end, 16), [&](const tbb::blocked_range<size_t>& r) {
      for (size_t e = r.begin(); e != r.end(); ++e)
        finite[e - begin] = element(e, energy[e - begin], ge[e - begin], He[e - begin]);
    });
    for (size_t e = begin; e < end; ++e) {
      if (!finite[e - begin]) {
        ev.finite = false;
        return ev;
      }
      ev.energy += energy[e - begin];
      for (int a = 0; a < NN; ++a)
        for (int da = 0; da < 3; ++da) {
          const int ra = 3 * node[e][a] + da;
          ev.gradient(ra) += ge[e - begin](3 * a + da);
          if (with_hessian)
            for (int b = 0; b < NN; ++b)
              for (int db = 0; db < 3; ++db)
                hessian.add(ra, 3 * node[e][b] + db, He[e - begin](3 * a + da, 3 * b + db));
        }
    }
  }
  if (with_hessian) ev.hessian = hessian.finish();
  return ev;
}

Evaluation evaluate_bulk(const std::vector<GridElement>& elements, const std::vector<std::vector<int>>& node,
                         const Material& material, const Eigen::VectorXd& u, bool with_hessian) {
  if (!node.empty() && node.front().size() == 27)
    return evaluate_bulk<27>(elements, node, material, u, with_hessian);
  return evaluate_bulk<8>(elements, node, material, u, with_hessian);
}

}  // namespace

LinearXfemResult NonlinearXfemResult::as_linear() const {
  LinearXfemResult r;
  r.solved = converged;
  r.u = u;
  r.node = node;
  r.dofs = dofs;
  r.aggregated_nodes = aggregated_nodes;
  r.factorization = factorization;
  r.aggregation = aggregation;
  return r;
}

Eigen::VectorXd element_internal_force(const GridElement& el, const Material& material, const Eigen::VectorXd& ue) {
  const int nn = static_cast<int>(ue.size() / 3);
  PARAFAB_VERIFY(ue.size() == 24 || ue.size() == 81, "element_internal_force: " << ue.size() << " nodal values");
  Eigen::VectorXd ge = Eigen::VectorXd::Zero(ue.size());
  for (size_t q = 0; q < el.rule.points.size(); ++q) {
    Eigen::MatrixXd G;
    if (nn == 8) {
      Eigen::Matrix<double, 8, 1> N;
      Eigen::Matrix<double, 8, 3> g;
      trilinear_shape(el.box, el.rule.points[q], N, g);
      G = g;
    } else {
      Eigen::Matrix<double, 27, 1> N;
      Eigen::Matrix<double, 27, 3> g;
      triquadratic_shape(el.box, el.rule.points[q], N, g);
      G = g;
    }
    Eigen::Matrix3d F = Eigen::Matrix3d::Identity();
    for (int k = 0; k < nn; ++k) F += ue.segment<3>(3 * k) * G.row(k);
    PARAFAB_VERIFY(F.determinant() > 0, "element_internal_force: det F = " << F.determinant() << " at a rule point");
    const Eigen::Matrix3d P = material.stress(F);
    for (int k = 0; k < nn; ++k) ge.segment<3>(3 * k) += el.rule.weights[q] * P * G.row(k).transpose();
  }
  return ge;
}

NonlinearXfemResult solve_nonlinear(const std::vector<GridElement>& elements,
                                    const std::vector<std::array<int, 2>>& adjacent,
                                    const Material& material, const ElasticMaterial& small_strain,
                                    const std::vector<DirichletCondition>& dirichlet,
                                    const std::vector<TractionCondition>& tractions,
                                    const NonlinearXfemOptions& options) {
  PARAFAB_VERIFY(options.load_steps >= 1, "load_steps must be >= 1, got " << options.load_steps);
  const auto t0 = std::chrono::steady_clock::now();
  NonlinearXfemResult r;
  int count = 0;
  r.node = number_dof_nodes(elements, adjacent, count, options.boundary.element);
  r.dofs = 3 * count;
  // Boundary and load terms are quadratic in u: ½uᵀK_b u − f_bᵀu (Nitsche, tractions, gravity).
  const LinearSystem boundary = assemble_linear(elements, r.node, count, small_strain, dirichlet, tractions,
                                                options.boundary, /*include_bulk=*/false);
  // Cell aggregation as in the linear solver: Newton runs on u = T u_r, so DOF nodes that only
  // tiny cut cells touch follow their neighbours and the Hessian stays well conditioned.
  const Eigen::SparseMatrix<double> T = aggregation_map(elements, adjacent, r.node, count,
                                                        options.boundary.aggregation_fraction, &r.aggregated_nodes);
  // Without aggregated nodes T = I: the products with T are skipped.
  const bool reduce = r.aggregated_nodes > 0;
  const Eigen::SparseMatrix<double> Tt = reduce ? Eigen::SparseMatrix<double>(T.transpose()) : Eigen::SparseMatrix<double>();
  const Eigen::SparseMatrix<double> K_boundary = reduce ? Eigen::SparseMatrix<double>(Tt * boundary.K * T) : boundary.K;
  Eigen::VectorXd ur = Eigen::VectorXd::Zero(T.cols());
  r.u = Eigen::VectorXd::Zero(r.dofs);
  SparseCholesky llt;  // symbolic analysis once: every Newton Hessian has the same pattern
  if (options.boundary.memory_limit_mb > 0) llt.memory_limit_mb = options.boundary.memory_limit_mb;
  Eigen::SparseMatrix<double> H_final;  // the reduced Hessian at the converged u (keep_factorization)
  for (int step = 1; step <= options.load_steps; ++step) {
    const double lambda = static_cast<double>(step) / options.load_steps;
    const Eigen::VectorXd f = lambda * (reduce ? Eigen::VectorXd(Tt * boundary.f) : boundary.f);
    // Energy of the reduced unknowns x (u = T x); gradient and Hessian reduced by T.
    Eigen::SparseMatrix<double> H_bulk;
    auto total = [&](const Eigen::VectorXd& x, bool hess, Evaluation& ev) {
      ev = evaluate_bulk(elements, r.node, material, reduce ? Eigen::VectorXd(T * x) : x, hess);
      if (!ev.finite) return std::numeric_limits<double>::infinity();
      if (hess) {
        H_bulk = reduce ? Eigen::SparseMatrix<double>(Tt * ev.hessian * T) : std::move(ev.hessian);
        ev.hessian = Eigen::SparseMatrix<double>();
      }
      const Eigen::VectorXd Kx = K_boundary * x;
      ev.gradient = (reduce ? Eigen::VectorXd(Tt * ev.gradient) : ev.gradient) + Kx - f;
      return ev.energy + 0.5 * x.dot(Kx) - f.dot(x);
    };
    Evaluation ev;
    double energy = total(ur, true, ev);
    const double scale = std::max(f.norm(), ev.gradient.norm());
    bool step_done = false;
    for (int it = 0; it < options.max_iterations; ++it) {
      const double gnorm = ev.gradient.norm();
      if (gnorm <= options.tolerance * std::max(scale, 1e-300)) {
        step_done = true;
        break;
      }
      const Eigen::SparseMatrix<double> H = H_bulk + K_boundary;
      llt.factorize(H);  // reuses the symbolic analysis while the pattern stays
      Eigen::VectorXd d;
      if (llt.status() == SparseCholesky::Status::Factorized) {
        // Iterative refinement: tiny cut cells make H ill-conditioned (no stabilization yet),
        // and one triangular solve then leaves a linear residual that stalls Newton.
        d = llt.solve(-ev.gradient, 3);
      } else {  // indefinite (buckling, too small β): LU step, still checked by the line search
        if (!llt.IsDone()) {
          r.message = "Newton system singular at load step " + std::to_string(step);
          r.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
          return r;
        }
        d = -llt.solve(ev.gradient, 0);
        if (d.dot(ev.gradient) > 0) d = -ev.gradient;  // not a descent direction
      }
      // Converged to round-off: the Newton decrement −dᵀg (the quadratic model's predicted
      // energy change, ×2) is below what the energy's sum can resolve and the step is below
      // 1e-8 of u. Measured: the turned cantilever, hex27 on 4 cells at β = 100, stalled at a
      // residual of 0.55 N (5e-7 of the load) with steps of 1.4e-9 of u that the line search
      // could not accept (python.simulate_element, 2026-11-28).
      if (-d.dot(ev.gradient) <= 1e-12 * std::max(std::abs(energy), 1e-300) &&
          d.norm() <= 1e-8 * std::max(ur.norm(), 1e-300)) {
        step_done = true;
        break;
      }
      // Backtracking (Armijo) on the total energy; infinite energy (J ≤ 0) rejects a step.
      double alpha = 1;
      Evaluation trial;
      double e_trial = total(ur + d, false, trial);
      const double slope = d.dot(ev.gradient);
      // Near the solution the energy changes by less than the round-off of its sum over all
      // quadrature points (cancelling bulk and load terms): there the full Newton step is taken
      // when it reduces the residual instead.
      const bool roundoff = std::abs(e_trial - energy) <= 1e-9 * std::max(std::abs(energy), 1e-300) &&
                            trial.finite && trial.gradient.norm() < gnorm;
      while (!roundoff && !(e_trial <= energy + 1e-4 * alpha * slope) && alpha > 1e-10) {
        alpha *= 0.5;
        e_trial = total(ur + alpha * d, false, trial);
      }
      if (!roundoff && !(e_trial <= energy + 1e-4 * alpha * slope)) {
        r.message = "line search failed at load step " + std::to_string(step);
        break;
      }
      ur += alpha * d;
      energy = total(ur, true, ev);
      ++r.iterations;
      r.residuals.push_back(ev.gradient.norm());
      // A Newton step that no longer moves the solution: converged to round-off (the residual
      // can stall above the tolerance where Nitsche penalties make the Hessian very stiff).
      if (d.norm() <= 1e-10 * std::max(ur.norm(), 1e-300)) {
        step_done = true;
        break;
      }
    }
    r.u = reduce ? Eigen::VectorXd(T * ur) : ur;
    if (!step_done) {
      if (r.message.empty())
        r.message = "Newton did not converge in " + std::to_string(options.max_iterations) +
                    " iterations at load step " + std::to_string(step) + " (residual " +
                    std::to_string(ev.gradient.norm()) + ")";
      r.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
      return r;
    }
    r.energy = energy;
    if (options.keep_factorization && step == options.load_steps) H_final = H_bulk + K_boundary;
  }
  if (options.keep_factorization) {
    auto kept = std::make_shared<SparseCholesky>();
    if (options.boundary.memory_limit_mb > 0) kept->memory_limit_mb = options.boundary.memory_limit_mb;
    kept->factorize(H_final);
    if (!kept->IsDone()) {
      r.message = "the Hessian at the solution could not be factorized (kept for adjoint solves)";
      r.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
      return r;
    }
    r.factorization = std::move(kept);
    if (reduce) r.aggregation = T;
  }
  r.converged = true;
  r.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return r;
}

}  // namespace parafab::xfem
