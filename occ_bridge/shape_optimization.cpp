// Shape optimization over projected CAD parameters (thesis §6.2.3 Eq. 6.5 objectives, §6.5.1
// projection Eq. 6.25-6.26, §6.5.2 chain rule Eq. 6.28-6.29): the objective's terms, and
// optimize_shape's driver, its history and the outer iterations of its volume bounds (the
// evaluations are in shape_evaluation.cpp).
#include "shape_optimization.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <set>
#include <sstream>

#include "common/error.h"
#include "occt_shape.h"
#include "optimize/jet.h"
#include "shape_evaluation.h"
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

using detail::EvaluationCache;
using detail::Evaluation;
using detail::ShapeProblem;
using detail::VolumeBounds;
using Clock = std::chrono::steady_clock;

// p and the design entries at the start and at the end of the run.
void set_ends(ShapeOptimizationResult& result, const std::vector<int>& design, const Eigen::VectorXd& p_initial,
              const Eigen::VectorXd& p_final) {
  const int nd = static_cast<int>(design.size());
  result.p_initial = p_initial, result.p_final = p_final;
  result.design_initial.resize(nd), result.design_final.resize(nd);
  for (int k = 0; k < nd; ++k) result.design_initial[k] = p_initial[design[k]], result.design_final[k] = p_final[design[k]];
}

// The part's own parameters do not project onto its constraints (`start` failed): the result
// says why, with the nearest valid model where one violates only the user's constraints.
void refuse_start(const ShapeProblem& pb, const optimize::ProjectionResult& start, ShapeOptimizationResult& result,
                  Clock::time_point t0) {
  const PartShape& part = pb.part;
  const FaceModel& model = pb.model;
  const ShapeParameters& sp = pb.sp;
  const optimize::ProjectionOptions& popt = pb.popt;
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
      set_ends(result, pb.design, sp.initial, nearest.p);
      result.tangency_residual_max = tangency_residual_max(model, sp, nearest.p);
      result.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
      return;
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
}

// The design box [lower, upper] (relative_bound about the start, design_min / design_max) and
// the start x0 in it (design_start where given).
void design_box(const ShapeProblem& pb, const Eigen::VectorXd& anchor, Eigen::VectorXd& x0, Eigen::VectorXd& lower,
                Eigen::VectorXd& upper) {
  const ShapeOptimizationOptions& options = pb.options;
  const ShapeParameters& sp = pb.sp;
  const std::vector<int>& design = pb.design;
  const int nd = pb.nd;
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
}

// The run's history: every accepted iterate (the evaluation L-BFGS accepted last) recorded as a
// ShapeIterate and reported to `progress`.
class ShapeHistory {
 public:
  ShapeHistory(const ShapeProblem& pb, EvaluationCache& cache, ShapeOptimizationResult& result,
               const ShapeProgress& progress, Clock::time_point t0)
      : pb_(pb), cache_(cache), result_(result), progress_(progress), t0_(t0) {}

  // L-BFGS's iterate callback: false stops the run (the progress callback or an interrupt).
  bool on_iterate(const optimize::LbfgsIterate& it) {
    ShapeOptimizationResult& result = result_;
    const Evaluation& last = cache_.last;
    std::shared_ptr<const GridModel>& line_start = cache_.line_start;
    const FaceModel& model = pb_.model;
    const ShapeParameters& sp = pb_.sp;
    const std::vector<int>& design = pb_.design;
    const int nd = pb_.nd;
    const auto& progress = progress_;
    const auto t0 = t0_;
    const auto interrupted = [&]() { return cache_.interrupted(); };
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
  }

  Evaluation accepted;  ///< the last accepted iterate (without its geometry and solution)
  int outer_index = 0, iteration_count = 0;

 private:
  const ShapeProblem& pb_;
  EvaluationCache& cache_;
  ShapeOptimizationResult& result_;
  const ShapeProgress& progress_;
  Clock::time_point t0_;
};

