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

namespace {
// Sections every p/64 over [s0, s1]: the material width against w_K pointwise, and the
// harmonic means over windows of one pitch (the bending compliance of sections in series).
void deviation_report(PerforatedStripResult& r, const std::vector<double>& s,
                      const std::vector<double>& w, const std::vector<double>& wk) {
  const double s0 = s.front(), s1 = s.back(), p = r.pitch;
  const int n = std::max(64, static_cast<int>(std::ceil(64 * (s1 - s0) / p)));
  const double ds = (s1 - s0) / n;
  auto inside = [&](double x) { return x >= r.perforated_from && x <= r.perforated_to; };
  std::vector<double> at(n + 1), inv_mat(n + 1), inv_des(n + 1);
  size_t first = 0;  // diamonds are sorted by s
  for (int i = 0; i <= n; ++i) {
    at[i] = s0 + ds * i;
    while (first < r.diamonds.size() && r.diamonds[first].s + 0.5 * r.diamonds[first].length <= at[i]) ++first;
    double holes = 0;
    for (size_t k = first; k < r.diamonds.size() && r.diamonds[k].s - 0.5 * r.diamonds[k].length < at[i]; ++k) {
      const double t = std::abs(at[i] - r.diamonds[k].s);
      if (t < 0.5 * r.diamonds[k].length) holes += r.diamonds[k].width * (1 - 2 * t / r.diamonds[k].length);
    }
    const double need = lerp(s, wk, at[i]), mat = lerp(s, w, at[i]) - holes;
    inv_mat[i] = 1 / mat;
    inv_des[i] = 1 / need;
    const double dev = std::abs(mat / need - 1);
    if (dev > r.max_width_deviation) r.max_width_deviation = dev, r.max_width_deviation_s = at[i];
    if (holes == 0) r.end_zone_deviation = std::max(r.end_zone_deviation, mat / need - 1);
    if (inside(at[i]) && dev > r.interior_width_deviation)
      r.interior_width_deviation = dev, r.interior_width_deviation_s = at[i];
  }
  const int win = std::min(n, std::max(2, static_cast<int>(std::round(p / ds))));
  for (int i = 0; i + win <= n; ++i) {
    double cm = 0, cd = 0;  // trapezoidal ∫ 1/w over the window
    for (int k = i; k < i + win; ++k)
      cm += 0.5 * (inv_mat[k] + inv_mat[k + 1]), cd += 0.5 * (inv_des[k] + inv_des[k + 1]);
    const double dev = std::abs(cd / cm - 1);  // K_eff/K_design = (p/∫1/w_mat)/(p/∫1/w_K)
    if (dev > r.max_stiffness_deviation)
      r.max_stiffness_deviation = dev, r.max_stiffness_deviation_s = at[i] + 0.5 * win * ds;
    if (inside(at[i]) && inside(at[i + win]) && dev > r.interior_stiffness_deviation)
      r.interior_stiffness_deviation = dev, r.interior_stiffness_deviation_s = at[i] + 0.5 * win * ds;
  }
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
  deviation_report(r, s, w, wk);
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
