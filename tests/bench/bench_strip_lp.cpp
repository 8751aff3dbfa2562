// Benchmark of the strip LP (thesis Eq. 4.4): time and accuracy of R against the number of
// samples, for ParaFab's dense dual simplex (default), with Clp on the dual form and on the
// row-wise primal form as in-process baselines (their R must agree). Reference: the minimax ratio of an exact rational elliptic arc, computed without
// any LP (golden-section search over the line's one free parameter, which symmetry leaves,
// with K maximized and minimized on the continuous curve).
//   bench_strip_lp [--quick] [--out DIR]   → DIR/strip_lp.json (then plot_strip_lp.py)
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <functional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "strips/stiffness_lp.h"
#include "strips/strip_design.h"
#include "bench_output.h"

using namespace parafab;

namespace {

constexpr double kA = 0.30, kB = 0.15;  // semi-axes [m]
constexpr double kT0 = 0.3;              // arc t ∈ [t0, π − t0], symmetric about the y axis

// Exact rational quadratic NURBS of the elliptic arc, split into 4 pieces of equal angle.
BSplineCurve2 elliptic_arc() {
  const int pieces = 4;
  const double t1 = M_PI - kT0, dt = (t1 - kT0) / pieces;
  std::vector<Vec2> poles;
  std::vector<double> weights, knots{0, 0, 0};
  for (int i = 0; i < pieces; ++i) {
    const double ta = kT0 + i * dt, tm = ta + dt / 2, tb = ta + dt;
    // Circle arc mapped affinely: middle pole at the tangent intersection, weight cos(dt/2).
    const double w = std::cos(dt / 2);
    if (i == 0) poles.emplace_back(kA * std::cos(ta), kB * std::sin(ta)), weights.push_back(1);
    poles.emplace_back(kA * std::cos(tm) / w, kB * std::sin(tm) / w);
    weights.push_back(w);
    poles.emplace_back(kA * std::cos(tb), kB * std::sin(tb));
    weights.push_back(1);
    if (i + 1 < pieces) knots.push_back(i + 1), knots.push_back(i + 1);
  }
  knots.insert(knots.end(), {double(pieces), double(pieces), double(pieces)});
  return BSplineCurve2(2, knots, poles, weights);
}

// K(t) ∝ (1 + c·y(t)) / κ(t) for the symmetric line a = 1, b = (0, c).
double stiffness(double c, double t) {
  const double s = std::sin(t), co = std::cos(t);
  const double kappa = kA * kB / std::pow(kA * kA * s * s + kB * kB * co * co, 1.5);
  return (1 + c * kB * s) / kappa;
}

double golden(const std::function<double(double)>& f, double lo, double hi, double tol) {
  const double g = 0.5 * (std::sqrt(5.0) - 1);
  double x1 = hi - g * (hi - lo), x2 = lo + g * (hi - lo), f1 = f(x1), f2 = f(x2);
  while (hi - lo > tol) {
    if (f1 < f2) hi = x2, x2 = x1, f2 = f1, x1 = hi - g * (hi - lo), f1 = f(x1);
    else lo = x1, x1 = x2, f1 = f2, x2 = lo + g * (hi - lo), f2 = f(x2);
  }
  return 0.5 * (lo + hi);
}

// max K / min K on the continuous arc for a given c (dense scan + local golden refinement).
double ratio_for(double c) {
  const int n = 2000;
  const double t1 = M_PI - kT0, h = (t1 - kT0) / n;
  int imax = 0, imin = 0;
  std::vector<double> K(n + 1);
  for (int i = 0; i <= n; ++i) {
    K[i] = stiffness(c, kT0 + i * h);
    if (K[i] > K[imax]) imax = i;
    if (K[i] < K[imin]) imin = i;
  }
  auto refine = [&](int i, double sign) {
    const double lo = std::max(kT0, kT0 + (i - 1) * h), hi = std::min(t1, kT0 + (i + 1) * h);
    const double t = golden([&](double x) { return sign * stiffness(c, x); }, lo, hi, 1e-13);
    return sign * std::min(sign * stiffness(c, t), sign * K[i]);  // golden minimizes sign·K
  };
  const double kmax = refine(imax, -1.0), kmin = refine(imin, 1.0);
  return kmax / kmin;
}

double reference_ratio() {
  // Positive K needs 1 + c·y > 0 on the arc (y ≤ kB): c ∈ (−1/kB, ∞); R(c) is quasi-convex.
  const double c = golden(ratio_for, -1.0 / kB + 1e-6, 20.0, 1e-12);
  return ratio_for(c);
}

template <class F>
double median_seconds(int repeats, F&& f) {
  std::vector<double> t;
  for (int r = 0; r < repeats; ++r) {
    const auto t0 = std::chrono::steady_clock::now();
    f();
    t.push_back(std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
  }
  std::sort(t.begin(), t.end());
  return t[t.size() / 2];
}

}  // namespace

int main(int argc, char** argv) {
  bool quick = false;
  std::string out_dir = ".";
  for (int i = 1; i < argc; ++i) {
    if (!std::strcmp(argv[i], "--quick")) quick = true;
    else if (!std::strcmp(argv[i], "--out") && i + 1 < argc) out_dir = argv[++i];
    else {
      std::fprintf(stderr, "usage: bench_strip_lp [--quick] [--out DIR]\n");
      return 2;
    }
  }
  const PlaneCurve curve(elliptic_arc());
  const double R_ref = reference_ratio();
  std::vector<int> counts = quick ? std::vector<int>{100, 400, 4000}
                                  : std::vector<int>{100, 400, 1000, 4000, 10000, 40000, 100000, 400000};
  const int primal_limit = quick ? 4000 : 40000;
  nlohmann::json rows = nlohmann::json::array();
  std::printf("reference R = %.15f (no LP: golden search on the symmetric line)\n", R_ref);
  std::printf("%8s %11s %11s %11s %8s %14s %10s %12s\n", "samples", "dense [ms]", "Clp dual", "Clp primal",
              "dual/dense", "R error", "dense-dual", "sampling[ms]");
  for (int n : counts) {
    std::vector<CurvePoint> samples;
    const double t_sample = median_seconds(1, [&] { samples = sample_by_arc_length(curve, n, {}); });
    const int repeats = std::max(3, std::min(51, 200000 / n));
    StiffnessLpResult dense, dual;
    StiffnessLpOptions o;
    const double t_dense = median_seconds(repeats, [&] { dense = solve_stiffness_lp(samples, {}, {}, curve.length(), o); });
    o.form = LpForm::Dual;
    const double t_dual = median_seconds(repeats, [&] { dual = solve_stiffness_lp(samples, {}, {}, curve.length(), o); });
    double t_primal = NAN;
    if (n <= primal_limit) {
      o.form = LpForm::Primal;
      StiffnessLpResult primal;
      t_primal = median_seconds(n >= 10000 ? 1 : 3, [&] { primal = solve_stiffness_lp(samples, {}, {}, curve.length(), o); });
      if (!primal.ok() || std::abs(primal.R - dual.R) > 1e-8 * dual.R) {
        std::fprintf(stderr, "primal and dual disagree at n = %d: %.12g vs %.12g (%s)\n", n, primal.R, dual.R, primal.message.c_str());
        return 1;
      }
    }
    if (!dual.ok() || !dense.ok()) {
      std::fprintf(stderr, "LP failed at n = %d: %s %s\n", n, dual.message.c_str(), dense.message.c_str());
      return 1;
    }
    const double dense_vs_dual = std::abs(dense.R - dual.R) / dual.R;
    if (dense_vs_dual > 1e-10) {
      std::fprintf(stderr, "dense and Clp dual disagree at n = %d: %.15g vs %.15g\n", n, dense.R, dual.R);
      return 1;
    }
    const double err = std::abs(dense.R - R_ref) / R_ref;
    std::printf("%8d %11.4f %11.4f %11.4f %8.1f %14.3e %10.1e %12.3f\n", n, 1e3 * t_dense, 1e3 * t_dual,
                1e3 * t_primal, t_dual / t_dense, err, dense_vs_dual, 1e3 * t_sample);
    rows.push_back({{"samples", n}, {"dense_seconds", t_dense}, {"dense_iterations", dense.iterations},
                    {"dense_vs_dual_R", dense_vs_dual}, {"dual_seconds", t_dual}, {"repeats", repeats},
                    {"primal_seconds", std::isfinite(t_primal) ? nlohmann::json(t_primal) : nlohmann::json(nullptr)},
                    {"R", dense.R}, {"R_relative_error", err}, {"iterations", dual.iterations},
                    {"sampling_seconds", t_sample}});
  }
  // The adaptive design (sample count chosen from the tolerance on R) on the same curve.
  nlohmann::json adaptive = nlohmann::json::array();
  for (double tol : {1e-3, 1e-4, 1e-6, 1e-8}) {
    StripDesignOptions so;
    so.tolerance = tol;
    StripDesign d;
    const double t = median_seconds(3, [&] { d = design_strip(curve.bspline(), so); });
    adaptive.push_back({{"tolerance", tol}, {"samples", d.lp_samples}, {"seconds", t},
                        {"R_relative_error", std::abs(d.R - R_ref) / R_ref}});
    std::printf("adaptive tol %.0e: %d samples, %.3f ms, R error %.2e\n", tol, d.lp_samples, 1e3 * t,
                std::abs(d.R - R_ref) / R_ref);
  }
  nlohmann::json out{{"benchmark", "strip_lp"},
                     {"curve", "rational elliptic arc a=0.30 b=0.15 t in [0.3, pi-0.3]"},
                     {"reference_R", R_ref},
                     {"rows", rows},
                     {"adaptive", adaptive}};
  const std::string path = write_bench_file(out_dir, "strip_lp.json", out.dump(2) + "\n");
  std::printf("wrote %s\n", path.c_str());
  return 0;
}
