// optimize_shape's evaluation cache (thesis §6.5: one evaluation projects the design onto
// c_para = 0, Eq. 6.25-6.26, writes the model back and evaluates the objective with its
// gradient chained through dp⊥/dp̃, Eq. 6.29), the run's fixed problem and the
// augmented-Lagrangian terms of its volume bounds. Only for occ_bridge/shape_optimization*.cpp.
#pragma once

#include <memory>
#include <vector>

#include "shape_modify.h"
#include "shape_optimization.h"

namespace parafab::occ::detail {

/// One evaluated design point.
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

/// What stays fixed through a run (the objective's scales aside, set at the first evaluation
/// with "normalize"): the face model, the parameters, the objective's terms and the design.
/// The constructor validates the options (parafab::Error on bad input).
struct ShapeProblem {
  ShapeProblem(const PartShape& part, const ShapeOptimizationOptions& options, ShapeOptimizationResult& result);

  const PartShape& part;
  const ShapeOptimizationOptions& options;
  FaceModel model;
  ShapeParameters sp;
  ObjectiveSpec spec;
  bool failure = false, matching = false;
  bool compliance = false;  ///< an objective term that solves (compliance, failure or target)
  TargetOptions target_options;
  FailureOptions failure_options;
  bool scales_set = true;  ///< false until a "normalize" sum's scales are set
  std::vector<int> design;  ///< the design entries of p
  int nd = 0;
  optimize::ProjectionOptions popt;
  double part_size = 0;  ///< the part's box diagonal

  /// "normalize": every term of a sum divided by its value at the first evaluation (the start).
  void normalize_terms(const Moments& m, double compliance_value, double failure_value, double target_value);
  /// Whether entry i of p is a direction (a normal, an axis, a half-angle): its difference
  /// step is not scaled by the part's size.
  bool is_direction(int i) const;
};

/// Volume bounds: augmented Lagrangian of Powell–Hestenes–Rockafellar (Nocedal & Wright,
/// Numerical Optimization, §17.4, Eq. 17.65 for inequalities): for g = V/V0 − ratio ≤ 0 the
/// inner L-BFGS minimizes f + s·ψ(g), ψ = (ρ/2)(max(0, g + λ/ρ)² − (λ/ρ)²) (s = max(|f0|, tiny)),
/// and each outer iteration updates λ ← max(0, λ + ρ g), ρ ← 10ρ when |g| did not fall by 4×.
/// Unlike the old quadratic penalty (violation ≈ λ*/ρ, where the line search stalled) λ
/// converges to the true multiplier and the bound holds with ρ bounded.
struct VolumeBounds {
  struct Bound {
    bool on = false;
    double ratio = 0, sign = 1, lambda = 0, rho = 0;  // g = sign·(V/V0 − ratio)
  };
  explicit VolumeBounds(const ShapeOptimizationOptions& options);

  Bound bounds[2];
  bool bounded = false;
  double V0 = 0, f_scale = 1;  ///< set at the first evaluation (set_reference)

  /// The largest g of the bounds that are on (−1e300 with none).
  double signed_violation(double V, double V0v) const;
  /// F = f + the augmented-Lagrangian terms at e, and ∇F.
  void penalized(const Evaluation& e, double& F, Eigen::VectorXd& grad) const;
  /// At the first evaluation: V0, the scale s and the absolute bounds (volume_max / volume_min,
  /// e.g. a mass bound over the density) as ratios; with a ratio on the same side the tighter holds.
  void set_reference(double V, double f, const ShapeOptimizationOptions& options);
};

/// Unwinds from an evaluation out of L-BFGS to the end of the run (options.interrupted).
struct Interrupted {};

/// The evaluations of a run: each design x projected, written and evaluated (the geometry of a
/// switch refresh reused), with the state the next evaluation starts from (the projection's warm
/// start, the grid of the run, the line search's switches).
class EvaluationCache {
 public:
  EvaluationCache(ShapeProblem& problem, VolumeBounds& bounds, ShapeOptimizationResult& result,
                  const Eigen::VectorXd& anchor, const Eigen::VectorXd& warm_p);

  /// F (penalized) and its gradient at x; false where the model is invalid. Throws Interrupted.
  bool evaluate(const Eigen::VectorXd& x, double& F, Eigen::VectorXd& grad);
  /// At an accepted point whose frozen switches differ from its own: evaluated again with its
  /// own, so that the next line search starts from the model's own objective and gradient.
  bool refresh(const Eigen::VectorXd& x, double& F, Eigen::VectorXd& grad);
  /// evaluate, or the start's evaluation if x is the start evaluated before the first inner run.
  bool objective(const Eigen::VectorXd& x, double& F, Eigen::VectorXd& grad);
  bool interrupted() const { return problem_.options.interrupted && problem_.options.interrupted(); }

  Evaluation last;  ///< the latest evaluation
  /// The start evaluated before the first inner run (for the multiplier estimate), handed to
  /// that run as its first evaluation instead of being repeated.
  Evaluation evaluated_start;
  /// The discrete switches of a line search's trial models are those of its start (the last
  /// accepted iterate, evaluated with its own switches): see ShapeOptimizationOptions::freeze_switches.
  std::shared_ptr<const GridModel> line_start;
  bool volume_only = false;  ///< the restoration: V and dV/dx only (no compliance solve)

 private:
  // The solving terms (compliance, failure, target) at the evaluated geometry: f, and their
  // gradient per design entry by the exact route where it applies, else semi-analytic.
  bool solving_terms(const Evaluation* reuse, const Evaluation::Geometry& geometry, Eigen::Matrix<double, 10, 1>& dfdm,
                     double& f, Eigen::VectorXd& compliance_gradient);
  // Their gradient per design entry: the exact route for every entry whose direction dp⊥/dp̃
  // it covers, the others differenced over two perturbed models.
  bool design_gradient(const ComplianceState& solved, const FailureValue& fv, const Eigen::VectorXd& adjoint,
                       const TargetValue& tv, const Eigen::VectorXd& target_adjoint_u,
                       const Evaluation::Geometry& geometry, Eigen::VectorXd& compliance_gradient);

  ShapeProblem& problem_;
  VolumeBounds& bounds_;
  ShapeOptimizationResult& result_;
  Eigen::VectorXd anchor_;  ///< p̃ outside the design entries
  Eigen::VectorXd warm_p_;  ///< the projection's primal warm start
  /// Compliance: the grid of the whole run is cut from the first evaluated model (the start).
  std::shared_ptr<ComplianceState> base_state_;
  /// Set by the switch refresh: the frozen evaluation of the same point, whose geometry and
  /// re-cut are re-solved with the elements' own switches.
  const Evaluation* refresh_of_ = nullptr;
};

}  // namespace parafab::occ::detail
