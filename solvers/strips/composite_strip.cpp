#include "strips/composite_strip.h"

#include <algorithm>
#include <cmath>
#include <sstream>

#include "common/error.h"

namespace parafab {

CompositeStripResult design_composite_strip(const std::vector<double>& s,
                                            const std::vector<double>& K,
                                            const std::vector<double>& w1,
                                            const CompositeStripOptions& o) {
  PARAFAB_VERIFY(!s.empty() && s.size() == K.size() && s.size() == w1.size(),
                 "composite strip: s, stiffness and outer_width need equal non-zero lengths, got "
                     << s.size() << ", " << K.size() << ", " << w1.size());
  PARAFAB_VERIFY(std::isfinite(o.outer_thickness) && o.outer_thickness > 0,
                 "composite.outer_thickness must be positive (metres), got " << o.outer_thickness);
  PARAFAB_VERIFY(std::isfinite(o.inner_thickness) && o.inner_thickness > 0,
                 "composite.inner_thickness must be positive (metres), got " << o.inner_thickness);
  for (size_t i = 0; i < s.size(); ++i) {
    PARAFAB_VERIFY(std::isfinite(K[i]) && K[i] > 0, "composite: stiffness[" << i << "] must be positive, got " << K[i]);
    PARAFAB_VERIFY(std::isfinite(w1[i]) && w1[i] > 0, "composite: outer_width[" << i << "] must be positive, got " << w1[i]);
  }
  const double h1 = o.outer_thickness, h2 = o.inner_thickness;
  const double P1 = h1 * h1 * h1, P12 = std::pow(h1 + h2, 3), P2 = P12 - P1;
  CompositeStripResult r;
  double qmin = INFINITY, qmax = 0;  // w₁/K
  size_t imax = 0;
  for (size_t i = 0; i < s.size(); ++i) {
    const double q = w1[i] / K[i];
    if (q > qmax) qmax = q, imax = i;
    qmin = std::min(qmin, q);
  }
  r.max_c_min = P1 * qmax;
  r.min_c_max = P12 * qmin;
  r.worst_s = s[imax];
  const double t = std::cbrt(qmin / qmax);
  r.max_thickness_ratio = t >= 1 ? INFINITY : t / (1 - t);
  if (!(r.max_c_min <= r.min_c_max)) {
    std::ostringstream os;
    os << "no narrow strip fits inside the broad one: at s = " << r.worst_s
       << " the broad strip alone is already too stiff relative to the rest (max c_min = "
       << r.max_c_min << " > min c_max = " << r.min_c_max << "); h₁/h₂ = " << h1 / h2
       << " must be at most " << r.max_thickness_ratio << " (or widen w₁ elsewhere)";
    r.message = os.str();
    return r;
  }
  r.feasible = true;
  r.scale = r.min_c_max;
  r.inner_width.resize(s.size());
  for (size_t i = 0; i < s.size(); ++i)
    r.inner_width[i] = std::clamp((r.scale * K[i] - P1 * w1[i]) / P2, 0.0, w1[i]);
  return r;
}

}  // namespace parafab
