#include "xfem/nonlinear_xfem.h"

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
  std::vector<Eigen::Triplet<double>> hessian;
  bool finite = true;
};

// Bulk terms: Σ ∫ Ψ(F), its gradient and Hessian (vec(F) column-major: F(i, a) ↔ i + 3a).
// Elements in parallel (TBB), a chunk at a time; energies, gradients and Hessian triplets are
// gathered in element order, so the result is bit-identical for every thread count.
Evaluation evaluate_bulk(const std::vector<GridElement>& elements, const std::vector<std::array<int, 8>>& node,
                         const Material& material, const Eigen::VectorXd& u, bool with_hessian) {
  Evaluation ev;
  ev.gradient = Eigen::VectorXd::Zero(u.size());
  using Vec24 = Eigen::Matrix<double, 24, 1>;
  using Mat24 = Eigen::Matrix<double, 24, 24>;
  // Element e's energy, gradient and Hessian; false if Ψ is not finite (J ≤ 0).
  auto element = [&](size_t e, double& energy, Vec24& ge, Mat24& He) {
    const GridElement& el = elements[e];
    Vec24 ue;
    for (int k = 0; k < 8; ++k) ue.segment<3>(3 * k) = u.segment<3>(3 * node[e][k]);
    energy = 0;
    ge.setZero();
    if (with_hessian) He.setZero();
    for (size_t q = 0; q < el.rule.points.size(); ++q) {
      const double w = el.rule.weights[q];
      Eigen::Matrix<double, 8, 1> N;
      Eigen::Matrix<double, 8, 3> G;
      trilinear_shape(el.box, el.rule.points[q], N, G);
      Eigen::Matrix3d F = Eigen::Matrix3d::Identity();
      for (int k = 0; k < 8; ++k) F += ue.segment<3>(3 * k) * G.row(k);
      const double psi = material.energy(F);
      if (!std::isfinite(psi)) return false;
      energy += w * psi;
      const Eigen::Matrix3d P = material.stress(F);
      for (int k = 0; k < 8; ++k) ge.segment<3>(3 * k) += w * P * G.row(k).transpose();
      if (with_hessian) {
        const Eigen::Matrix<double, 9, 9> A = material.tangent(F);
        // dF/du_(k,i) = e_i ⊗ ∇N_k → vec index i + 3a with weight G(k, a).
        Eigen::Matrix<double, 9, 24> dF = Eigen::Matrix<double, 9, 24>::Zero();
        for (int k = 0; k < 8; ++k)
          for (int i = 0; i < 3; ++i)
            for (int a = 0; a < 3; ++a) dF(i + 3 * a, 3 * k + i) = G(k, a);
        He.noalias() += w * dF.transpose() * A * dF;
      }
    }
    return true;
  };
  const size_t n = elements.size(), chunk = 4096;
  if (with_hessian) ev.hessian.reserve(576 * n);
  std::vector<double> energy(std::min(n, chunk));
  std::vector<char> finite(std::min(n, chunk));
  std::vector<Vec24, Eigen::aligned_allocator<Vec24>> ge(std::min(n, chunk));
  std::vector<Mat24, Eigen::aligned_allocator<Mat24>> He(with_hessian ? std::min(n, chunk) : 0);
  for (size_t begin = 0; begin < n; begin += chunk) {
    const size_t end = std::min(n, begin + chunk);
    tbb::parallel_for(tbb::blocked_range<size_t>(begin, end, 16), [&](const tbb::blocked_range<size_t>& r) {
      Mat24 local;
      for (size_t e = r.begin(); e != r.end(); ++e)
        finite[e - begin] = element(e, energy[e - begin], ge[e - begin], with_hessian ? He[e - begin] : local);
    });
    for (size_t e = begin; e < end; ++e) {
      if (!finite[e - begin]) {
        ev.finite = false;
        ev.hessian.clear();
        return ev;
      }
      ev.energy += energy[e - begin];
      for (int a = 0; a < 8; ++a)
        for (int da = 0; da < 3; ++da) {
          const int ra = 3 * node[e][a] + da;
          ev.gradient(ra) += ge[e - begin](3 * a + da);
          if (with_hessian)
            for (int b = 0; b < 8; ++b)
              for (int db = 0; db < 3; ++db)
                ev.hessian.emplace_back(ra, 3 * node[e][b] + db, He[e - begin](3 * a + da, 3 * b + db));
        }
    }
  }
  return ev;
}

}  // namespace

LinearXfemResult NonlinearXfemResult::as_linear() const {
  LinearXfemResult r;
  r.solved = converged;
  r.u = u;
  r.node = node;
  r.dofs = dofs;
  r.aggregated_nodes = aggregated_nodes;
  return r;
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
  r.node = number_dof_nodes(elements, adjacent, count);
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
  for (int step = 1; step <= options.load_steps; ++step) {
    const double lambda = static_cast<double>(step) / options.load_steps;
    const Eigen::VectorXd f = lambda * (reduce ? Eigen::VectorXd(Tt * boundary.f) : boundary.f);
    // Energy of the reduced unknowns x (u = T x); gradient and Hessian reduced by T.
    Eigen::SparseMatrix<double> H_bulk;
    auto total = [&](const Eigen::VectorXd& x, bool hess, Evaluation& ev) {
      ev = evaluate_bulk(elements, r.node, material, reduce ? Eigen::VectorXd(T * x) : x, hess);
      if (!ev.finite) return std::numeric_limits<double>::infinity();
      if (hess) {
        Eigen::SparseMatrix<double> H(r.dofs, r.dofs);
        H.setFromTriplets(ev.hessian.begin(), ev.hessian.end());
        ev.hessian.clear();
        ev.hessian.shrink_to_fit();
        H_bulk = reduce ? Eigen::SparseMatrix<double>(Tt * H * T) : std::move(H);
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
  }
  r.converged = true;
  r.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return r;
}

}  // namespace parafab::xfem
