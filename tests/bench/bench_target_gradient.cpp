// The target-shape gradient (thesis §6.2.3 Eq. 6.6; shape_target.h) against central differences
// of the pipeline, over the step H (issue 12: "a chart of the agreement against the step size"),
// linear and hyperelastic. The L-bracket turned 11° off the grid (cut cells), support on the
// upright's back, 500 N on the base end (total force), 10-cell face-route grid; the base top face
// matched to its own plane. Hyperelastic: CalculiX's isochoric neo-Hooke with E = 3 GPa (RMS
// distance 2.5 mm). Each entry moves the way the optimizer moves it (projection with one-entry
// design weights, then the B-rep write-back); the adjoint derivative (its own step 1e-4·L) against
// (J(x+H) − J(x−H))/2H with both sides re-cut on the grid of the start model and solved, for
// H = 1e-1 … 1e-6 mm. Linear rows also carry the exact route (target_gradient: boundary integrals,
// every entry of p in one call, its time beside the adjoint route's per entry).
// Usage: bench_target_gradient [--quick] --out DIR SAMPLES_DIR -> DIR/target_gradient.json
//        (plot: tests/bench/plot_compliance_gradient.py DIR target_gradient)
#include <Eigen/Geometry>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <nlohmann/json.hpp>
#include <string>

#include "bench_arguments.h"
#include "bench_output.h"
#include "face_lookup.h"
#include "occt_mass_properties.h"
#include "optimize/projection.h"
#include "part_reader.h"
#include "shape_modify.h"
#include "shape_parameters.h"
#include "shape_target.h"
#include "turned_bracket_job.h"

using namespace parafab;
using namespace parafab::occ;

int main(int argc, char** argv) {
  const BenchArguments args = bench_arguments(argc, argv);
  const bool quick = args.quick;
  const std::string &out = args.out, &samples = args.samples;
  const bench::TurnedBracketJob job = bench::turned_bracket_job(samples);
  const auto& part = job.part;
  const ComplianceSetup& linear = job.setup;
  auto turned = [&](const Vec3& X) { return job.turned(X); };
  ComplianceSetup hyper = linear;
  hyper.material.youngs_modulus = 3000;
  hyper.hyperelastic = xfem::make_material("neo_hooke_isochoric", 3000, 0.3);
  hyper.load_steps = 3;

  const bench::DesignSpace space = bench::design_space(*part, linear);
  const auto& [model, sp, start, L] = space;
  TargetOptions target;
  target.face = face_at_point(*part, turned({30, 20, 8}), 1e-6);
  target.target = target_of_face(model, target.face);
  struct Entry {
    const char* label;
    Vec3 point;
    const char* parameter;
  };
  std::vector<Entry> entries = {{"hole radius", {44, 12, 4}, "radius"},
                                {"base top plane offset (the matched face)", {30, 20, 8}, "offset"}};
  std::vector<double> steps = {1e-1, 3e-2, 1e-2, 3e-3, 1e-3, 3e-4, 1e-4, 3e-5, 1e-5, 1e-6};
  if (quick) entries.resize(1), steps = {1e-2, 1e-3};
  nlohmann::json rows = nlohmann::json::array();
  for (const bool hyperelastic : {false, true}) {
    const ComplianceSetup& setup = hyperelastic ? hyper : linear;
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
      const TargetValue v = target_value(at, setup, target, true);
      const auto t0 = std::chrono::steady_clock::now();
      const double h = 1e-4 * L;
      const ComplianceDerivative d = target_derivative(at, v, {}, part_at(h), part_at(-h), h, setup, target);
      const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
      const std::string label = std::string(e.label) + (hyperelastic ? ", neo-Hooke" : ", linear");
      // The exact route (linear only) along the entry's column of dp⊥/dp̃.
      double exact = NAN, exact_seconds = NAN;
      if (!hyperelastic) {
        const Eigen::VectorXd column =
            optimize::projection_derivative(sp.constraints, base, sp.lower, sp.upper, po.weights).jacobian.col(index);
        const Eigen::VectorXd lambda = target_adjoint(at, v);
        const auto e0 = std::chrono::steady_clock::now();
        const ComplianceGradient g = target_gradient(at, v, lambda, setup, target, sp, base.p);
        exact_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - e0).count();
        if (!g.done || !exact_along(g, column)) {
          std::fprintf(stderr, "%s: the exact route %s\n", label.c_str(), g.done ? "flags this entry" : g.message.c_str());
          return 1;
        }
        exact = g.gradient.dot(column);
      }
      nlohmann::json row = {{"entry", label}, {"parameter", sp.names[index]}, {"objective", v.objective},
                            {"rms_distance", std::sqrt(v.objective)}, {"adjoint", d.derivative},
                            {"adjoint_seconds", seconds}, {"steps", steps},
                            {"central_differences", nlohmann::json::array()},
                            {"relative_difference_adjoint", nlohmann::json::array()}};
      if (!hyperelastic) {
        row["exact"] = exact;
        row["exact_seconds"] = exact_seconds;
        row["relative_difference_exact"] = nlohmann::json::array();
      }
      for (double H : steps) {
        double j[2] = {NAN, NAN};
        for (int side = 0; side < 2; ++side) {
          const auto p = part_at(side ? -H : H);
          if (!p) continue;
          const ComplianceState s = compliance_at(p, at, setup);
          if (s.done) j[side] = target_value(s, setup, target).objective;
        }
        const double fd = (j[0] - j[1]) / (2 * H);
        row["central_differences"].push_back(fd);
        row["relative_difference_adjoint"].push_back(std::abs(d.derivative - fd) / std::abs(fd));
        if (!hyperelastic) row["relative_difference_exact"].push_back(std::abs(exact - fd) / std::abs(fd));
      }
      std::printf("%-60s J %.6g, adjoint %.10g (%.3f s), exact %.10g (%.3f s, all entries)\n", label.c_str(), v.objective,
                  d.derivative, seconds, exact, exact_seconds);
      rows.push_back(row);
    }
  }
  write_bench_file(out, "target_gradient.json", rows.dump(2));
  return 0;
}
