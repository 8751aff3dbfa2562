// Benchmark of Kirchhoff rod design (thesis §5.7–5.8, timings of §5.9.2: LP ≈ 5 ms and
// geometry ≈ 6 ms at 400 samples, ≈ 6 ms per dead-load iteration): the three segments of the
// light sculpture (§5.9.5) at 0.2 m per unit, SmoothSil 960, 25 mm largest mean radius,
// designed under dead load. Per curve and sample count: sampling, LP (Eq. 5.19 + stiffness-
// ratio stage), geometry (§5.7.3) and dead-load fixed point (§5.8.2) timed separately
// (medians over repeats; total = sampling + design), and the deviation of a forward
// simulation (discrete elastic rod, 200 edges, with gravity) from the target curve relative
// to the length, also with 1e4× stretching stiffness (inextensible limit).
//   bench_rod [--quick] [--out DIR]   → DIR/rod.json
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "rods/rod_design.h"
#include "../solvers/rods/rod_test_curves.h"
#include "bench_output.h"

using namespace parafab;

namespace {

// The thesis's light-sculpture curve (scaled 0.2 m), segment k of three (as the rod tests).
SpaceCurve light_sculpture_segment(int k) {
  return rod_test::light_sculpture(0.2, k * 4 * M_PI / 3, (k + 1) * 4 * M_PI / 3);
}

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
    else {
      std::fprintf(stderr, "usage: bench_rod [--quick] [--out DIR]\n");
      return 2;
    }
  }
  const std::vector<int> counts = quick ? std::vector<int>{100, 400} : std::vector<int>{100, 200, 400, 800, 1600, 3200};
  const int repeats = quick ? 3 : 21, edges = quick ? 50 : 200;
  RodDesignOptions o;
  o.material = RodMaterial::smooth_sil_960();
  o.max_radius = 0.025;
  o.loads.dead_load = true;
  nlohmann::json curves = nlohmann::json::array();
  int status = 0;
  std::printf("%7s %7s %9s %9s %9s %11s %5s %9s %11s %11s\n", "segment", "samples", "sample ms", "LP ms",
              "geom ms", "deadload ms", "iter", "total ms", "deviation/L", "dev/L inext");
  for (int k = 0; k < 3; ++k) {
    const SpaceCurve curve = light_sculpture_segment(k);
    nlohmann::json rows = nlohmann::json::array();
    for (int n : counts) {
      std::vector<double> ts, tl, tg, td, tt;
      RodDesign d;
      for (int r = 0; r < repeats; ++r) {
        const auto t0 = std::chrono::steady_clock::now();
        const std::vector<RodSample> samples = sample_by_arc_length(curve, n);
        require_frenet_curve(curve, samples);
        const double sampling = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
        d = design_rod(samples, o);
        ts.push_back(sampling);
        tl.push_back(d.lp_seconds), tg.push_back(d.geometry_seconds), td.push_back(d.dead_load_seconds);
        tt.push_back(sampling + d.total_seconds);
      }
      if (!d.ok()) {
        std::fprintf(stderr, "segment %d, %d samples: %s\n", k, n, d.message.c_str());
        status = 1;
        continue;
      }
      const DiscreteRodModel m = discrete_rod_model(d, curve, edges, o.material, o.loads, true);
      const DiscreteRodResult sim = simulate_discrete_rod(m);
      const double dev = max_node_distance(sim.nodes, m.nodes) / curve.length();
      // The same with 1e4× stretching stiffness: removes the extension of the simulated rod
      // (Kirchhoff rods are inextensible), leaving design + discretization error.
      DiscreteRodModel stiff = m;
      for (double& ks : stiff.stretching_stiffness) ks *= 1e4;
      const DiscreteRodResult sim_stiff = simulate_discrete_rod(stiff);
      const double dev_stiff = max_node_distance(sim_stiff.nodes, m.nodes) / curve.length();
      const double total_ms = 1e3 * median(tt);
      std::printf("%7d %7d %9.3f %9.3f %9.3f %11.3f %5d %9.3f %11.2e %11.2e%s\n", k, n, 1e3 * median(ts),
                  1e3 * median(tl), 1e3 * median(tg), 1e3 * median(td), d.fixed_point_iterations,
                  total_ms, dev, dev_stiff, sim.ok() && sim_stiff.ok() ? "" : " (simulation not converged)");
      rows.push_back({{"samples", n},
                      {"repeats", repeats},
                      {"sampling_seconds", median(ts)},
                      {"lp_seconds", median(tl)},
                      {"lp_count", d.lp.lps_solved},
                      {"lp_iterations", d.lp.iterations},
                      {"geometry_seconds", median(tg)},
                      {"dead_load_seconds", median(td)},
                      {"dead_load_iterations", d.fixed_point_iterations},
                      {"dead_load_seconds_per_iteration", median(td) / std::max(1, d.fixed_point_iterations)},
                      {"dead_load_history", d.fixed_point_history},
                      {"total_seconds", median(tt)},
                      {"twist_ratio", d.lp.twist_ratio},
                      {"stiffness_ratio", d.lp.stiffness_ratio},
                      {"simulation_edges", edges},
                      {"simulation_converged", sim.ok()},
                      {"simulation_seconds", sim.seconds},
                      {"deviation_over_length", dev},
                      {"deviation_over_length_inextensible", dev_stiff}});
    }
    curves.push_back({{"segment", k}, {"length", curve.length()}, {"rows", rows}});
  }
  nlohmann::json out{{"benchmark", "rod_design"},
                     {"curve", "light sculpture (thesis 5.9.5), 0.2 m per unit, 3 segments"},
                     {"material", "SmoothSil 960: E = 2.3 MPa, nu = 0.48, rho = 1250 kg/m^3"},
                     {"max_radius", o.max_radius},
                     {"goal_seconds_at_400", 0.010},
                     {"curves", curves}};
  const std::string path = write_bench_file(out_dir, "rod.json", out.dump(2) + "\n");
  std::printf("wrote %s\n", path.c_str());
  return status;
}
