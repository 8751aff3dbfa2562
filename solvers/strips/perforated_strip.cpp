#include "strips/perforated_strip.h"

#include <algorithm>
#include <cmath>
#include <sstream>

#include "common/error.h"

namespace parafab {

std::array<Vec2, 4> Diamond::corners() const {
  return {Vec2(s - 0.5 * length, offset), Vec2(s, offset - 0.5 * width),
          Vec2(s + 0.5 * length, offset), Vec2(s, offset + 0.5 * width)};
}

namespace {
double lerp(const std::vector<double>& xs, const std::vector<double>& ys, double x) {
  if (x <= xs.front()) return ys.front();
  if (x >= xs.back()) return ys.back();
  const size_t i = static_cast<size_t>(std::upper_bound(xs.begin(), xs.end(), x) - xs.begin());
  const double t = (x - xs[i - 1]) / (xs[i] - xs[i - 1]);
  return ys[i - 1] + t * (ys[i] - ys[i - 1]);
}
}  // namespace

PerforatedStripResult design_perforated_strip(const std::vector<double>& s,
                                              const std::vector<double>& w,
                                              const std::vector<double>& wk,
                                              const PerforatedStripOptions& o) {
  PARAFAB_VERIFY(s.size() >= 2 && s.size() == w.size() && s.size() == wk.size(),
                 "perforated strip: s, outer_width and solid_width need equal lengths >= 2, got "
                     << s.size() << ", " << w.size() << ", " << wk.size());
  PARAFAB_VERIFY(o.min_ligament > 0, "perforation.min_ligament must be positive, got " << o.min_ligament);
  PARAFAB_VERIFY(o.cell_aspect > 0, "perforation.cell_aspect must be positive, got " << o.cell_aspect);
  PARAFAB_VERIFY(o.columns == 0 || o.columns >= 2, "perforation.columns must be 0 or >= 2, got " << o.columns);
  for (size_t i = 0; i < s.size(); ++i) {
    PARAFAB_VERIFY(i == 0 || s[i] > s[i - 1], "perforated strip: s must increase; s[" << i << "] = " << s[i]);
    PARAFAB_VERIFY(std::isfinite(w[i]) && w[i] > 0, "perforated strip: outer_width[" << i << "] must be positive, got " << w[i]);
    PARAFAB_VERIFY(std::isfinite(wk[i]) && wk[i] > 0, "perforated strip: solid_width[" << i << "] must be positive, got " << wk[i]);
  }
  PerforatedStripResult r;
  for (size_t i = 0; i < s.size(); ++i) {
    if (wk[i] > w[i] * (1 + 1e-12)) {
      std::ostringstream os;
      os << "the stiffness needs a solid width of " << wk[i] << " m at s = " << s[i]
         << ", more than the outer width " << w[i] << " m";
      r.worst_s = s[i];
      r.message = os.str();
      return r;
    }
  }
  // Column count: across any section the gap between neighbouring holes is at least
  // (c − max(D_A, D_B))/2 and to the edge (c − D_A)/2, so D_B = H/(m − 1) ≤ c − 2·ligament.
  const double lig = o.min_ligament;
  auto fits = [&](int m, size_t& bad) {
    for (size_t i = 0; i < s.size(); ++i) {
      const double H = w[i] - wk[i], c = w[i] / m;
      if (H / (m - 1) > c - 2 * lig) { bad = i; return false; }
    }
    return true;
  };
  size_t bad = 0;
  int m = o.columns;
  if (m == 0) {
    for (int k = 2; k <= o.max_columns && m == 0; ++k)
      if (fits(k, bad)) m = k;
    if (m == 0) {
      std::ostringstream os;
      os << "no column count up to " << o.max_columns << " leaves strands of " << lig
         << " m: at s = " << s[bad] << " holes of " << w[bad] - wk[bad] << " m must fit into "
         << w[bad] << " m";
      r.worst_s = s[bad];
      r.message = os.str();
      return r;
    }
  } else if (!fits(m, bad)) {
    std::ostringstream os;
    os << m << " columns leave strands thinner than " << lig << " m at s = " << s[bad];
    r.worst_s = s[bad];
    r.message = os.str();
    return r;
  }
  double wmean = 0;
  for (size_t i = 0; i + 1 < s.size(); ++i) wmean += 0.5 * (w[i] + w[i + 1]) * (s[i + 1] - s[i]);
  wmean /= s.back() - s.front();
  const double p = o.cell_aspect * wmean / m;
  r.columns = m;
  r.pitch = p;
  // Rows every p/2, A rows first, centred in [s0 + p/2, s1 − p/2].
  const double L = s.back() - s.front();
  const int rows = static_cast<int>(std::floor((L - p) / (0.5 * p))) + 1;
  if (rows < 2) {
    r.message = "the strip is shorter than two rows of diamonds; lower cell_aspect";
    return r;
  }
  const double first = s.front() + 0.5 * (L - 0.5 * p * (rows - 1));
  for (int j = 0; j < rows; ++j) {
    const double sj = first + 0.5 * p * j;
    const double wj = lerp(s, w, sj), H = wj - lerp(s, wk, sj), c = wj / m;
    const bool typeA = j % 2 == 0;
    const int count = typeA ? m : m - 1;
    const double D = H / count;
    if (D <= 0) continue;
    for (int k = 0; k < count; ++k) {
      const double off = typeA ? (k + 0.5) * c - 0.5 * wj : (k + 1) * c - 0.5 * wj;
      r.diamonds.push_back({sj, off, p, D});
    }
  }
  r.perforated_from = first;
  r.perforated_to = first + 0.5 * p * (rows - 1);
  r.feasible = true;
  return r;
}

double perforated_material_width(const PerforatedStripResult& strip, const std::vector<double>& s,
                                 const std::vector<double>& w, double at) {
  double holes = 0;
  for (const auto& d : strip.diamonds) {
    const double t = std::abs(at - d.s);
    if (t < 0.5 * d.length) holes += d.width * (1 - 2 * t / d.length);
  }
  return lerp(s, w, at) - holes;
}

}  // namespace parafab