// Least-squares multiplier estimate of a bound that holds with equality or is violated at
// the start (Nocedal & Wright §17.4 / §18.3, Eq. 18.21: λ minimizing ‖∇f + s λ ∇g‖ over
// the entries not at a bound): the first steps of the inner run then follow the bound to
// first order, instead of crossing it and being cut back by the penalty. A bound that is
// inactive at the start keeps λ = 0. The start's evaluation is kept for the first inner run.
void estimate_multipliers(EvaluationCache& cache, VolumeBounds& vb, const ShapeOptimizationOptions& options,
                          const Eigen::VectorXd& x, const Eigen::VectorXd& lower, const Eigen::VectorXd& upper) {
  const Evaluation& last = cache.last;
  const int nd = static_cast<int>(x.size());
  double F = 0;
  Eigen::VectorXd grad;
  if (!cache.evaluate(x, F, grad)) throw Error("the objective cannot be evaluated at the start");
  cache.evaluated_start = last;
  const double V0 = vb.V0, f_scale = vb.f_scale;
  for (VolumeBounds::Bound& b : vb.bounds) {
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

// The outer iterations of the augmented Lagrangian (VolumeBounds): an L-BFGS run on F, then the
// multiplier update and the penalty's growth, until feasible and complementary (one run
// without bounds). Throws Interrupted and parafab::Error from the evaluations.
void outer_iterations(const ShapeOptimizationOptions& options, EvaluationCache& cache, VolumeBounds& vb,
                      ShapeHistory& history, ShapeOptimizationResult& result, Eigen::VectorXd& x,
                      const Eigen::VectorXd& lower, const Eigen::VectorXd& upper, optimize::LbfgsResult& run) {
  VolumeBounds::Bound* bounds = vb.bounds;
  const bool bounded = vb.bounded;
  const double& V0 = vb.V0;
  const Evaluation& accepted = history.accepted;
  int& outer_index = history.outer_index;
  const auto signed_violation = [&](double V, double V0v) { return vb.signed_violation(V, V0v); };
  const auto objective = [&](const Eigen::VectorXd& xk, double& F, Eigen::VectorXd& grad) {
    return cache.objective(xk, F, grad);
  };
  const auto refresh = [&](const Eigen::VectorXd& xk, double& F, Eigen::VectorXd& grad) {
    return cache.refresh(xk, F, grad);
  };
  const auto on_iterate = [&](const optimize::LbfgsIterate& it) { return history.on_iterate(it); };
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
    for (VolumeBounds::Bound& b : vb.bounds) {
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
}

// Restoration: if the outer iterations end above the tolerance, Newton steps on the volume
// alone along dV/dx (V is smooth in x; a few steps) onto the bound minus half the tolerance.
void restore_volume(const ShapeProblem& pb, EvaluationCache& cache, const VolumeBounds& vb, ShapeHistory& history,
                    ShapeOptimizationResult& result, const Eigen::VectorXd& lower, const Eigen::VectorXd& upper,
                    const optimize::LbfgsResult& run) {
  const ShapeOptimizationOptions& options = pb.options;
  const std::vector<int>& design = pb.design;
  const int nd = pb.nd;
  const VolumeBounds::Bound* bounds = vb.bounds;
  const bool bounded = vb.bounded;
  const double V0 = vb.V0;
  const Evaluation& accepted = history.accepted;
  const Evaluation& last = cache.last;
  bool& volume_only = cache.volume_only;
  const auto signed_violation = [&](double V, double V0v) { return vb.signed_violation(V, V0v); };
  const auto interrupted = [&]() { return cache.interrupted(); };
  if (!(bounded && accepted.ok && signed_violation(accepted.volume, V0) > options.volume_tolerance &&
      run.status != "cancelled" && !interrupted())) return;
  volume_only = true;
  Evaluation good = accepted;
  Eigen::VectorXd xr(nd), gr;
  for (int k = 0; k < nd; ++k) xr[k] = good.p[design[k]];
  double F = 0;
  for (int it = 0; it < 10 && signed_violation(good.volume, V0) > options.volume_tolerance; ++it) {
    const double g = signed_violation(good.volume, V0) + 0.5 * options.volume_tolerance;
    const VolumeBounds::Bound& b = bounds[0].on && bounds[0].sign * (good.volume / V0 - bounds[0].ratio) > 0 ? bounds[0] : bounds[1];
    const Eigen::VectorXd dg = b.sign * good.volume_gradient / V0;
    if (dg.squaredNorm() == 0) break;
    xr = (xr - g / dg.squaredNorm() * dg).cwiseMax(lower).cwiseMin(upper);
    if (!cache.evaluate(xr, F, gr)) break;
    good = last;
  }
  volume_only = false;
  if (signed_violation(good.volume, V0) <= options.volume_tolerance) {
    // The objective at the restored design (a full evaluation, compliance included, with its
    // own discrete switches).
    cache.line_start.reset();
    if (cache.evaluate(xr, F, gr)) {
      result.volume_restored = true;
      cache.last.violation = std::max(0.0, signed_violation(last.volume, V0));
      ++history.outer_index;
      history.on_iterate({history.iteration_count, F, xr, 0, result.evaluations});
    }
  }
}

// The result of a run that got past its start: status and message, the ends, the final part and
// its tangency residual on its own face model.
void finish_result(const ShapeProblem& pb, const VolumeBounds& vb, const Evaluation& accepted,
                   const optimize::LbfgsResult& run, const Eigen::VectorXd& start_p, ShapeOptimizationResult& result) {
  const ShapeOptimizationOptions& options = pb.options;
  const FaceModel& model = pb.model;
  const ShapeParameters& sp = pb.sp;
  const std::vector<int>& design = pb.design;
  const bool bounded = vb.bounded;
  const double V0 = vb.V0;
  const auto signed_violation = [&](double V, double V0v) { return vb.signed_violation(V, V0v); };
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
  set_ends(result, design, start_p, accepted.p);
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
}

}  // namespace

ShapeOptimizationResult optimize_shape(const PartShape& part, const ShapeOptimizationOptions& options,
                                       const ShapeProgress& progress) {
  const auto t0 = std::chrono::steady_clock::now();
  ShapeOptimizationResult result;
  ShapeProblem pb(part, options, result);
  const ShapeParameters& sp = pb.sp;
  const int nd = pb.nd;
  // The start: the part's own parameters projected (the face model's relations hold to ~1e-6).
  optimize::ProjectionResult start =
      optimize::project(sp.constraints, sp.initial, sp.initial, sp.lower, sp.upper, {}, pb.popt);
  if (!start.done) {
    refuse_start(pb, start, result, t0);
    return result;
  }
  Eigen::VectorXd anchor = start.p;  // p̃ outside the design entries
  Eigen::VectorXd x0(nd), lower(nd), upper(nd);
  design_box(pb, anchor, x0, lower, upper);
  PARAFAB_VERIFY(options.max_outer >= 1, "max_outer must be >= 1, got " << options.max_outer);
  PARAFAB_VERIFY(options.volume_tolerance > 0, "volume_tolerance must be positive");
  VolumeBounds vb(options);
  EvaluationCache cache(pb, vb, result, anchor, start.p);
  ShapeHistory history(pb, cache, result, progress, t0);
  optimize::LbfgsResult run;
  Eigen::VectorXd x = x0;
  try {
    if (vb.bounded && options.estimate_multiplier) estimate_multipliers(cache, vb, options, x, lower, upper);
    outer_iterations(options, cache, vb, history, result, x, lower, upper, run);
  } catch (const detail::Interrupted&) {
    run.status = "cancelled";  // as a callback's false: the accepted iterate stands (below)
    run.done = false;
  } catch (const Error& e) {
    result.status = "invalid_start";
    result.message = std::string("the start cannot be evaluated: ") + e.what() +
                     (result.notes.empty() ? "" : " (" + result.notes.back() + ")");
    return result;
  }
  restore_volume(pb, cache, vb, history, result, lower, upper, run);
  const Evaluation& accepted = history.accepted;
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
  finish_result(pb, vb, accepted, run, start.p, result);
  result.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return result;
}

}  // namespace parafab::occ
