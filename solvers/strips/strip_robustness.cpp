#include "strips/strip_robustness.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <sstream>

#include "common/error.h"

namespace parafab {

StripRobustness strip_robustness_study(const BSplineCurve2& curve, const StripDesign& design,
                                       const StripDesignOptions& o,
                                       const StripRobustnessOptions& ro) {
  const auto t0 = std::chrono::steady_clock::now();
  PARAFAB_VERIFY(design.feasible, "robustness study: the design is not feasible (" << design.reason << ")");
  for (double f : ro.plastic_fractions)
    PARAFAB_VERIFY(f > 0 && f < 1, "robustness.plastic_fractions must lie in (0, 1), got " << f);
  std::vector<std::pair<std::string, StripPerturbation>> todo;
  auto pct = [](double x) {
    std::ostringstream os;
    os << (x >= 0 ? "+" : "") << std::lround(100 * x) << "%";
    return os.str();
  };
  todo.push_back({"baseline", {}});
  for (double sg : {1.0, -1.0}) {
    StripPerturbation p;
    p.stiffness_ratio_scale = 1 + sg * ro.stiffness_change;
    todo.push_back({"stiffness_range" + pct(sg * ro.stiffness_change), p});
  }
  if (o.gravity.enabled) {
    for (double sg : {1.0, -1.0}) {
      StripPerturbation p;
      p.gravity_scale = 1 + sg * ro.gravity_change;
      todo.push_back({"gravity" + pct(sg * ro.gravity_change), p});
    }
  }
  for (double sg : {1.0, -1.0}) {
    StripPerturbation p;  // opening: start turned clockwise, end counter-clockwise
    p.start_angle_offset = -sg * ro.angle_change;
    p.end_angle_offset = sg * ro.angle_change;
    std::ostringstream os;
    os << "end_angles_" << (sg > 0 ? "opened_" : "closed_") << std::lround(ro.angle_change * 180 / M_PI) << "deg";
    todo.push_back({os.str(), p});
  }
  std::vector<double> kap;
  for (const auto& s : design.samples) kap.push_back(std::abs(s.kappa - o.natural_curvature));
  std::sort(kap.begin(), kap.end());
  for (double f : ro.plastic_fractions) {
    StripPerturbation p;
    const size_t idx = std::min(kap.size() - 1, static_cast<size_t>(std::floor((1 - f) * kap.size())));
    p.curvature_limit = std::max(kap[idx], 1e-12);
    p.plastic_hardening = ro.plastic_hardening;
    todo.push_back({"plastic_top_" + std::to_string(std::lround(100 * f)) + "%", p});
  }
  StripRobustness out;
  for (const auto& [name, p] : todo) {
    StripValidationOptions v = ro.validation;
    v.perturbation = p;
    const StripValidation val = validate_strip(curve, design, o, v);
    StripRobustnessCase c;
    c.name = name;
    c.perturbation = p;
    c.converged = val.converged;
    c.deviation = val.deviation;
    c.max_distance = val.max_distance;
    c.message = val.message;
    c.nodes = val.simulation.nodes;
    if (c.converged && c.deviation > out.worst_deviation) out.worst_deviation = c.deviation, out.worst_case = name;
    out.cases.push_back(c);
  }
  out.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return out;
}

}  // namespace parafab
