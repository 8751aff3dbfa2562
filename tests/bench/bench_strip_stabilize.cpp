// Benchmark of stability recovery (thesis §4.5.4, Algorithm 4.2; issue goal ≤ 0.25 s per
// curve). The set: clamped sine waves y = A sin(x/c) over x/c ∈ [−1, φ_end] (three collinear
// inflections), amplitudes A/c ∈ {0.4, 0.6, 0.8} and ends φ_end ∈ {2π + 0.4, 2π + 0.8,
// 2π + 1.2, 2π + 1.6}, each a quintic fair fit with 16 poles whose inflections are made
// collinear (EnforceConstraints, App. A.4). Unstable ones are stabilized (R_max 10, margin 5 %);
// stable ones are reported as such. Per curve: the median wall time of stabilize_strip over
// repeats, the status, σ/l before, R before/after, the max pole move and the curve deviation
// (relative to the length), and the σ history against time; as the baseline measured in the
// same run, one strip_stability (design + Jacobi test) of the curve.
//   bench_strip_stabilize [--quick] [--repeats N] [--out DIR]   → DIR/strip_stabilize.json
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "strips/curve_fairing.h"
#include "strips/jacobi_stability.h"
#include "strips/strip_stabilize.h"
#include "bench_output.h"

using namespace parafab;
using Clock = std::chrono::steady_clock;

namespace {
double since(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }
double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v[v.size() / 2];
}
BSplineCurve2 wave(double amp, double phi_end) {
  const double c = 0.05;
  std::vector<Vec2> pts;
  for (int i = 0; i < 400; ++i) {
    const double x = c * (-1 + (phi_end + 1) * i / 399);
    pts.emplace_back(x, amp * c * std::sin(x / c));
  }
  FairFitOptions fo;
  fo.degree = 5;
  fo.poles = 16;
  fo.fairness = 1e-8;
  BSplineCurve2 b = fit_fair_bspline(pts, fo).curve;
  project_to_equilibrium(b);
  return b;
}
nlohmann::json num(double x) { return std::isfinite(x) ? nlohmann::json(x) : nlohmann::json(nullptr); }
}  // namespace

int main(int argc, char** argv) {
  bool quick = false;
  int repeats = 5;
  std::string out_dir = ".";
  for (int i = 1; i < argc; ++i) {
    if (!std::strcmp(argv[i], "--quick")) quick = true;
    else if (!std::strcmp(argv[i], "--out") && i + 1 < argc) out_dir = argv[++i];
    else if (!std::strcmp(argv[i], "--repeats") && i + 1 < argc) repeats = std::atoi(argv[++i]);
    else {
      std::fprintf(stderr, "usage: bench_strip_stabilize [--quick] [--repeats N] [--out DIR]\n");
      return 2;
    }
  }
  if (quick) repeats = 1;
  std::vector<double> amps = {0.4, 0.6, 0.8}, ends = {0.4, 0.8, 1.2, 1.6};
  if (quick) amps = {0.6}, ends = {0.4, 0.8};
  nlohmann::json curves = nlohmann::json::array();
  std::vector<double> times, ratios;
  int index = 0, unstable = 0, stabilized = 0;
  std::printf("%-5s %-5s %-6s %-9s %-8s %-7s %-7s %-9s %-9s %-9s %-9s\n", "curve", "A/c", "end", "sigma/l", "status",
              "R0", "R1", "move/l", "dev/l", "t [ms]", "check [ms]");
  for (double amp : amps)
    for (double e : ends) {
      const BSplineCurve2 c = wave(amp, 2 * M_PI + e);
      std::vector<double> ts, tc;
      StripStabilizeResult r(c);
      for (int rep = 0; rep < repeats; ++rep) {
        auto t0 = Clock::now();
        r = stabilize_strip(c);
        ts.push_back(since(t0));
        t0 = Clock::now();
        StripDesignOptions o;
        o.tolerance = 1e-3;
        o.max_samples = 4097;
        const StripDesign d = design_strip(c, o);
        (void)strip_stability(c, d, o);
        tc.push_back(since(t0));
      }
      const double t = median(ts), tcheck = median(tc);
      if (!r.stable_before) {
        ++unstable;
        stabilized += r.done;
        times.push_back(t);
        ratios.push_back(t / tcheck);
      }
      std::printf("%-5d %-5.1f %-6.1f %-9.4f %-8s %-7.2f %-7.2f %-9.2e %-9.2e %-9.1f %-9.2f\n", index, amp, e,
                  r.sigma_before / r.length, r.status.c_str(), r.R_before, r.R_after, r.max_pole_move / r.length,
                  r.deviation_relative, 1e3 * t, 1e3 * tcheck);
      nlohmann::json hist = nlohmann::json::array();
      for (const auto& h : r.history)
        hist.push_back({{"seconds", h.seconds}, {"sigma_margin", num(h.sigma_margin / r.length)}, {"R", num(h.R)}});
      curves.push_back({{"index", index}, {"amplitude", amp}, {"end", e}, {"status", r.status}, {"done", r.done},
                        {"stable_before", r.stable_before}, {"stable_after", r.stable_after},
                        {"sigma_before", num(r.sigma_before / r.length)}, {"R_before", num(r.R_before)},
                        {"R_after", num(r.R_after)}, {"max_pole_move", r.max_pole_move / r.length},
                        {"deviation", r.deviation_relative}, {"seconds", t}, {"check_seconds", tcheck},
                        {"iterations", static_cast<int>(r.history.size()) - 1}, {"rejected_steps", r.rejected_steps},
                        {"bound_returns", r.bound_returns},
                        // Time after the last accepted step (last repeat): the search that ends a `stationary`
                        // run, the final verdict and the deviation.
                        {"tail_seconds", r.history.empty() ? 0.0 : r.seconds - r.history.back().seconds},
                        {"message", r.message}, {"history", hist}});
      ++index;
    }
  const double med = times.empty() ? NAN : median(times), worst = times.empty() ? NAN : *std::max_element(times.begin(), times.end());
  std::printf("stabilized %d of %d unstable curves; time per unstable curve: median %.3f s, max %.3f s (goal <= 0.25 s); "
              "median %.0fx one stability check\n",
              stabilized, unstable, med, worst, ratios.empty() ? NAN : median(ratios));
  nlohmann::json out = {{"curves", curves}, {"repeats", repeats}, {"unstable", unstable}, {"stabilized", stabilized},
                        {"median_seconds", num(med)}, {"max_seconds", num(worst)}, {"goal_seconds", 0.25}};
  std::printf("wrote %s\n", write_bench_file(out_dir, "strip_stabilize.json", out.dump(1) + "\n").c_str());
  return 0;  // a measurement: curves that stall are reported, not failed
}
