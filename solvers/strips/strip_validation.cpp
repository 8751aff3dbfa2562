#include "strips/strip_validation.h"

#include <algorithm>
#include <cmath>

#include "common/error.h"
#include "strips/composite_strip.h"

namespace parafab {

StripValidation validate_strip(const BSplineCurve2& bspline, const StripDesign& design,
                               const StripDesignOptions& o, const StripValidationOptions& v) {
  PARAFAB_VERIFY(design.feasible && !design.samples.empty(),
                 "validate_strip: the design is not feasible (" << design.reason << ")");
  const PlaneCurve curve(bspline);
  const double l = curve.length();
  const StripPerturbation& pert = v.perturbation;
  PlaneRodProblem p;
  p.length = l;
  for (const auto& s : design.samples) {
    p.stiffness_s.push_back(s.s);
    p.stiffness.push_back(1.0 + pert.stiffness_ratio_scale * (s.K - 1.0));
  }
  // Composite strip under gravity: the strip as cut (design_composite_strip's layer widths),
  // its stiffness E/12·(h₁³w₁ + ((h₁+h₂)³ − h₁³)w₂) and the weight ρg(h₁w₁ + r h₂w₂) of both
  // layers, computed from the widths alone (not from the design's weight model).
  if (o.composite.enabled && o.gravity.enabled && pert.stiffness_ratio_scale == 1.0) {
    const double h1 = o.composite.outer_thickness, h2 = o.composite.inner_thickness;
    const double w1 = o.composite.outer_width;
    CompositeStripOptions co;
    co.outer_thickness = h1;
    co.inner_thickness = h2;
    std::vector<double> K;
    for (const auto& q : design.samples) K.push_back(q.K);
    const CompositeStripResult cr =
        design_composite_strip(p.stiffness_s, K, std::vector<double>(K.size(), w1), co);
    PARAFAB_VERIFY(cr.feasible, "validate_strip: the composite strip is infeasible: " << cr.message);
    const double P1 = h1 * h1 * h1, P2 = std::pow(h1 + h2, 3) - P1;
    for (size_t i = 0; i < K.size(); ++i) {
      const double stiff = P1 * w1 + P2 * cr.inner_width[i];  // ×E/12
      p.stiffness[i] = stiff / (P1 + P2) / w1;
      p.weight_ratio.push_back(o.thickness * o.thickness *
                               (h1 * w1 + o.composite.inner_density_ratio * h2 * cr.inner_width[i]) / stiff);
    }
  }
  const CurvePoint a = curve.at_arc_length(0), b = curve.at_arc_length(l);
  p.start_point = a.point;
  p.end_point = b.point;
  p.boundary = o.boundary;
  p.load = o.gravity.load() * pert.gravity_scale;
  p.law = o.law;
  if (std::isfinite(pert.curvature_limit)) {
    p.law.curvature_limit = pert.curvature_limit;
    p.law.plastic_hardening = pert.plastic_hardening;
  }
  p.natural_curvature = o.natural_curvature;
  // Ideal plasticity (H = 0, App. A.5): the curvature beyond the limit is a permanent set.
  // The bent strip is then an elastic strip whose natural curvature is κ₀ + that set,
  // κ_p = sign(κ − κ₀)·(|κ − κ₀| − κ_lim)₊ of the target, so its moment is K·m(κ_eff).
  const bool ideal = std::isfinite(o.law.curvature_limit) && o.law.plastic_hardening == 0 &&
                     !std::isfinite(pert.curvature_limit);
  if (ideal) {
    p.law.curvature_limit = INFINITY;
    const int n = std::max(v.rod.edges, 1) * 4;
    for (int k = 0; k <= n; ++k) {
      const double s = l * k / n, kap = curve.at_arc_length(s).kappa - o.natural_curvature;
      p.natural_curvature_s.push_back(s);
      p.natural_curvature_field.push_back(std::copysign(std::max(std::abs(kap) - o.law.curvature_limit, 0.0), kap));
    }
  }
  // Initial guess: the target's chord angles, unwrapped; the clamp angles continue them.
  const int N = v.rod.edges;
  std::vector<Vec2> target(N + 1);
  for (int k = 0; k <= N; ++k) target[k] = curve.at_arc_length(l * k / N).point;
  p.initial_angles.resize(N);
  double prev = std::atan2(a.tangent.y(), a.tangent.x());
  p.start_angle = prev + pert.start_angle_offset;
  for (int j = 0; j < N; ++j) {
    const Vec2 d = target[j + 1] - target[j];
    double ang = std::atan2(d.y(), d.x());
    ang += 2 * M_PI * std::round((prev - ang) / (2 * M_PI));
    p.initial_angles[j] = prev = ang;
  }
  double end = std::atan2(b.tangent.y(), b.tangent.x());
  end += 2 * M_PI * std::round((prev - end) / (2 * M_PI));
  p.end_angle = end + pert.end_angle_offset;

  StripValidation out;
  out.simulation = simulate_plane_rod(p, v.rod);
  const PlaneRodResult& r = out.simulation;
  out.converged = r.converged;
  out.iterations = r.iterations;
  out.load_steps = r.load_steps;
  out.seconds = r.seconds;
  out.message = r.message;
  out.max_distance = 0;
  for (int k = 0; k <= N; ++k) {
    const double dist = (r.nodes[k] - target[k]).norm();
    if (dist > out.max_distance) out.max_distance = dist, out.worst_s = r.node_s[k];
  }
  out.deviation = out.max_distance / l;
  return out;
}

}  // namespace parafab
