// Benchmark of a pavilion-like scene (thesis §4.8.1, Fig. 4.17): 31 cardboard strips, each an
// ellipse segment rotated about its centre, designed under gravity (LP Eq. 4.6 with the
// smoothing phase of §4.4.3), each at the sample count its tolerance on R needs (nested
// grids). Reports the median wall time of the whole scene over repeats (one core), per-strip
// sample counts, R, LP times, the median time per phase (StripDesign::phases), and the
// deviation of each strip simulated back (not timed). The scene through design_strips on
// `--threads` TBB workers (default 2) is timed in the same run against the serial loop
// (the baseline), and its results are checked bit-identical.
//   bench_strip_scene [--quick] [--repeats N] [--threads T] [--out DIR]   → DIR/strip_scene.json
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <ctime>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "strips/strip_design.h"
#include "strips/strip_validation.h"
#include "bench_output.h"

using namespace parafab;

namespace {

// Strip i of n: ellipse 0.17 × 0.12 m, segment t ∈ [0.35, π − 0.35], rotated about its
// centre by φ_i ∈ [−0.35, 0.35] rad (the corkscrew of the pavilion). Exact rational quadratic
// NURBS in 4 pieces (as a CAD system stores an elliptic arc), or, with `interpolated`, a
// quintic through 201 points of it (200 spans: the arc-length table then dominates).
BSplineCurve2 strip_curve(int i, int n, bool interpolated) {
  const double phi = -0.35 + 0.7 * i / (n - 1), c = std::cos(phi), s = std::sin(phi);
  auto rot = [&](const Vec2& p) { return Vec2(c * p.x() - s * p.y(), s * p.x() + c * p.y()); };
  const double ax = 0.17, ay = 0.12, t0 = 0.35, t1 = M_PI - 0.35;
  if (interpolated) {
    std::vector<Vec2> pts;
    for (int k = 0; k <= 200; ++k) {
      const double t = t0 + (t1 - t0) * k / 200;
      pts.push_back(rot(Vec2(ax * std::cos(t), ay * std::sin(t))));
    }
    return interpolate_points(pts, 5);
  }
  const int pieces = 4;
  const double dt = (t1 - t0) / pieces, w = std::cos(dt / 2);
  std::vector<Vec2> poles;
  std::vector<double> weights, knots{0, 0, 0};
  for (int k = 0; k < pieces; ++k) {
    const double ta = t0 + k * dt, tm = ta + dt / 2, tb = ta + dt;
    if (k == 0) poles.push_back(rot(Vec2(ax * std::cos(ta), ay * std::sin(ta)))), weights.push_back(1);
    poles.push_back(rot(Vec2(ax * std::cos(tm) / w, ay * std::sin(tm) / w)));
    weights.push_back(w);
    poles.push_back(rot(Vec2(ax * std::cos(tb), ay * std::sin(tb))));
    weights.push_back(1);
    if (k + 1 < pieces) knots.push_back(k + 1), knots.push_back(k + 1);
  }
  knots.insert(knots.end(), {double(pieces), double(pieces), double(pieces)});
  return BSplineCurve2(2, knots, poles, weights);
}

double median(std::vector<double> v) {
  std::nth_element(v.begin(), v.begin() + v.size() / 2, v.end());
  return v[v.size() / 2];
}

}  // namespace

