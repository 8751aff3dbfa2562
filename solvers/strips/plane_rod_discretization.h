// Shared pieces of the discrete plane rod of thesis §4.6.1, used by the forward simulator
// (plane_rod_simulator), the energy-decreasing release (plane_rod_release) and the Jacobi test
// (jacobi_stability): piecewise-linear resampling of a field given at arc lengths, and how the
// end conditions reference node positions to the clamped ends (the gravity weights Q).
#pragma once

#include <algorithm>
#include <vector>

#include "strips/strip_model.h"

namespace parafab::plane_rod {

/// ys at x, piecewise linear through (xs, ys) (xs increasing), constant beyond the ends.
inline double interpolate(const std::vector<double>& xs, const std::vector<double>& ys, double x) {
  if (x <= xs.front()) return ys.front();
  if (x >= xs.back()) return ys.back();
  const size_t i = static_cast<size_t>(std::upper_bound(xs.begin(), xs.end(), x) - xs.begin());
  const double t = (x - xs[i - 1]) / (xs[i] - xs[i - 1]);
  return ys[i - 1] + t * (ys[i] - ys[i - 1]);
}

/// Per coordinate d: whether both ends fix it (the end-to-end vector is a constraint), whether
/// node positions are referenced to the start (else to the end), and Q[d][j], the load weight of
/// the nodes whose position moves with edge j: the sum of weight·w after edge j (referenced to
/// the start) or minus the sum before it (referenced to the end). N edges, N + 1 nodes.
struct EndReferences {
  bool constrained[2] = {true, true};
  bool ref_start[2] = {true, true};
  std::vector<double> Q[2];
};

inline EndReferences end_references(const StripBoundary& boundary, const std::vector<double>& weight,
                                    const std::vector<double>& w, int N) {
  EndReferences r;
  const bool sfree[2] = {boundary.start.free_x, boundary.start.free_y};
  const bool efree[2] = {boundary.end.free_x, boundary.end.free_y};
  for (int d = 0; d < 2; ++d) {
    r.constrained[d] = !sfree[d] && !efree[d];
    r.ref_start[d] = !sfree[d] || efree[d];
    r.Q[d].assign(N, 0.0);
    double acc = 0;
    if (r.ref_start[d]) {
      for (int j = N - 1; j >= 0; --j) acc += weight[j + 1] * w[j + 1], r.Q[d][j] = acc;
    } else {
      for (int j = 0; j < N; ++j) acc += weight[j] * w[j], r.Q[d][j] = -acc;
    }
  }
  return r;
}

}  // namespace parafab::plane_rod
