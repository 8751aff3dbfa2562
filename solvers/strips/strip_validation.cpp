#include "strips/strip_validation.h"

#include <cmath>

#include "common/error.h"

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