int main(int argc, char** argv) {
  bool quick = false;
  int repeats = 11, threads = 2;
  std::string out_dir = ".";
  for (int i = 1; i < argc; ++i) {
    if (!std::strcmp(argv[i], "--quick")) quick = true;
    else if (!std::strcmp(argv[i], "--out") && i + 1 < argc) out_dir = argv[++i];
    else if (!std::strcmp(argv[i], "--repeats") && i + 1 < argc) repeats = std::atoi(argv[++i]);
    else if (!std::strcmp(argv[i], "--threads") && i + 1 < argc) threads = std::atoi(argv[++i]);
    else {
      std::fprintf(stderr, "usage: bench_strip_scene [--quick] [--repeats N] [--threads T] [--out DIR]\n");
      return 2;
    }
  }
  if (quick) repeats = 3;
  const int n = 31;
  std::vector<BSplineCurve2> curves, interpolated;
  for (int i = 0; i < n; ++i) curves.push_back(strip_curve(i, n, false)), interpolated.push_back(strip_curve(i, n, true));
  StripDesignOptions o;
  o.gravity.enabled = true;  // 200 gsm cardboard, βl³ = 8.86e-4 m³
  o.load_tolerance = 1e-4;
  o.initial_samples = 32;
  // Wall time and process CPU time (the machine may be shared: CPU time is what one core
  // spends on the scene).
  std::vector<double> scene, scene_cpu, scene_par;
  std::vector<StripDesign> designs(n), par;
  const char* phase_names[] = {"curve", "zeros", "check", "sampling", "lp", "ratio", "outputs"};
  std::vector<std::vector<double>> phase(7);  // per repeat: summed over the scene
  for (int r = 0; r < repeats; ++r) {
    const std::clock_t c0 = std::clock();
    const auto t0 = std::chrono::steady_clock::now();
    for (int i = 0; i < n; ++i) designs[i] = design_strip(curves[i], o);
    scene.push_back(std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
    scene_cpu.push_back(double(std::clock() - c0) / CLOCKS_PER_SEC);
    std::vector<double> sum(7, 0.0);
    for (const auto& d : designs) {
      const auto& p = d.phases;
      const double v[] = {p.curve, p.zeros, p.check, p.sampling, p.lp, p.ratio, p.outputs};
      for (int k = 0; k < 7; ++k) sum[k] += v[k];
    }
    for (int k = 0; k < 7; ++k) phase[k].push_back(sum[k]);
    // The same scene over TBB workers (interleaved with the serial baseline).
    const auto t1 = std::chrono::steady_clock::now();
    par = design_strips(curves, o, threads);
    scene_par.push_back(std::chrono::duration<double>(std::chrono::steady_clock::now() - t1).count());
  }
  bool identical = par.size() == designs.size();
  for (size_t i = 0; identical && i < par.size(); ++i) {
    identical = par[i].feasible == designs[i].feasible && par[i].R == designs[i].R &&
                par[i].samples.size() == designs[i].samples.size();
    for (size_t k = 0; identical && k < par[i].samples.size(); ++k)
      identical = par[i].samples[k].K == designs[i].samples[k].K && par[i].samples[k].s == designs[i].samples[k].s;
  }
  // Cold starts of every LP (StripDesignOptions::warm_start = false; the default warm-starts
  // each grid from the coarser one): time against the serial loop of the same run, and how
  // far R and K move.
  StripDesignOptions ow = o;
  ow.warm_start = false;
  std::vector<double> scene_warm;
  double warm_R_difference = 0;
  for (int r = 0; r < repeats; ++r) {
    const auto t1 = std::chrono::steady_clock::now();
    const std::vector<StripDesign> warm = design_strips(curves, ow, 1);
    scene_warm.push_back(std::chrono::duration<double>(std::chrono::steady_clock::now() - t1).count());
    for (int i = 0; i < n; ++i)
      if (warm[i].feasible && designs[i].feasible) {
        warm_R_difference = std::max(warm_R_difference, std::abs(warm[i].R / designs[i].R - 1));
        for (size_t k = 0; k < warm[i].samples.size() && k < designs[i].samples.size(); ++k)
          warm_R_difference = std::max(warm_R_difference, std::abs(warm[i].samples[k].K / designs[i].samples[k].K - 1));
      }
  }
  nlohmann::json phases_json;
  for (int k = 0; k < 7; ++k) phases_json[phase_names[k]] = median(phase[k]);
  // The same scene from interpolated quintics (for comparison; fewer repeats).
  std::vector<double> scene_interp;
  double max_R_difference = 0;
  for (int r = 0; r < std::max(1, repeats / 3); ++r) {
    const auto t0 = std::chrono::steady_clock::now();
    for (int i = 0; i < n; ++i) {
      const StripDesign d = design_strip(interpolated[i], o);
      if (d.feasible && designs[i].feasible)
        max_R_difference = std::max(max_R_difference, std::abs(d.R_first / designs[i].R_first - 1));
    }
    scene_interp.push_back(std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
  }
  nlohmann::json strips = nlohmann::json::array();
  int feasible = 0;
  double worst_dev = 0;
  for (int i = 0; i < n; ++i) {
    const StripDesign& d = designs[i];
    nlohmann::json row{{"index", i}, {"feasible", d.feasible}, {"length", d.length},
                       {"samples", d.lp_samples}, {"converged", d.converged},
                       {"total_seconds", d.total_seconds}, {"lp_seconds", d.lp_seconds},
                       {"smoothing_seconds", d.lp_seconds_second}};
    if (d.feasible) {
      ++feasible;
      StripValidationOptions v;
      v.rod.edges = quick ? 200 : 400;
      const StripValidation val = validate_strip(curves[i], d, o, v);
      worst_dev = std::max(worst_dev, val.deviation);
      row["R"] = d.R;
      row["R_first"] = d.R_first;
      row["smoothed"] = d.smoothed;
      row["deviation"] = val.deviation;
      row["simulation_converged"] = val.converged;
    } else {
      row["reason"] = d.reason;
    }
    strips.push_back(row);
  }
  nlohmann::json out{{"benchmark", "strip_scene"},
                     {"strips", n},
                     {"repeats", repeats},
                     {"load_tolerance", o.load_tolerance},
                     {"scene_seconds_median", median(scene)},
                     {"scene_seconds_min", *std::min_element(scene.begin(), scene.end())},
                     {"scene_cpu_seconds_median", median(scene_cpu)},
                     {"phases_seconds_median", phases_json},
                     {"threads", threads},
                     {"parallel_scene_seconds_median", median(scene_par)},
                     {"parallel_speedup", median(scene) / median(scene_par)},
                     {"parallel_identical", identical},
                     {"cold_start_scene_seconds_median", median(scene_warm)},
                     {"cold_start_max_relative_R_K_difference", warm_R_difference},
                     {"curves", "exact rational quadratic NURBS, 4 pieces"},
                     {"interpolated_scene_seconds_median", median(scene_interp)},
                     {"interpolated_max_relative_R_difference", max_R_difference},
                     {"feasible", feasible},
                     {"worst_deviation", worst_dev},
                     {"per_strip", strips}};
  const std::string path = write_bench_file(out_dir, "strip_scene.json", out.dump(2) + "\n");
  std::printf("strip scene: %d/%d feasible, median %.1f ms wall (min %.1f) / %.1f ms CPU for the scene (%d repeats), worst "
              "simulated deviation %.2g; from interpolated quintics %.1f ms (R within %.1g) -> %s\n",
              feasible, n, 1e3 * median(scene), 1e3 * *std::min_element(scene.begin(), scene.end()), 1e3 * median(scene_cpu), repeats, worst_dev, 1e3 * median(scene_interp),
              max_R_difference, path.c_str());
  std::printf("  phases [ms, scene]:");
  for (int k = 0; k < 7; ++k) std::printf(" %s %.2f", phase_names[k], 1e3 * median(phase[k]));
  std::printf("\n  design_strips on %d threads: %.1f ms (%.2fx the serial loop), results %s\n", threads,
              1e3 * median(scene_par), median(scene) / median(scene_par), identical ? "identical" : "DIFFER");
  std::printf("  cold-started LPs (warm_start = false), one thread: %.1f ms (the warm-started serial loop is %.2fx faster), R and K within %.2g\n",
              1e3 * median(scene_warm), median(scene_warm) / median(scene), warm_R_difference);
  return feasible == n && identical ? 0 : 1;
}
