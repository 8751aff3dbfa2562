// optimize_shape's evaluations (thesis §6.5.1 projection Eq. 6.25-6.26, §6.5.2 chain rule
// Eq. 6.28-6.29; compliance, failure and target by shape_compliance.h, shape_failure.h and
// shape_target.h): the run's problem, its volume bounds and the evaluation cache; see
// shape_evaluation.h.
#include "shape_evaluation.h"

#include <algorithm>
#include <cmath>
#include <set>

#include "common/error.h"
#include "occt_shape.h"
#include "shape_modify.h"

namespace parafab::occ::detail {

ShapeProblem::ShapeProblem(const PartShape& part_, const ShapeOptimizationOptions& options_, ShapeOptimizationResult& result)
    : part(part_), options(options_), model(build_face_model(part_, options_.face_model)),
      sp(build_shape_parameters(model, options_.parameterization)) {
  result.notes = sp.notes;
  spec = options.objective;
  // Compliance and the failure metric alone or as terms of a sum (weighted by term_weight;
  // moment terms are added by objective_from_moments); both solve the same
  // elasticity job once per evaluation.
  const ObjectiveSpec* failure_spec = failure_term(spec);
  failure = failure_spec != nullptr;
  const ObjectiveSpec* target_spec = target_term(spec);
  matching = target_spec != nullptr;
  if (matching) {
    target_options.face = target_spec->face;
    PARAFAB_VERIFY(target_options.face >= 0 && target_options.face < static_cast<int>(model.faces.size()),
                   "objective 'target': face " << target_options.face << " outside 0.." << model.faces.size() - 1);
    target_options.target = target_spec->has_target ? target_spec->target : target_of_face(model, target_options.face);
    check_target_surface(target_options.target);
    result.target = target_options.target;
  }
  compliance = spec.type == "compliance" || failure || matching ||
               (spec.type == "sum" && std::any_of(spec.terms.begin(), spec.terms.end(), [](const ObjectiveSpec& t) {
                  return t.type == "compliance";
                }));
  failure_options =
      failure ? FailureOptions{failure_spec->yield_stress, failure_spec->exponent, failure_spec->per_volume} : FailureOptions{};
  if (failure) check_failure_options(failure_options);
  {
    Eigen::Matrix<double, 10, 1> g;
    objective_from_moments(spec, Moments::Zero().unaryExpr([](double) { return 1.0; }), &g);  // validates the type
  }
  if (compliance) {
    PARAFAB_VERIFY(options.compliance, "objective '" << spec.type << "' needs the elasticity job (material, supports, loads, grid)");
    PARAFAB_VERIFY(options.compliance_step > 0, "compliance_step must be positive, got " << options.compliance_step);
    if (options.compliance->hyperelastic && (term_weight(spec, "compliance") != 0 || failure))
      PARAFAB_INPUT_ERROR("objective '" << spec.type << "': compliance and failure run on a linear solve; a hyperelastic "
                                      "material (" << options.compliance->hyperelastic->name()
                                      << ") serves the target objective only");
    // The failure integrand is evaluated at the cut cells' moment-fitted rule points, which lie
    // in the fitting box, partly outside the material. The trilinear field stays moderate there,
    // but the triquadratic one of a sliver cell does not, and exp(α σ_vm/σ_y) of it swamps the
    // integral (L-bracket, 12 cells: J = 2e10 against 0.0026 on hex8, then negative).
    if (failure && options.compliance->solver.element == xfem::ElementType::Hex27)
      PARAFAB_INPUT_ERROR("element: the failure objective runs on 'hex8' only (on 'hex27' the rule points of cut "
                          "cells outside the material see the extrapolated quadratic stress, and exp(alpha "
                          "sigma_vm / sigma_y) of it swamps J); got 'hex27'");
  }
  {
    const double L = part_box(part).diagonal();
    if (spec.length_scale <= 0) spec.length_scale = L;
    for (ObjectiveSpec& t : spec.terms)
      if (t.length_scale <= 0) t.length_scale = L;
  }
  // "normalize": every term of a sum divided by its value at the first evaluation (the start).
  scales_set = !(spec.type == "sum" && spec.normalize);
  // Design entries.
  design = options.design;
  std::set<int> fixed(sp.fixed_faces.begin(), sp.fixed_faces.end());
  if (design.empty())
    for (const auto& b : sp.blocks)
      if (!fixed.count(b.face))
        for (int k = 0; k < b.size(); ++k) design.push_back(b.offset + k);
  PARAFAB_VERIFY(!design.empty(), "no design parameters: every analytic face is fixed (B-spline poles are design parameters only when listed)");
  for (int i : design) {
    PARAFAB_VERIFY(i >= 0 && i < sp.size(), "design parameter index " << i << " outside 0.." << sp.size() - 1);
    PARAFAB_VERIFY(sp.lower[i] < sp.upper[i], "design parameter '" << sp.names[i] << "' belongs to a fixed face");
  }
  nd = static_cast<int>(design.size());
  for (int i : design) result.design_names.push_back(sp.names[i]);

  popt = options.projection;
  popt.weights = projection_weights(sp, design, options.follower_weight, part_box(part).diagonal());
  part_size = part_box(part).diagonal();
}

void ShapeProblem::normalize_terms(const Moments& m, double compliance_value, double failure_value, double target_value) {
  if (scales_set) return;
  for (ObjectiveSpec& t : spec.terms) {
    const double v = t.type == "compliance" ? compliance_value
                     : t.type == "failure"  ? failure_value
                     : t.type == "target"   ? target_value
                                            : objective_from_moments(t, m, nullptr);
    t.scale = std::abs(v) > 0 && std::isfinite(v) ? std::abs(v) : 1.0;
  }
  scales_set = true;
}

bool ShapeProblem::is_direction(int i) const {
  const std::string& n = sp.names[i];
  return n.find(" normal ") != std::string::npos || n.find("half-angle") != std::string::npos ||
         (n.size() > 7 && n.compare(n.size() - 7, 6, " axis ") == 0);
}

VolumeBounds::VolumeBounds(const ShapeOptimizationOptions& options) {
  if (options.volume_max_ratio > 0) bounds[0] = {true, options.volume_max_ratio, 1, 0, options.penalty};
  if (options.volume_min_ratio > 0) bounds[1] = {true, options.volume_min_ratio, -1, 0, options.penalty};
  // Absolute bounds (volume_max / volume_min, e.g. a mass bound over the density) become ratios
  // once V0 is known (the first evaluation); with a ratio on the same side the tighter holds.
  if (options.volume_max > 0) bounds[0].on = true, bounds[0].sign = 1, bounds[0].rho = options.penalty;
  if (options.volume_min > 0) bounds[1].on = true, bounds[1].sign = -1, bounds[1].rho = options.penalty;
  bounded = bounds[0].on || bounds[1].on;
}

double VolumeBounds::signed_violation(double V, double V0v) const {
  double g = -1e300;
  for (const Bound& b : bounds)
    if (b.on) g = std::max(g, b.sign * (V / V0v - b.ratio));
  return g;
}

void VolumeBounds::penalized(const Evaluation& e, double& F, Eigen::VectorXd& grad) const {
  F = e.objective;
  double dpsi_dV = 0;
  for (const Bound& b : bounds) {
    if (!b.on) continue;
    const double m = std::max(0.0, b.lambda + b.rho * b.sign * (e.volume / V0 - b.ratio));
    F += f_scale * (m * m - b.lambda * b.lambda) / (2 * b.rho);
    dpsi_dV += f_scale * m * b.sign / V0;
  }
  grad = e.gradient + dpsi_dV * e.volume_gradient;
}

void VolumeBounds::set_reference(double V, double f, const ShapeOptimizationOptions& options) {
  V0 = V, f_scale = std::max(std::abs(f), 1e-300);
  if (options.volume_max > 0)
    bounds[0].ratio = options.volume_max_ratio > 0 ? std::min(options.volume_max_ratio, options.volume_max / V0)
                                                   : options.volume_max / V0;
  if (options.volume_min > 0)
    bounds[1].ratio = std::max(options.volume_min_ratio, options.volume_min / V0);
}

EvaluationCache::EvaluationCache(ShapeProblem& problem, VolumeBounds& bounds, ShapeOptimizationResult& result,
                                 const Eigen::VectorXd& anchor, const Eigen::VectorXd& warm_p)
    : problem_(problem), bounds_(bounds), result_(result), anchor_(anchor), warm_p_(warm_p) {}

bool EvaluationCache::solving_terms(const Evaluation* reuse, const Evaluation::Geometry& geometry,
                                    Eigen::Matrix<double, 10, 1>& dfdm, double& f, Eigen::VectorXd& compliance_gradient) {
  ShapeOptimizationResult& result = result_;
  const ShapeOptimizationOptions& options = problem_.options;
  const ObjectiveSpec& spec = problem_.spec;
  const bool failure = problem_.failure, matching = problem_.matching;
  const FailureOptions& failure_options = problem_.failure_options;
  const TargetOptions& target_options = problem_.target_options;
  std::shared_ptr<ComplianceState>& base_state = base_state_;
  const ModifyResult& mod = geometry.mod;
  const MomentDerivatives& md = geometry.md;
  // C at p⊥ on the fixed grid, and dC/dx_k by the semi-analytic route: each design entry
  // perturbed by ±h through the projection and the write-back, only the cells the change
  // touches re-cut and differenced (shape_compliance.h).
  std::shared_ptr<ComplianceState> state;
  if (!base_state) {
    state = std::make_shared<ComplianceState>(compliance_start(mod.part, *options.compliance));
    if (!state->done) PARAFAB_INPUT_ERROR("compliance at the start: " << state->message);
    base_state = state;
  } else if (reuse && reuse->state && reuse->switches_own) {
    // Only the failure metric's frames were frozen: K, f and u are the model's own.
    state = std::make_shared<ComplianceState>(compliance_own_frames(*reuse->state));
    ++result.frame_refreshes;
  } else if (reuse && reuse->model) {
    state = std::make_shared<ComplianceState>(
        compliance_own_switches(mod.part, *reuse->model, reuse->occt_volume, *options.compliance));
    if (!state->done) {
      if (result.invalid_models++ == 0) result.notes.push_back("first failed compliance evaluation: " + state->message);
      return false;
    }
  } else {
    state = std::make_shared<ComplianceState>(compliance_at(mod.part, *base_state, *options.compliance,
                                                            options.freeze_switches ? line_start.get() : nullptr));
    if (!state->done) {
      if (result.invalid_models++ == 0) result.notes.push_back("first failed compliance evaluation: " + state->message);
      return false;
    }
  }
  if (!state->ties.empty()) {
    ++result.tied_evaluations;
    result.max_ties = std::max(result.max_ties, static_cast<int>(state->ties.size()));
    result.max_mode_tied_pairs = std::max(result.max_mode_tied_pairs, state->solution.mode_tied_pairs);
  }
  FailureValue fv;
  Eigen::VectorXd adjoint;
  if (failure) {
    // J and the adjoint λ = −K⁻¹∂J/∂u (kept factorization), shared by every design direction.
    fv = failure_value(*state, *options.compliance, failure_options, true);
    if (!fv.done) {
      if (result.invalid_models++ == 0) result.notes.push_back("first failed failure evaluation: " + fv.message);
      return false;
    }
    last.max_von_mises = fv.max_von_mises;
    adjoint = failure_adjoint(*state, fv);
  }
  TargetValue tv;
  Eigen::VectorXd target_adjoint_u;
  if (matching) {
    // J of the matched face and its adjoint λ = −K⁻¹∂J/∂u, as for the failure metric.
    tv = target_value(*state, *options.compliance, target_options, true);
    if (!tv.done) {
      if (result.invalid_models++ == 0) result.notes.push_back("first failed target evaluation: " + tv.message);
      return false;
    }
    last.target_rms = std::sqrt(tv.objective);
    last.target_max = tv.max_distance;
    target_adjoint_u = target_adjoint(*state, tv);
  }
  last.model = state->model;
  last.state = state;
  last.switches_own = state->switches_own;
  last.frames_own = state->frames_own;
  last.occt_volume = state->occt_volume;
  problem_.normalize_terms(md.moments, state->compliance, fv.objective, tv.objective);
  const double cw = term_weight(spec, "compliance"), fw = term_weight(spec, "failure"), tw = term_weight(spec, "target");
  f = cw * state->compliance + fw * fv.objective + tw * tv.objective + objective_from_moments(spec, md.moments, &dfdm);
  return design_gradient(*state, fv, adjoint, tv, target_adjoint_u, geometry, compliance_gradient);
}

bool EvaluationCache::design_gradient(const ComplianceState& solved, const FailureValue& fv, const Eigen::VectorXd& adjoint,
                                      const TargetValue& tv, const Eigen::VectorXd& target_adjoint_u,
                                      const Evaluation::Geometry& geometry, Eigen::VectorXd& compliance_gradient) {
  ShapeOptimizationResult& result = result_;
  const ShapeOptimizationOptions& options = problem_.options;
  const PartShape& part = problem_.part;
  const FaceModel& model = problem_.model;
  const ShapeParameters& sp = problem_.sp;
  const ObjectiveSpec& spec = problem_.spec;
  const std::vector<int>& design = problem_.design;
  const int nd = problem_.nd;
  const FailureOptions& failure_options = problem_.failure_options;
  const TargetOptions& target_options = problem_.target_options;
  const optimize::ProjectionOptions& popt = problem_.popt;
  const double part_size = problem_.part_size;
  const Eigen::VectorXd& target = geometry.target;
  const optimize::ProjectionResult& proj = geometry.proj;
  const optimize::ProjectionDerivative& D = geometry.D;
  const ComplianceState* state = &solved;
  const double cw = term_weight(spec, "compliance"), fw = term_weight(spec, "failure"), tw = term_weight(spec, "target");
  compliance_gradient.resize(nd);
  // The exact route for every design entry whose direction dp⊥/dp̃ moves no face next to a
  // support or load (compliance_gradient's `incomplete`); the others are differenced.
  const bool exact_route = cw != 0 && options.compliance_gradient == ShapeOptimizationOptions::ComplianceGradientRoute::Exact;
  // Entries that some design direction moves (exact zeros elsewhere: the projection's
  // derivative is block diagonal over the groups the constraints couple).
  std::vector<char> moving(sp.size(), 0);
  for (int k = 0; k < nd; ++k)
    for (int i = 0; i < sp.size(); ++i)
      if (D.jacobian(i, design[k]) != 0) moving[i] = 1;
  const ComplianceGradient exact =
      exact_route ? occ::compliance_gradient(*state, *options.compliance, sp, proj.p, &moving) : ComplianceGradient{};
  // The failure metric's exact route: one adjoint (above), boundary integrals (shape_failure.h).
  const bool exact_failure = fw != 0 && options.compliance_gradient == ShapeOptimizationOptions::ComplianceGradientRoute::Exact;
  const ComplianceGradient failure_exact =
      exact_failure ? failure_gradient(*state, fv, adjoint, *options.compliance, failure_options, sp, proj.p, &moving)
                    : ComplianceGradient{};
  // The target's exact route (linear only; shape_target.h): the same adjoint, boundary
  // integrals with the face's own motion and its edges' slide.
  const bool exact_target = tw != 0 && !options.compliance->hyperelastic &&
                            options.compliance_gradient == ShapeOptimizationOptions::ComplianceGradientRoute::Exact;
  const ComplianceGradient target_exact =
      exact_target ? target_gradient(*state, tv, target_adjoint_u, *options.compliance, target_options, sp, proj.p, &moving)
                   : ComplianceGradient{};
  for (int k = 0; k < nd; ++k) {
    compliance_gradient[k] = 0;
    bool difference_compliance = cw != 0, difference_failure = fw != 0, difference_target = tw != 0;
    if (exact_route && exact_along(exact, D.jacobian.col(design[k]))) {
      compliance_gradient[k] = cw * exact.gradient.dot(D.jacobian.col(design[k]));
      difference_compliance = false;
      ++result.exact_derivatives;
    }
    if (exact_failure && exact_along(failure_exact, D.jacobian.col(design[k]))) {
      compliance_gradient[k] += fw * failure_exact.gradient.dot(D.jacobian.col(design[k]));
      difference_failure = false;
      ++result.exact_derivatives;
    }
    if (exact_target && exact_along(target_exact, D.jacobian.col(design[k]))) {
      compliance_gradient[k] += tw * target_exact.gradient.dot(D.jacobian.col(design[k]));
      difference_target = false;
      ++result.exact_derivatives;
    }
    if (!difference_compliance && !difference_failure && !difference_target) continue;
    const double h = options.compliance_step * (problem_.is_direction(design[k]) ? 1.0 : part_size);
    std::shared_ptr<const PartShape> sides[2];
    for (int side = 0; side < 2; ++side) {
      Eigen::VectorXd t = target;
      t[design[k]] += side == 0 ? h : -h;
      const optimize::ProjectionResult pk = optimize::project(sp.constraints, t, proj.p, sp.lower, sp.upper, {}, popt);
      if (!pk.done) continue;
      // Checked like the model itself: next to a refused model (the run's end, say) a side
      // can cross; element_difference then takes the one-sided difference.
      const ModifyResult mk = modify_part(part, model, sp, pk.p);
      if (mk.done) sides[side] = mk.part;
    }
    // dC/dx_k, dJ/dx_k of the failure metric and of the target from the same two perturbed
    // models (each derivative re-cuts them on the grid).
    enum Term { Compliance, Failure, Target };
    for (const Term term : {Compliance, Failure, Target}) {
      const double weight = term == Compliance ? (difference_compliance ? cw : 0)
                            : term == Failure  ? (difference_failure ? fw : 0)
                                               : (difference_target ? tw : 0);
      if (weight == 0) continue;
      ++result.semi_analytic_derivatives;
      const ComplianceDerivative cd =
          term == Failure  ? failure_derivative(*state, fv, adjoint, sides[0], sides[1], h, *options.compliance, failure_options)
          : term == Target ? target_derivative(*state, tv, target_adjoint_u, sides[0], sides[1], h, *options.compliance,
                                               target_options)
                           : compliance_derivative(*state, sides[0], sides[1], h, *options.compliance);
      if (!cd.done) {
        if (result.invalid_models++ == 0)
          result.notes.push_back(std::string(term == Failure ? "failure" : term == Target ? "target" : "compliance") +
                                 " gradient of '" + sp.names[design[k]] + "': " + cd.message);
        return false;
      }
      compliance_gradient[k] += weight * cd.derivative;
      result.topology_switches += cd.topology_switches;
      result.gradient_cells += cd.cells_changed;
    }
  }
  result.gradient = result.semi_analytic_derivatives == 0 ? "exact"
                    : result.exact_derivatives == 0      ? "semi-analytic"
                                                         : "exact + semi-analytic";
  return true;
}

bool EvaluationCache::evaluate(const Eigen::VectorXd& x, double& F, Eigen::VectorXd& grad) {
  ShapeOptimizationResult& result = result_;
  const ShapeOptimizationOptions& options = problem_.options;
  const ShapeParameters& sp = problem_.sp;
  const std::vector<int>& design = problem_.design;
  const int nd = problem_.nd;
  if (interrupted()) throw Interrupted{};
  ++result.evaluations;
  const Evaluation* reuse = refresh_of_;
  refresh_of_ = nullptr;
  last = Evaluation{};
  std::shared_ptr<const Evaluation::Geometry> geometry = reuse ? reuse->geometry : nullptr;
  if (!geometry) {
    auto g = std::make_shared<Evaluation::Geometry>();
    g->target = anchor_;
    for (int k = 0; k < nd; ++k) g->target[design[k]] = x[k];
    g->proj = optimize::project(sp.constraints, g->target, warm_p_, sp.lower, sp.upper, {}, problem_.popt);  // primal warm start
    if (!g->proj.done) {
      if (result.failed_projections++ == 0) result.notes.push_back("first failed projection: " + g->proj.message);
      return false;  // never evaluate an invalid model
    }
    g->mod = modify_part(problem_.part, problem_.model, sp, g->proj.p);
    if (!g->mod.done) {
      if (result.invalid_models++ == 0) result.notes.push_back("first invalid B-rep update: " + g->mod.message);
      return false;
    }
    g->md = moment_derivatives(*g->mod.part, sp, g->proj.p, options.quadrature);
    g->D = optimize::projection_derivative(sp.constraints, g->proj, sp.lower, sp.upper, problem_.popt.weights);
    geometry = std::move(g);
  }
  last.geometry = geometry;
  const optimize::ProjectionResult& proj = geometry->proj;
  const ModifyResult& mod = geometry->mod;
  const MomentDerivatives& md = geometry->md;
  const optimize::ProjectionDerivative& D = geometry->D;
  Eigen::Matrix<double, 10, 1> dfdm = Eigen::Matrix<double, 10, 1>::Zero();
  double f = 0;
  Eigen::VectorXd compliance_gradient;
  if (problem_.compliance && !volume_only) {
    if (!solving_terms(reuse, *geometry, dfdm, f, compliance_gradient)) return false;
  } else if (!problem_.compliance) {
    problem_.normalize_terms(md.moments, 0.0, 0.0, 0.0);
    f = objective_from_moments(problem_.spec, md.moments, &dfdm);
  }
  Eigen::VectorXd dfdp = md.gradient.transpose() * dfdm;
  // Volume bounds: the augmented-Lagrangian term (see VolumeBounds).
  const double V = md.moments[0];
  if (bounds_.V0 == 0) bounds_.set_reference(V, f, options);
  const double V0 = bounds_.V0;
  double violation = 0;
  for (const VolumeBounds::Bound& b : bounds_.bounds)
    if (b.on) violation = std::max(violation, b.sign * (V / V0 - b.ratio));
  // Chain rule through the projection (Eq. 6.29): dF/dp̃ = (dp⊥/dp̃)ᵀ dF/dp⊥.
  const Eigen::VectorXd g_target = D.jacobian.transpose() * dfdp;
  const Eigen::VectorXd v_target = D.jacobian.transpose() * md.gradient.row(0).transpose();
  grad.resize(nd);
  last.volume_gradient.resize(nd);
  for (int k = 0; k < nd; ++k) grad[k] = g_target[design[k]], last.volume_gradient[k] = v_target[design[k]];
  if (problem_.compliance && !volume_only) grad += compliance_gradient;
  if (result.initial_gradient.size() == 0 && !volume_only) result.initial_gradient = grad;  // of f, without the penalty
  last.gradient = grad;
  last.x = x;
  last.objective = f;
  last.volume = V;
  bounds_.penalized(last, F, grad);
  last.ok = true;
  last.penalized = F;
  last.violation = violation;
  last.p = proj.p;
  last.lambda = proj.multipliers;
  last.part = mod.part;
  warm_p_ = proj.p;
  return true;
}

bool EvaluationCache::refresh(const Eigen::VectorXd& x, double& F, Eigen::VectorXd& grad) {
  // The failure metric integrates on frames frozen with the switches: refreshed as they are.
  if (!last.model || (last.switches_own && (!problem_.failure || last.frames_own))) return false;
  const Evaluation frozen = last;
  const int invalid = result_.invalid_models;
  const size_t notes = result_.notes.size();
  const std::shared_ptr<const GridModel> keep = line_start;
  line_start.reset();
  refresh_of_ = &frozen;
  const bool ok = evaluate(x, F, grad) && std::isfinite(F);
  line_start = keep;
  if (!ok) {  // keep the frozen value (the model is valid: it was just evaluated)
    last = frozen;
    result_.invalid_models = invalid;
    result_.notes.resize(notes);
    return false;
  }
  ++result_.switch_refreshes;
  return true;
}

bool EvaluationCache::objective(const Eigen::VectorXd& xk, double& F, Eigen::VectorXd& grad) {
  if (evaluated_start.ok && xk == evaluated_start.x) {
    last = evaluated_start;
    evaluated_start = Evaluation{};
    bounds_.penalized(last, F, grad);
    last.penalized = F;
    return true;
  }
  evaluated_start = Evaluation{};
  return evaluate(xk, F, grad);
}

}  // namespace parafab::occ::detail
