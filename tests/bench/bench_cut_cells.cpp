// Benchmark of the cut-cell quadrature (thesis §6.3, cf. Fig. 6.4, 6.12 and 6.13): for every
// cut cell of the sample parts and every monomial up to degree 2 in cell coordinates, the error
// of the rules against the per-cell OCCT Boolean route (box ∩ part, BRepGProp), divided by the
// cell volume; time per cell (medians over repeats) of three routes in the same run: the face
// route (cut by face + rules), the splitter route (OCCT splitter + rules) and the Boolean.
// Then error against time while the curve-segment tolerance and the grid resolution vary,
// linear against parabolic segments (splitter route).
//   bench_cut_cells [--quick] [--out DIR] SAMPLES_DIR   → DIR/cut_cells.json
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "occt_mass_properties.h"
#include "part_integration.h"
#include "part_reader.h"
#include "bench_output.h"

using namespace parafab;
using nlohmann::json;

namespace {

double now() {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

// ∫1, ∫ξ, ∫ξξᵀ in cell coordinates ξ = (X − min)/h from mass properties (about the centre).
std::vector<double> monomials(const xfem::MassProperties& p, const xfem::Box3& cell) {
  const double h = cell.size().maxCoeff();
  const Eigen::Vector3d c = (p.center - cell.min) / h;
  const double V = p.volume / (h * h * h);  // measure in ξ units
  const Eigen::Matrix3d I = p.inertia / std::pow(h, 5);
  const Eigen::Matrix3d second_central = 0.5 * I.trace() * Eigen::Matrix3d::Identity() - I;
  const Eigen::Matrix3d second = second_central + V * c * c.transpose();
  std::vector<double> m{V, V * c.x(), V * c.y(), V * c.z()};
  for (int i = 0; i < 3; ++i)
    for (int j = i; j < 3; ++j) m.push_back(second(i, j));
  return m;
}

struct CellReference {
  xfem::Box3 box;
  std::vector<double> moments;
};

struct Stats {
  double median = 0, p90 = 0, max = 0;
};
Stats stats(std::vector<double> e) {
  Stats s;
  if (e.empty()) return s;
  std::sort(e.begin(), e.end());
  s.median = e[e.size() / 2];
  s.p90 = e[std::min(e.size() - 1, e.size() * 9 / 10)];
  s.max = e.back();
  return s;
}

// Rules for every cut cell; errors of the 10 monomials against the references.
struct RunResult {
  std::vector<double> errors;
  double seconds_per_cell = 0;       ///< cut + rules
  double cut_seconds_per_cell = 0;   ///< OCCT splitter + patch extraction
  double rule_seconds_per_cell = 0;  ///< moment-fitted rules only
  int cells = 0, segments = 0;
  bool done = false;
  bool fell_back = false;  ///< the face route cut a shifted grid (retry_reason)
  std::string reason;
};
RunResult run_rules(const occ::PartShape& part, const occ::IntegrationOptions& o,
                    const std::vector<CellReference>& refs) {
  RunResult rr;
  const double t0 = now();
  const occ::IntegrationResult r = occ::integrate_part(part, o);
  const double t = now() - t0;
  if (!r.done) return rr;
  rr.done = true;
  rr.fell_back = !r.cut.retry_reason.empty();
  rr.reason = r.cut.retry_reason;
  rr.cells = static_cast<int>(r.cut.cut_cells.size());
  rr.segments = r.cut.segments;
  rr.seconds_per_cell = t / std::max(1, rr.cells);
  rr.cut_seconds_per_cell = r.cut_seconds / std::max(1, rr.cells);
  rr.rule_seconds_per_cell = r.rule_seconds / std::max(1, rr.cells);
  for (const auto& cell : r.cut.cut_cells) {
    const xfem::Box3 box = r.cut.cell_box(cell.index);
    const std::vector<double> mine = monomials(occ::cut_cell_properties(r, cell), box);
    const CellReference* ref = nullptr;
    for (const auto& c : refs)
      if ((c.box.min - box.min).norm() < 1e-9 * box.size().norm()) ref = &c;
    if (!ref) continue;  // grid differs (not the reference grid)
    for (size_t k = 0; k < mine.size(); ++k) rr.errors.push_back(std::abs(mine[k] - ref->moments[k]));
  }
  return rr;
}

}  // namespace

int main(int argc, char** argv) {
  bool quick = false;
  int repeats = 0;
  std::string out_dir = ".", samples;
  for (int i = 1; i < argc; ++i) {
    if (!std::strcmp(argv[i], "--quick")) quick = true;
    else if (!std::strcmp(argv[i], "--out") && i + 1 < argc) out_dir = argv[++i];
    else if (!std::strcmp(argv[i], "--repeats") && i + 1 < argc) repeats = std::atoi(argv[++i]);
    else samples = argv[i];
  }
  if (samples.empty()) {
    std::fprintf(stderr, "usage: bench_cut_cells [--quick] [--repeats N] [--out DIR] SAMPLES_DIR\n");
    return 2;
  }
  const std::vector<std::string> parts =
      quick ? std::vector<std::string>{"l_bracket"}
            : std::vector<std::string>{"box", "cylinder", "l_bracket", "wrench", "ring", "half_torus", "wheel", "housing"};
  const int cells = quick ? 4 : 6;
  if (repeats <= 0) repeats = quick ? 1 : 5;
  json per_part = json::array();
  struct Totals {
    std::vector<double> errors;
    double cut = 0, rules = 0;
  } tot[2];  // [0] face route, [1] splitter route
  double bool_time = 0;
  int total_cells = 0;
  const char* route_name[2] = {"face", "splitter"};
  std::printf("%-11s %6s %-8s %10s %10s %9s %9s %9s %8s %s\n", "part", "cells", "route", "median", "max", "cut ms",
              "rules ms", "bool ms", "speedup", "note");
  for (const std::string& name : parts) {
    const auto part = occ::read_part(samples + "/parts/" + name + ".step");
    occ::IntegrationOptions o;
    o.grid.cells_longest = cells;
    o.occt_reference = false;
    // Reference: per-cell Boolean on the same grid (median over repeats of the whole loop).
    const occ::GridCut grid = occ::cut_by_grid(*part, o.grid);
    std::vector<CellReference> refs;
    std::vector<double> t_bools;
    for (int rep = 0; rep < repeats; ++rep) {
      refs.clear();
      const double t0 = now();
      for (const auto& cell : grid.cut_cells) {
        const xfem::Box3 box = grid.cell_box(cell.index);
        const occ::CellBooleanResult b = occ::occt_cell_properties(*part, box);
        if (b.done) refs.push_back({box, monomials(b.properties, box)});
      }
      t_bools.push_back((now() - t0) / std::max<size_t>(1, grid.cut_cells.size()));
      if (quick) break;
    }
    std::sort(t_bools.begin(), t_bools.end());
    const double t_bool = t_bools[t_bools.size() / 2];
    json entry{{"part", name}, {"boolean_seconds_per_cell", t_bool}};
    for (int route = 0; route < 2; ++route) {
      o.grid.method = route == 0 ? occ::CutMethod::FaceCut : occ::CutMethod::Splitter;
      std::vector<double> cut_t, rule_t;
      RunResult rr;
      for (int rep = 0; rep < repeats; ++rep) {
        rr = run_rules(*part, o, refs);
        cut_t.push_back(rr.cut_seconds_per_cell);
        rule_t.push_back(rr.rule_seconds_per_cell);
      }
      std::sort(cut_t.begin(), cut_t.end());
      std::sort(rule_t.begin(), rule_t.end());
      const double tc = cut_t[cut_t.size() / 2], trl = rule_t[rule_t.size() / 2];
      const Stats s = stats(rr.errors);
      const std::string note = rr.fell_back ? "shifted grid: " + rr.reason : "";
      std::printf("%-11s %6d %-8s %10.2e %10.2e %9.3f %9.3f %9.3f %7.1fx %s\n", name.c_str(), rr.cells, route_name[route],
                  s.median, s.max, 1e3 * tc, 1e3 * trl, 1e3 * t_bool, t_bool / (tc + trl), note.c_str());
      entry[route_name[route]] = {{"cut_cells", rr.cells}, {"median", s.median}, {"p90", s.p90}, {"max", s.max},
                                  {"cut_seconds_per_cell", tc}, {"rules_seconds_per_cell", trl},
                                  {"speedup", t_bool / (tc + trl)}, {"fell_back", rr.fell_back}, {"reason", rr.reason}};
      tot[route].errors.insert(tot[route].errors.end(), rr.errors.begin(), rr.errors.end());
      tot[route].cut += tc * rr.cells;
      tot[route].rules += trl * rr.cells;
      if (route == 0) total_cells += rr.cells, bool_time += t_bool * rr.cells;
    }
    per_part.push_back(entry);
  }
  json all{{"cells", total_cells}, {"boolean_seconds_per_cell", bool_time / total_cells}};
  for (int route = 0; route < 2; ++route) {
    const Stats s = stats(tot[route].errors);
    const double tc = tot[route].cut / total_cells, trl = tot[route].rules / total_cells;
    std::printf("%s route, all %d cut cells x 10 monomials: median %.2e, p90 %.2e, max %.2e; per cell: cut %.3f ms + "
                "rules %.3f ms vs Boolean %.3f ms: %.1fx\n",
                route_name[route], total_cells, s.median, s.p90, s.max, 1e3 * tc, 1e3 * trl, 1e3 * bool_time / total_cells,
                bool_time / total_cells / (tc + trl));
    all[route_name[route]] = {{"median", s.median}, {"p90", s.p90}, {"max", s.max}, {"cut_seconds_per_cell", tc},
                              {"rules_seconds_per_cell", trl}, {"speedup", bool_time / total_cells / (tc + trl)}};
  }

  // Error against time: segment tolerance × order on curved parts, at several grids.
  json sweep = json::array();
  const std::vector<std::string> sweep_parts = quick ? std::vector<std::string>{"ring"} : std::vector<std::string>{"ring", "l_bracket"};
  const std::vector<int> grids = quick ? std::vector<int>{4} : std::vector<int>{4, 8, 12};
  const std::vector<double> tols = quick ? std::vector<double>{1e-3, 1e-8} : std::vector<double>{1e-2, 1e-4, 1e-6, 1e-8, 1e-10};
  for (const std::string& name : sweep_parts) {
    const auto part = occ::read_part(samples + "/parts/" + name + ".step");
    for (int n : grids) {
      occ::IntegrationOptions o;
      o.grid.cells_longest = n;
      o.occt_reference = false;
      const occ::GridCut grid = occ::cut_by_grid(*part, o.grid);
      std::vector<CellReference> refs;
      for (const auto& cell : grid.cut_cells) {
        const xfem::Box3 box = grid.cell_box(cell.index);
        const occ::CellBooleanResult b = occ::occt_cell_properties(*part, box);
        if (b.done) refs.push_back({box, monomials(b.properties, box)});
      }
      for (int order : {1, 2})
        for (double tol : tols) {
          o.grid.segment_order = order;
          o.grid.segment_tolerance = tol;
          const RunResult rr = run_rules(*part, o, refs);
          const Stats st = stats(rr.errors);
          sweep.push_back({{"part", name}, {"cells", n}, {"order", order}, {"segment_tolerance", tol},
                           {"segments", rr.segments}, {"seconds_per_cell", rr.seconds_per_cell},
                           {"median", st.median}, {"max", st.max}});
          std::printf("sweep %-9s grid %2d order %d tol %.0e: %6d segments, %.3f ms/cell, median %.2e max %.2e\n",
                      name.c_str(), n, order, tol, rr.segments, 1e3 * rr.seconds_per_cell, st.median, st.max);
        }
    }
  }
  json out{{"benchmark", "cut_cells"}, {"cells_longest", cells}, {"repeats", repeats},
           {"parts", per_part},           {"all", all},           {"sweep", sweep}};
  std::printf("wrote %s\n", write_bench_file(out_dir, "cut_cells.json", out.dump(2) + "\n").c_str());
  return 0;
}
