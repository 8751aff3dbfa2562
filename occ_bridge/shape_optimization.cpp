// Shape optimization over projected CAD parameters (thesis §6.2.3 Eq. 6.5 objectives, §6.5.1
// projection Eq. 6.25-6.26, §6.5.2 chain rule Eq. 6.28-6.29).
#include "shape_optimization.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <set>
#include <sstream>

#include "common/error.h"
#include "occt_shape.h"
#include "optimize/jet.h"
#include "shape_modify.h"

namespace parafab::occ {

double objective_from_moments(const ObjectiveSpec& spec, const Moments& m, Eigen::Matrix<double, 10, 1>* gradient) {
  using optimize::Dual;
  using optimize::V3;
  std::vector<Dual> x;
  for (int k = 0; k < 10; ++k) x.push_back(Dual::variable(m[k], k, 10));
  const Vec3 an = spec.axis.normalized();
  auto constant = [](double v) { return Dual(v, 10); };
  const V3<Dual> a{constant(an.x()), constant(an.y()), constant(an.z())};
  auto center_term = [&]() {
    const V3<Dual> c{x[1] / x[0], x[2] / x[0], x[3] / x[0]};
    const V3<Dual> w = c - V3<Dual>{constant(spec.point.x()), constant(spec.point.y()), constant(spec.point.z())};
    const V3<Dual> perp = w - dot(w, a) * a;
    return dot(perp, perp);
  };
  auto alignment_term = [&]() {
    // Central second moments S = M2 − m1 m1ᵀ / m0; I a − (aᵀ I a) a = −(S a − (aᵀ S a) a).
    const Dual sxx = x[4] - x[1] * x[1] / x[0], syy = x[5] - x[2] * x[2] / x[0], szz = x[6] - x[3] * x[3] / x[0];
    const Dual sxy = x[7] - x[1] * x[2] / x[0], syz = x[8] - x[2] * x[3] / x[0], sxz = x[9] - x[1] * x[3] / x[0];
    const V3<Dual> Sa{sxx * a.x + sxy * a.y + sxz * a.z, sxy * a.x + syy * a.y + syz * a.z,
                      sxz * a.x + syz * a.y + szz * a.z};
    const V3<Dual> off = Sa - dot(a, Sa) * a;
    const Dual trace_i = 2.0 * (sxx + syy + szz);
    return dot(off, off) / (trace_i * trace_i);
  };
  if (spec.type == "sum") {
    if (spec.terms.empty()) PARAFAB_INPUT_ERROR("objective 'sum' has no terms");
    double f = 0;
    Eigen::Matrix<double, 10, 1> g = Eigen::Matrix<double, 10, 1>::Zero(), gi;
    for (size_t i = 0; i < spec.terms.size(); ++i) {
      const ObjectiveSpec& t = spec.terms[i];
      if (t.type == "sum") PARAFAB_INPUT_ERROR("objective.terms[" << i << "]: a sum cannot be a term of a sum");
      if (!(t.scale > 0) || !std::isfinite(t.weight))
        PARAFAB_INPUT_ERROR("objective.terms[" << i << "]: weight " << t.weight << ", scale " << t.scale);
      const double fi = objective_from_moments(t, m, &gi);
      f += t.weight / t.scale * fi;
      g += t.weight / t.scale * gi;
    }
    if (gradient) *gradient = g;
    return f;
  }
  if (spec.type == "compliance" || spec.type == "failure" || spec.type == "target") {  // not functions of the moments (optimize_shape adds them)
    if (gradient) gradient->setZero();
    return 0;
  }
  Dual f;
  if (spec.type == "mass") f = spec.density * x[0];
  else if (spec.type == "volume") f = x[0] * 1.0;
  else if (spec.type == "center_of_mass") f = center_term();
  else if (spec.type == "inertia_alignment") f = alignment_term();
  else if (spec.type == "balance") f = center_term() / (spec.length_scale * spec.length_scale) + alignment_term();
  else
    PARAFAB_INPUT_ERROR("objective.type '" << spec.type
                                           << "' is unknown (mass, volume, center_of_mass, inertia_alignment, balance, "
                                              "compliance, failure, target, sum)");
  if (gradient) *gradient = f.g;
  return f.v;
}

double term_weight(const ObjectiveSpec& spec, const std::string& type) {
  if (spec.type == type) return 1;
  double w = 0;
  if (spec.type == "sum")
    for (const ObjectiveSpec& t : spec.terms)
      if (t.type == type) w += t.weight / t.scale;
  return w;
}

namespace {

// `spec` itself if of `type`, else the one term of that type of a "sum" (a second is an error).
const ObjectiveSpec* single_term(const ObjectiveSpec& spec, const std::string& type) {
  if (spec.type == type) return &spec;
  const ObjectiveSpec* found = nullptr;
  if (spec.type == "sum")
    for (size_t i = 0; i < spec.terms.size(); ++i)
      if (spec.terms[i].type == type) {
        if (found) PARAFAB_INPUT_ERROR("objective.terms[" << i << "]: a sum takes one '" << type << "' term at most");
        found = &spec.terms[i];
      }
  return found;
}

}  // namespace

const ObjectiveSpec* failure_term(const ObjectiveSpec& spec) { return single_term(spec, "failure"); }
const ObjectiveSpec* target_term(const ObjectiveSpec& spec) { return single_term(spec, "target"); }

namespace {

struct Evaluation {
  bool ok = false;
  double objective = 0, penalized = 0, violation = 0, volume = 0, tangency = 0, max_von_mises = 0;
  double target_rms = 0, target_max = 0;  ///< "target": √J and max |d| of the matched face
  Eigen::VectorXd p, lambda, volume_gradient;  ///< volume_gradient: dV/dx (design entries)
  Eigen::VectorXd gradient;                    ///< df/dx (design entries), without the volume term
  Eigen::VectorXd x;                           ///< the design point evaluated
  std::shared_ptr<const PartShape> part;
  /// Objectives that solve: the grid model of the solve (its cut elements' fractions freeze the
  /// next line search's switches; the solution and its factorization are not kept) and whether
  /// its switches were its own.
  std::shared_ptr<const GridModel> model;
  /// The solved state itself, kept only until the next evaluation: a refresh of an accepted
  /// point whose switches are its own and frames are not re-integrates on its own frames
  /// without a solve (compliance_own_frames).
  std::shared_ptr<const ComplianceState> state;
  bool switches_own = true;
  bool frames_own = true;  ///< the failure metric's frames were its own (ComplianceState::frames_own)
  /// What a switch refresh of this point reuses, none of which depends on the switches: the
  /// projection, the written part, its moments and dp⊥/dp̃, and (with `model`) the re-cut and
  /// OCCT's volume of the part, which shape_compliance.h's compliance_own_switches re-solves.
  /// The factorization is not kept.
  struct Geometry {
    Eigen::VectorXd target;  ///< p̃: the design written into the anchor
    optimize::ProjectionResult proj;
    ModifyResult mod;
    MomentDerivatives md;
    optimize::ProjectionDerivative D;
  };
  std::shared_ptr<const Geometry> geometry;
  double occt_volume = 0;
};

}  // namespace

ShapeOptimizationResult optimize_shape(const PartShape& part, const ShapeOptimizationOptions& options,
                                       const ShapeProgress& progress) {
  const auto t0 = std::chrono::steady_clock::now();
  ShapeOptimizationResult result;
  const FaceModel model = build_face_model(part, options.face_model);
  const ShapeParameters sp = build_shape_parameters(model, options.parameterization);
  result.notes = sp.notes;
  ObjectiveSpec spec = options.objective;
  // Compliance and the failure metric alone or as terms of a sum (weighted by term_weight;
  // moment terms are added by objective_from_moments); both solve the same
  // elasticity job once per evaluation.
  const ObjectiveSpec* failure_spec = failure_term(spec);
  const bool failure = failure_spec != nullptr;
  const ObjectiveSpec* target_spec = target_term(spec);
  const bool matching = target_spec != nullptr;
  TargetOptions target_options;
  if (matching) {
    target_options.face = target_spec->face;
    PARAFAB_VERIFY(target_options.face >= 0 && target_options.face < static_cast<int>(model.faces.size()),
                   "objective 'target': face " << target_options.face << " outside 0.." << model.faces.size() - 1);
    target_options.target = target_spec->has_target ? target_spec->target : target_of_face(model, target_options.face);
    check_target_surface(target_options.target);
    result.target = target_options.target;
  }
  const bool compliance = spec.type == "compliance" || failure || matching ||
                          (spec.type == "sum" && std::any_of(spec.terms.begin(), spec.terms.end(), [](const ObjectiveSpec& t) {
                             return t.type == "compliance";
                           }));
  const FailureOptions failure_options =
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
  bool scales_set = !(spec.type == "sum" && spec.normalize);
  const auto normalize_terms = [&](const Moments& m, double compliance_value, double failure_value, double target_value) {
    if (scales_set) return;
    for (ObjectiveSpec& t : spec.terms) {
      const double v = t.type == "compliance" ? compliance_value
                       : t.type == "failure"  ? failure_value
                       : t.type == "target"   ? target_value
                                              : objective_from_moments(t, m, nullptr);
      t.scale = std::abs(v) > 0 && std::isfinite(v) ? std::abs(v) : 1.0;
    }
    scales_set = true;
  };
  // Design entries.
  std::vector<int> design = options.design;
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
  const int nd = static_cast<int>(design.size());
  for (int i : design) result.design_names.push_back(sp.names[i]);

  optimize::ProjectionOptions popt = options.projection;
  popt.weights = projection_weights(sp, design, options.follower_weight, part_box(part).diagonal());
  // p and the design entries at the start and at the end of the run.
  const auto set_ends = [&](const Eigen::VectorXd& p_initial, const Eigen::VectorXd& p_final) {
    result.p_initial = p_initial, result.p_final = p_final;
    result.design_initial.resize(nd), result.design_final.resize(nd);
    for (int k = 0; k < nd; ++k) result.design_initial[k] = p_initial[design[k]], result.design_final[k] = p_final[design[k]];
  };
  // The start: the part's own parameters projected (the face model's relations hold to ~1e-6).
  optimize::ProjectionResult start =
      optimize::project(sp.constraints, sp.initial, sp.initial, sp.lower, sp.upper, {}, popt);
  if (!start.done) {
    // No p satisfies every constraint (§6.5.1: "the nearest valid model is returned and said
    // so"): the unit axes and tangencies hold, the user's ties, symmetries and draft give way in
    // least squares. The optimizer does not run on it.
    std::string fallback;
    if (sp.first_user_constraint < sp.constraints.size()) {
      std::vector<bool> soft(sp.constraints.size(), false);
      for (int i = sp.first_user_constraint; i < sp.constraints.size(); ++i) soft[i] = true;
      const optimize::ProjectionResult nearest =
          optimize::project_least_violation(sp.constraints, soft, sp.initial, sp.initial, sp.lower, sp.upper, popt);
      const ModifyResult mod = nearest.done ? modify_part(part, model, sp, nearest.p) : ModifyResult{};
      std::vector<ShapeOptimizationResult::Violation> violated;
      if (nearest.done) {
        const Eigen::VectorXd c = sp.constraints.values(nearest.p);
        for (int i = sp.first_user_constraint; i < sp.constraints.size(); ++i)
          if (std::abs(c[i]) > popt.feasible_violation) violated.push_back({sp.constraints.constraints()[i].name, c[i]});
      }
      if (nearest.done && mod.done && !violated.empty()) {
        std::ostringstream os;
        os << "no parameters satisfying every constraint were found (projection: " << start.status
           << "); the nearest valid model (tangencies kept, the user constraints in least squares) violates";
        for (size_t i = 0; i < violated.size(); ++i) os << (i ? "," : "") << " '" << violated[i].name << "' by " << violated[i].value;
        result.violated_constraints = violated;
        result.status = "infeasible_constraints";
        result.message = os.str();
        result.part = mod.part;
        set_ends(sp.initial, nearest.p);
        result.tangency_residual_max = tangency_residual_max(model, sp, nearest.p);
        result.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
        return result;
      }
      fallback = !nearest.done ? "no nearest valid model either: " + nearest.message
                 : violated.empty()
                     ? "the least-violation model violates no user constraint (the projection failed otherwise)"
                     : "no nearest valid model either: its B-rep update failed: " + mod.message;
      result.notes.push_back(fallback);
    }
    result.status = "invalid_start";
    result.message = "the part's own parameters do not project onto its constraints: " + start.message +
                     (fallback.empty() ? "" : " (" + fallback + ")");
    return result;
  }
  Eigen::VectorXd anchor = start.p;  // p̃ outside the design entries
  Eigen::VectorXd x0(nd), lower(nd), upper(nd);
  const bool absolute = !options.design_min.empty() || !options.design_max.empty();
  PARAFAB_VERIFY(!absolute || (options.design_min.size() == static_cast<size_t>(nd) &&
                               options.design_max.size() == static_cast<size_t>(nd)),
                 "design_min / design_max have " << options.design_min.size() << " / " << options.design_max.size()
                                                 << " entries, the design " << nd);
  for (int k = 0; k < nd; ++k) {
    x0[k] = anchor[design[k]];
    const double span = options.relative_bound > 0 ? options.relative_bound * std::max(1.0, std::abs(x0[k])) : 1e19;
    lower[k] = std::max(sp.lower[design[k]], x0[k] - span);
    upper[k] = std::min(sp.upper[design[k]], x0[k] + span);
    if (absolute) {
      lower[k] = std::max(lower[k], options.design_min[k]);
      upper[k] = std::min(upper[k], options.design_max[k]);
      PARAFAB_VERIFY(lower[k] <= upper[k], "design entry " << k << " (" << sp.names[design[k]] << "): its bounds ["
                                                           << lower[k] << ", " << upper[k] << "] are empty");
      x0[k] = std::clamp(x0[k], lower[k], upper[k]);
    }
  }
  if (options.design_start.size() > 0) {
    PARAFAB_VERIFY(options.design_start.size() == nd, "design_start has " << options.design_start.size()
                                                                          << " entries, the design " << nd);
    for (int k = 0; k < nd; ++k) {
      PARAFAB_VERIFY(std::isfinite(options.design_start[k]), "design_start[" << k << "] is not finite");
      x0[k] = std::clamp(options.design_start[k], lower[k], upper[k]);
    }
  }
  PARAFAB_VERIFY(options.max_outer >= 1, "max_outer must be >= 1, got " << options.max_outer);
  PARAFAB_VERIFY(options.volume_tolerance > 0, "volume_tolerance must be positive");
  Eigen::VectorXd warm_p = start.p;
  const double part_size = part_box(part).diagonal();
  // Compliance: the grid of the whole run is cut from the first evaluated model (the start).
  std::shared_ptr<ComplianceState> base_state;
  // The discrete switches of a line search's trial models are those of its start (the last
  // accepted iterate, evaluated with its own switches): see ShapeOptimizationOptions::freeze_switches.
  std::shared_ptr<const GridModel> line_start;
  const auto is_direction = [&](int i) {
    const std::string& n = sp.names[i];
    return n.find(" normal ") != std::string::npos || n.find("half-angle") != std::string::npos ||
           (n.size() > 7 && n.compare(n.size() - 7, 6, " axis ") == 0);
  };

  // Volume bounds: augmented Lagrangian of Powell–Hestenes–Rockafellar (Nocedal & Wright,
  // Numerical Optimization, §17.4, Eq. 17.65 for inequalities): for g = V/V0 − ratio ≤ 0 the
  // inner L-BFGS minimizes f + s·ψ(g), ψ = (ρ/2)(max(0, g + λ/ρ)² − (λ/ρ)²) (s = max(|f0|, tiny)),
  // and each outer iteration updates λ ← max(0, λ + ρ g), ρ ← 10ρ when |g| did not fall by 4×.
  // Unlike the old quadratic penalty (violation ≈ λ*/ρ, where the line search stalled) λ
  // converges to the true multiplier and the bound holds with ρ bounded.
  struct Bound {
    bool on = false;
    double ratio = 0, sign = 1, lambda = 0, rho = 0;  // g = sign·(V/V0 − ratio)
  };
  Bound bounds[2];
  if (options.volume_max_ratio > 0) bounds[0] = {true, options.volume_max_ratio, 1, 0, options.penalty};
  if (options.volume_min_ratio > 0) bounds[1] = {true, options.volume_min_ratio, -1, 0, options.penalty};
  // Absolute bounds (volume_max / volume_min, e.g. a mass bound over the density) become ratios
  // once V0 is known (the first evaluation); with a ratio on the same side the tighter holds.
  if (options.volume_max > 0) bounds[0].on = true, bounds[0].sign = 1, bounds[0].rho = options.penalty;
  if (options.volume_min > 0) bounds[1].on = true, bounds[1].sign = -1, bounds[1].rho = options.penalty;
  const bool bounded = bounds[0].on || bounds[1].on;
  bool volume_only = false;  // the restoration: V and dV/dx only (no compliance solve)
  auto signed_violation = [&](double V, double V0v) {
    double g = -1e300;
    for (const Bound& b : bounds)
      if (b.on) g = std::max(g, b.sign * (V / V0v - b.ratio));
    return g;
  };

  double V0 = 0, f_scale = 1;
  Evaluation last;
  // F = f + the augmented-Lagrangian terms of the volume bounds (see Bound above) at e, and ∇F.
  auto penalized = [&](const Evaluation& e, double& F, Eigen::VectorXd& grad) {
    F = e.objective;
    double dpsi_dV = 0;
    for (const Bound& b : bounds) {
      if (!b.on) continue;
      const double m = std::max(0.0, b.lambda + b.rho * b.sign * (e.volume / V0 - b.ratio));
      F += f_scale * (m * m - b.lambda * b.lambda) / (2 * b.rho);
      dpsi_dV += f_scale * m * b.sign / V0;
    }
    grad = e.gradient + dpsi_dV * e.volume_gradient;
  };
  // Set by the switch refresh (below): the frozen evaluation of the same point, whose geometry
  // and re-cut are re-solved with the elements' own switches.
  const Evaluation* refresh_of = nullptr;
  struct Interrupted {};  // unwinds from an evaluation out of L-BFGS to the end of the run
  auto interrupted = [&]() { return options.interrupted && options.interrupted(); };
  auto evaluate = [&](const Eigen::VectorXd& x, double& F, Eigen::VectorXd& grad) {
    if (interrupted()) throw Interrupted{};
    ++result.evaluations;
    const Evaluation* reuse = refresh_of;
    refresh_of = nullptr;
    last = Evaluation{};
    std::shared_ptr<const Evaluation::Geometry> geometry = reuse ? reuse->geometry : nullptr;
    if (!geometry) {
      auto g = std::make_shared<Evaluation::Geometry>();
      g->target = anchor;
      for (int k = 0; k < nd; ++k) g->target[design[k]] = x[k];
      g->proj = optimize::project(sp.constraints, g->target, warm_p, sp.lower, sp.upper, {}, popt);  // primal warm start
      if (!g->proj.done) {
        if (result.failed_projections++ == 0) result.notes.push_back("first failed projection: " + g->proj.message);
        return false;  // never evaluate an invalid model
      }
      g->mod = modify_part(part, model, sp, g->proj.p);
      if (!g->mod.done) {
        if (result.invalid_models++ == 0) result.notes.push_back("first invalid B-rep update: " + g->mod.message);
        return false;
      }
      g->md = moment_derivatives(*g->mod.part, sp, g->proj.p, options.quadrature);
      g->D = optimize::projection_derivative(sp.constraints, g->proj, sp.lower, sp.upper, popt.weights);
      geometry = std::move(g);
    }
    last.geometry = geometry;
    const Eigen::VectorXd& target = geometry->target;
    const optimize::ProjectionResult& proj = geometry->proj;
    const ModifyResult& mod = geometry->mod;
    const MomentDerivatives& md = geometry->md;
    const optimize::ProjectionDerivative& D = geometry->D;
    Eigen::Matrix<double, 10, 1> dfdm = Eigen::Matrix<double, 10, 1>::Zero();
    double f = 0;
    Eigen::VectorXd compliance_gradient;
    if (compliance && !volume_only) {
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
      normalize_terms(md.moments, state->compliance, fv.objective, tv.objective);
      const double cw = term_weight(spec, "compliance"), fw = term_weight(spec, "failure"), tw = term_weight(spec, "target");
      f = cw * state->compliance + fw * fv.objective + tw * tv.objective + objective_from_moments(spec, md.moments, &dfdm);
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
        const double h = options.compliance_step * (is_direction(design[k]) ? 1.0 : part_size);
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
    } else if (!compliance) {
      normalize_terms(md.moments, 0.0, 0.0, 0.0);
      f = objective_from_moments(spec, md.moments, &dfdm);
    }
    Eigen::VectorXd dfdp = md.gradient.transpose() * dfdm;
    // Volume bounds: the augmented-Lagrangian term (see Bound above).
    const double V = md.moments[0];
    if (V0 == 0) {
      V0 = V, f_scale = std::max(std::abs(f), 1e-300);
      if (options.volume_max > 0)
        bounds[0].ratio = options.volume_max_ratio > 0 ? std::min(options.volume_max_ratio, options.volume_max / V0)
                                                       : options.volume_max / V0;
      if (options.volume_min > 0)
        bounds[1].ratio = std::max(options.volume_min_ratio, options.volume_min / V0);
    }
    double violation = 0;
    for (const Bound& b : bounds)
      if (b.on) violation = std::max(violation, b.sign * (V / V0 - b.ratio));
    // Chain rule through the projection (Eq. 6.29): dF/dp̃ = (dp⊥/dp̃)ᵀ dF/dp⊥.
    const Eigen::VectorXd g_target = D.jacobian.transpose() * dfdp;
    const Eigen::VectorXd v_target = D.jacobian.transpose() * md.gradient.row(0).transpose();
    grad.resize(nd);
    last.volume_gradient.resize(nd);
    for (int k = 0; k < nd; ++k) grad[k] = g_target[design[k]], last.volume_gradient[k] = v_target[design[k]];
    if (compliance && !volume_only) grad += compliance_gradient;
    if (result.initial_gradient.size() == 0 && !volume_only) result.initial_gradient = grad;  // of f, without the penalty
    last.gradient = grad;
    last.x = x;
    last.objective = f;
    last.volume = V;
    penalized(last, F, grad);
    last.ok = true;
    last.penalized = F;
    last.violation = violation;
    last.p = proj.p;
    last.lambda = proj.multipliers;
    last.part = mod.part;
    warm_p = proj.p;
    return true;
  };

  // At an accepted point whose frozen switches differ from its own: evaluated again with its
  // own, so that the next line search starts from the model's own objective and gradient.
  auto refresh = [&](const Eigen::VectorXd& x, double& F, Eigen::VectorXd& grad) {
    // The failure metric integrates on frames frozen with the switches: refreshed as they are.
    if (!last.model || (last.switches_own && (!failure || last.frames_own))) return false;
    const Evaluation frozen = last;
    const int invalid = result.invalid_models;
    const size_t notes = result.notes.size();
    const std::shared_ptr<const GridModel> keep = line_start;
    line_start.reset();
    refresh_of = &frozen;
    const bool ok = evaluate(x, F, grad) && std::isfinite(F);
    line_start = keep;
    if (!ok) {  // keep the frozen value (the model is valid: it was just evaluated)
      last = frozen;
      result.invalid_models = invalid;
      result.notes.resize(notes);
      return false;
    }
    ++result.switch_refreshes;
    return true;
  };
  Evaluation accepted;
  int outer_index = 0, iteration_count = 0;
  auto on_iterate = [&](const optimize::LbfgsIterate& it) {
    accepted = last;
    accepted.geometry.reset();  // dp⊥/dp̃ is dense: not kept through the next line search
    accepted.state.reset();     // nor the solution and its factorization
    line_start = accepted.model;
    // Later outer iterations restart L-BFGS at the previous end point: its iterate 0 is not new.
    if (it.iteration == 0 && outer_index > 0) return true;
    if (iteration_count == 0) {
      result.initial_max_von_mises = accepted.max_von_mises;
      result.initial_target_rms = accepted.target_rms, result.initial_target_max = accepted.target_max;
    }
    ShapeIterate s;
    s.iteration = iteration_count++;
    s.outer = outer_index;
    s.evaluations = result.evaluations;
    s.objective = accepted.objective;
    s.constraint_violation = accepted.violation;
    s.tangency_residual = tangency_residual_max(model, sp, accepted.p);
    s.design.resize(nd);
    for (int k = 0; k < nd; ++k) s.design[k] = accepted.p[design[k]];
    s.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    result.iterations.push_back(s);
    return (!progress || progress(s)) && !interrupted();
  };
  optimize::LbfgsResult run;
  Eigen::VectorXd x = x0;
  // The start evaluated before the first inner run (for the multiplier estimate), handed to
  // that run as its first evaluation instead of being repeated.
  Evaluation evaluated_start;
  auto objective = [&](const Eigen::VectorXd& xk, double& F, Eigen::VectorXd& grad) {
    if (evaluated_start.ok && xk == evaluated_start.x) {
      last = evaluated_start;
      evaluated_start = Evaluation{};
      penalized(last, F, grad);
      last.penalized = F;
      return true;
    }
    evaluated_start = Evaluation{};
    return evaluate(xk, F, grad);
  };
  try {
    if (bounded && options.estimate_multiplier) {
      // Least-squares multiplier estimate of a bound that holds with equality or is violated at
      // the start (Nocedal & Wright §17.4 / §18.3, Eq. 18.21: λ minimizing ‖∇f + s λ ∇g‖ over
      // the entries not at a bound): the first steps of the inner run then follow the bound to
      // first order, instead of crossing it and being cut back by the penalty. A bound that is
      // inactive at the start keeps λ = 0.
      double F = 0;
      Eigen::VectorXd grad;
      if (!evaluate(x, F, grad)) throw Error("the objective cannot be evaluated at the start");
      evaluated_start = last;
      for (Bound& b : bounds) {
        if (!b.on || b.sign * (last.volume / V0 - b.ratio) < -options.volume_tolerance) continue;
        double gf = 0, gg = 0;
        for (int k = 0; k < nd; ++k) {
          if (x[k] <= lower[k] || x[k] >= upper[k]) continue;
          const double dg = b.sign * last.volume_gradient[k] / V0;
          gf += last.gradient[k] * dg, gg += dg * dg;
        }
        if (gg > 0) b.lambda = std::max(0.0, -gf / (f_scale * gg));
      }
    }
    double previous_g = 1e300;
    for (outer_index = 0; outer_index < (bounded ? options.max_outer : 1); ++outer_index) {
      const int evaluations_before = outer_index == 0 ? 0 : result.evaluations;  // the start's included
      run = optimize::minimize_lbfgs(objective, x, lower, upper, options.lbfgs, on_iterate,
                                     options.freeze_switches ? optimize::ObjectiveFunction(refresh) : optimize::ObjectiveFunction());
      x = run.x;
      if (!bounded) break;
      AugmentedLagrangianStep step;
      step.outer = outer_index;
      step.multiplier = bounds[0].on ? bounds[0].lambda : bounds[1].lambda;
      step.penalty = bounds[0].on ? bounds[0].rho : bounds[1].rho;
      step.violation = signed_violation(accepted.volume, V0);
      step.objective = accepted.objective;
      step.inner_status = run.status;
      step.inner_iterations = static_cast<int>(run.iterates.size()) - 1;
      step.evaluations = result.evaluations - evaluations_before;
      result.outer.push_back(step);
      if (run.status == "cancelled" || run.status == "evaluation_failed") break;
      // Multiplier update (first-order), penalty growth when the violation did not fall enough.
      double g_max = 0;  // complementarity: |g| where λ > 0, max(g, 0) where λ = 0
      for (Bound& b : bounds) {
        if (!b.on) continue;
        const double g = b.sign * (accepted.volume / V0 - b.ratio);
        b.lambda = std::max(0.0, b.lambda + b.rho * g);
        g_max = std::max(g_max, b.lambda > 0 ? std::abs(g) : std::max(g, 0.0));
        if (g > 0.25 * previous_g && g > options.volume_tolerance) b.rho *= 10;
      }
      const double viol = std::max(0.0, signed_violation(accepted.volume, V0));
      // Stop when feasible and complementary (an active bound: |g| ≤ 100·tolerance, relative;
      // an inactive one: λ = 0), or when the inner run made no step (the multiplier cannot move
      // the design any more).
      if (viol <= options.volume_tolerance && g_max <= 100 * options.volume_tolerance) break;
      if (step.inner_iterations == 0 && viol <= options.volume_tolerance) break;
      previous_g = viol > 0 ? viol : previous_g;
    }
    if (outer_index >= options.max_outer) outer_index = options.max_outer - 1;
  } catch (const Interrupted&) {
    run.status = "cancelled";  // as a callback's false: the accepted iterate stands (below)
    run.done = false;
  } catch (const Error& e) {
    result.status = "invalid_start";
    result.message = std::string("the start cannot be evaluated: ") + e.what() +
                     (result.notes.empty() ? "" : " (" + result.notes.back() + ")");
    return result;
  }
  // Restoration: if the outer iterations end above the tolerance, Newton steps on the volume
  // alone along dV/dx (V is smooth in x; a few steps) onto the bound minus half the tolerance.
  if (bounded && accepted.ok && signed_violation(accepted.volume, V0) > options.volume_tolerance &&
      run.status != "cancelled" && !interrupted()) {
    volume_only = true;
    Evaluation good = accepted;
    Eigen::VectorXd xr(nd), gr;
    for (int k = 0; k < nd; ++k) xr[k] = good.p[design[k]];
    double F = 0;
    for (int it = 0; it < 10 && signed_violation(good.volume, V0) > options.volume_tolerance; ++it) {
      const double g = signed_violation(good.volume, V0) + 0.5 * options.volume_tolerance;
      const Bound& b = bounds[0].on && bounds[0].sign * (good.volume / V0 - bounds[0].ratio) > 0 ? bounds[0] : bounds[1];
      const Eigen::VectorXd dg = b.sign * good.volume_gradient / V0;
      if (dg.squaredNorm() == 0) break;
      xr = (xr - g / dg.squaredNorm() * dg).cwiseMax(lower).cwiseMin(upper);
      if (!evaluate(xr, F, gr)) break;
      good = last;
    }
    volume_only = false;
    if (signed_violation(good.volume, V0) <= options.volume_tolerance) {
      // The objective at the restored design (a full evaluation, compliance included, with its
      // own discrete switches).
      line_start.reset();
      if (evaluate(xr, F, gr)) {
        result.volume_restored = true;
        last.violation = std::max(0.0, signed_violation(last.volume, V0));
        ++outer_index;
        on_iterate({iteration_count, F, xr, 0, result.evaluations});
      }
    }
  }
  if (run.status == "cancelled") {
    // Interrupted (a signal, Cancel, the callback): the best valid iterate so far is the result.
    result.done = false;
    result.status = "interrupted";
    result.message = "interrupted after " + std::to_string(result.iterations.size()) +
                     " accepted iterates; the last valid one is kept";
    if (!accepted.part) {  // before the start was accepted: the part as read is the best so far
      result.message = "interrupted before the start was evaluated: the part is unchanged";
      result.part = std::make_shared<PartShape>(part);
      result.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
      return result;
    }
  }
  result.final_violation = std::max(0.0, bounded ? signed_violation(accepted.volume, V0) : 0.0);
  const bool interrupted_run = result.status == "interrupted";
  result.done = run.done && !interrupted_run;
  if (!interrupted_run) result.status = run.status, result.message = run.message;
  if (bounded && result.final_violation > options.volume_tolerance && run.done) {
    result.done = false;
    result.status = "infeasible";
    result.message = "the volume bound is violated by " + std::to_string(result.final_violation) +
                     " (relative) after the augmented-Lagrangian iterations and the restoration";
  } else if (bounded && result.volume_restored) {
    result.message = "feasible after a volume restoration (inner run: " + run.status + ")";
  }
  result.initial_objective = result.iterations.front().objective;
  result.final_objective = accepted.objective;
  result.final_max_von_mises = accepted.max_von_mises;
  result.final_target_rms = accepted.target_rms, result.final_target_max = accepted.target_max;
  result.initial_volume = V0;
  result.final_volume = accepted.volume;
  set_ends(start.p, accepted.p);
  result.part = accepted.part;
  // Tangency on the final B-rep: the face model of the written part, its own relations (if its
  // NURBS conversion fails, the original relations evaluated at p⊥).
  try {
    const FaceModel final_model = build_face_model(*accepted.part, options.face_model);
    for (const TangencyRelation& r : final_model.relations)
      for (double v : r.residuals) result.tangency_residual_max = std::max(result.tangency_residual_max, std::abs(v));
    if (final_model.relations.size() != model.relations.size())
      result.notes.push_back("the final part has " + std::to_string(final_model.relations.size()) +
                             " relations (tangent or coaxial faces), the original " + std::to_string(model.relations.size()));
  } catch (const Error& e) {
    result.tangency_residual_max = tangency_residual_max(model, sp, accepted.p);
    result.notes.push_back(std::string("tangency residual from the parameters (face model of the result: ") +
                           e.what() + ")");
  }
  result.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return result;
}

}  // namespace parafab::occ
