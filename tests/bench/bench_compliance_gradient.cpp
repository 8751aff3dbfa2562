// The compliance gradient against central differences of the whole pipeline, over the step H
// (issue 12: "a chart of the agreement against the step size"; thesis §6.5.3, Eq. 6.30–6.31).
// The L-bracket turned 11° off the grid (cut cells), support on the upright's back, 500 N on the
// base end as a total force, 10-cell face-route grid. For each design entry, moved the way the
// optimizer moves it (projection with one-entry design weights, then the B-rep write-back):
// the exact route (compliance_gradient chained through dp⊥/dp̃), the semi-analytic route
// (compliance_derivative, its own step 1e-4·L), and (C(x+H) − C(x−H))/2H with both sides re-cut on
// the grid of the start model and solved, for H = 1e-1 … 1e-6 mm.
// Usage: bench_compliance_gradient [--quick] --out DIR SAMPLES_DIR -> DIR/compliance_gradient.json
//        (plot: tests/bench/plot_compliance_gradient.py DIR)
#include <Eigen/Geometry>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <nlohmann/json.hpp>
#include <string>

#include "face_lookup.h"
#include "bench_arguments.h"
#include "occt_mass_properties.h"
#include "optimize/projection.h"
#include "part_reader.h"
#include "shape_compliance.h"
#include "shape_modify.h"
#include "shape_parameters.h"
#include "bench_output.h"
#include "turned_bracket_job.h"

using namespace parafab;
using namespace parafab::occ;

namespace {

double seconds_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

}  // namespace

int main(int argc, char** argv) {
  const BenchArguments args = bench_arguments(argc, argv);
  const bool quick = args.quick;
  const std::string &out = args.out, &samples = args.samples;
  const bench::TurnedBracketJob job = bench::turned_bracket_job(samples);
  const auto& part = job.part;
  const ComplianceSetup& setup = job.setup;
  auto turned = [&](const Vec3& X) { return job.turned(X); };

  const bench::DesignSpace space = bench::design_space(*part, setup);
  const auto& [model, sp, start, L] = space;
  struct Entry {
    const char* label;
    Vec3 point;
    const char* parameter;
  };
  std::vector<Entry> entries = {
      {"hole radius", {44, 12, 4}, "radius"},
      {"inner fillet radius", {8 + 5 - 5 * std::sqrt(0.5), 20, 8 + 5 - 5 * std::sqrt(0.5)}, "radius"},
      {"base top plane offset (moves the load face's edge)", {30, 20, 8}, "offset"},
      {"outer fillet radius (tangent into the support)", {12 - 12 * std::sqrt(0.5), 20, 12 - 12 * std::sqrt(0.5)}, "radius"}};
  std::vector<double> steps = {1e-1, 3e-2, 1e-2, 3e-3, 1e-3, 3e-4, 1e-4, 3e-5, 1e-5, 1e-6};
  if (quick) entries.resize(1), steps = {1e-2, 1e-3};
  nlohmann::json rows = nlohmann::json::array();
  for (const Entry& e : entries) {
    const int index = parameter_index(sp, face_at_point(*part, turned(e.point), 1e-6), e.parameter);
    optimize::ProjectionOptions po;
    po.weights = projection_weights(sp, {index}, 1e-4, L);
    const auto base = optimize::project(sp.constraints, start.p, start.p, sp.lower, sp.upper, {}, po);
    auto part_at = [&](double s) -> std::shared_ptr<const PartShape> {
      Eigen::VectorXd t = base.p;
      t[index] += s;
      const auto p = optimize::project(sp.constraints, t, base.p, sp.lower, sp.upper, {}, po);
      if (!p.done) return nullptr;
      const ModifyResult m = modify_part(*part, model, sp, p.p);
      return m.done ? m.part : nullptr;
    };
    const ComplianceState at = compliance_start(part_at(0), setup);
    if (!at.done) {
      std::fprintf(stderr, "%s: %s\n", e.label, at.message.c_str());
      return 1;
    }
    auto t0 = std::chrono::steady_clock::now();
    const ComplianceGradient g = compliance_gradient(at, setup, sp, base.p);
    const auto D = optimize::projection_derivative(sp.constraints, base, sp.lower, sp.upper, po.weights);
    const double exact = g.gradient.dot(D.jacobian.col(index));
    const double exact_seconds = seconds_since(t0);
    const bool complete = exact_along(g, D.jacobian.col(index));
    t0 = std::chrono::steady_clock::now();
    const double h = 1e-4 * L;
    const ComplianceDerivative semi = compliance_derivative(at, part_at(h), part_at(-h), h, setup);
    const double semi_seconds = seconds_since(t0);
    nlohmann::json row = {{"entry", e.label}, {"parameter", sp.names[index]}, {"compliance", at.compliance},
                          {"exact", exact}, {"exact_complete", complete}, {"exact_seconds", exact_seconds},
                          {"semi_analytic", semi.derivative}, {"semi_analytic_seconds", semi_seconds},
                          {"steps", steps}, {"central_differences", nlohmann::json::array()},
                          {"relative_difference_exact", nlohmann::json::array()},
                          {"relative_difference_semi_analytic", nlohmann::json::array()}};
    for (double H : steps) {
      double c[2] = {NAN, NAN};
      for (int side = 0; side < 2; ++side) {
        const auto p = part_at(side ? -H : H);
        if (!p) continue;
        const ComplianceState s = compliance_at(p, at, setup);
        if (s.done) c[side] = s.compliance;
      }
      const double fd = (c[0] - c[1]) / (2 * H);
      row["central_differences"].push_back(fd);
      row["relative_difference_exact"].push_back(std::abs(exact - fd) / std::abs(fd));
      row["relative_difference_semi_analytic"].push_back(std::abs(semi.derivative - fd) / std::abs(fd));
    }
    std::printf("%-52s exact %.10g%s (%.3f s), semi-analytic %.10g (%.3f s)\n", e.label, exact,
                complete ? "" : " (incomplete)", exact_seconds, semi.derivative, semi_seconds);
    rows.push_back(row);
  }
  write_bench_file(out, "compliance_gradient.json", rows.dump(2));
  return 0;
}
