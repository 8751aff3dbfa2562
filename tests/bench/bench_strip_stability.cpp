// Benchmark of the strip stability tests (thesis §4.5): per strip, the Jacobi test (Eq. 4.7,
// O(N) recurrence on the design, including the discretization of the curve) against the
// constrained eigenvalue test (simulation of the designed K to its equilibrium, then the
// Hessian inertia on the constraint tangent space, dense O(N³)), medians over repeats, and
// whether the verdicts agree. Curves: the strip test curves and inflectional elastica
// (stable and unstable). Goal (issue 13): the verdict in ≤ 5 ms per strip.
//   bench_strip_stability [--quick] [--out DIR]   → DIR/strip_stability.json (then
//   plot_strip_stability.py DIR → DIR/strip_stability.png)
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "strips/jacobi_stability.h"
#include "strips/strip_validation.h"
#include "../solvers/strips/strip_test_curves.h"
#include "../solvers/strips/strip_stability_curves.h"
#include "bench_output.h"

using namespace parafab;
using Clock = std::chrono::steady_clock;

namespace {
double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v[v.size() / 2];
}
}  // namespace

int main(int argc, char** argv) {
  bool quick = false;
  std::string out_dir = ".";
  for (int i = 1; i < argc; ++i) {
    if (!std::strcmp(argv[i], "--quick")) quick = true;
    else if (!std::strcmp(argv[i], "--out") && i + 1 < argc) out_dir = argv[++i];
  }
  const int repeats = quick ? 3 : 21;
  const std::vector<int> sim_edges = quick ? std::vector<int>{200} : std::vector<int>{200, 400, 800};
  const int jacobi_edges = 800;
  nlohmann::json rows = nlohmann::json::array();
  for (const auto& tc : test::stability_curves()) {
    const StripDesign d = design_strip(tc.curve, tc.options);
    if (!d.feasible) continue;
    StripStabilityOptions so;
    so.edges = jacobi_edges;
    std::vector<double> tj;
    StripStability st;
    for (int r = 0; r < repeats; ++r) {
      const auto t0 = Clock::now();
      st = strip_stability(tc.curve, d, tc.options, so);
      tj.push_back(std::chrono::duration<double>(Clock::now() - t0).count());
    }
    nlohmann::json eig = nlohmann::json::array();
    for (int n : sim_edges) {
      StripStabilityOptions se = so;
      se.eigenvalue_check = true;
      se.simulation.edges = n;
      std::vector<double> tsim, teig;
      StripStability sc;
      for (int r = 0; r < std::max(1, repeats / 4); ++r) {
        sc = strip_stability(tc.curve, d, tc.options, se);
        tsim.push_back(sc.simulation_seconds);
        teig.push_back(sc.eigen_seconds);
      }
      eig.push_back({{"edges", n}, {"converged", sc.simulation_converged}, {"stable", sc.inertia.stable},
                     {"negative", sc.inertia.negative}, {"agree", sc.agree},
                     {"simulation_ms", 1e3 * median(tsim)}, {"inertia_ms", 1e3 * median(teig)},
                     {"total_ms", 1e3 * (median(tsim) + median(teig))}});
      std::printf("%-34s N=%4d jacobi %s sigma/l %-8.4g %.3f ms | eigen(%d) %s sim %.2f ms inertia %.2f ms agree %d\n",
                  tc.name.c_str(), jacobi_edges, st.stable ? "stable  " : "UNSTABLE", st.sigma / d.length,
                  1e3 * median(tj), n, sc.inertia.stable ? "stable  " : "UNSTABLE", 1e3 * median(tsim),
                  1e3 * median(teig), sc.agree);
    }
    rows.push_back({{"name", tc.name}, {"R", d.R}, {"length", d.length}, {"stable", st.stable},
                    {"sigma", std::isfinite(st.sigma) ? nlohmann::json(st.sigma) : nlohmann::json(nullptr)},
                    {"jacobi_edges", jacobi_edges}, {"jacobi_ms", 1e3 * median(tj)}, {"eigen", eig}});
  }
  const std::string path =
      write_bench_file(out_dir, "strip_stability.json", nlohmann::json{{"repeats", repeats}, {"strips", rows}}.dump(2) + "\n");
  std::printf("wrote %s\n", path.c_str());
  return 0;
}
