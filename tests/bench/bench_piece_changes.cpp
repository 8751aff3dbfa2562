// Where the objective is not smooth (thesis §6.4.4, Eq. 6.24 not implemented): along design
// lines of the turned L-bracket, every point where a cut cell's material pieces change in
// number (split, join, appear, vanish), bisected to 1e-8 mm, and the compliance jump there
// against the slope times the bracket (what a continuous C would move). Each line is scanned in
// steps of 0.01 mm; a bisection that meets a model the cut refuses is reported as such.
// Usage: bench_piece_changes [--quick] --out DIR SAMPLES_DIR  -> DIR/piece_changes.json
#include <cmath>
#include <cstdio>
#include <map>
#include <nlohmann/json.hpp>
#include <set>
#include <string>

#include "bench_arguments.h"
#include "bench_output.h"
#include "optimize/projection.h"
#include "turned_bracket_job.h"

using namespace parafab;
using namespace parafab::occ;

namespace {

using Pieces = std::map<std::array<int, 3>, std::vector<double>>;  // cut cell → its pieces' volume fractions

Pieces pieces_of(const ComplianceState& st) {
  Pieces m;
  for (const xfem::GridElement& el : st.model->elements)
    if (el.subvolume) m[el.cell].push_back(xfem::volume_fraction(el));
  return m;
}

std::map<std::array<int, 3>, size_t> counts(const Pieces& p) {
  std::map<std::array<int, 3>, size_t> m;
  for (const auto& [cell, f] : p) m[cell] = f.size();
  return m;
}

}  // namespace

int main(int argc, char** argv) {
  const BenchArguments args = bench_arguments(argc, argv);
  const bench::TurnedBracketJob job = bench::turned_bracket_job(args.samples);
  const auto& part = job.part;
  const bench::DesignSpace space = bench::design_space(*part, job.setup);
  const auto& [model, sp, start, L] = space;
  struct Entry {
    const char* label;
    Vec3 point;
    const char* parameter;
    double range;
  };
  std::vector<Entry> entries = {{"hole radius", {44, 12, 4}, "radius", 1.5},
                                {"inner fillet radius", {8 + 5 - 5 * std::sqrt(0.5), 20, 8 + 5 - 5 * std::sqrt(0.5)}, "radius", 1.0},
                                {"base top offset", {30, 20, 8}, "offset", 1.0},
                                {"upright inner offset", {8, 20, 30}, "offset", 1.0}};
  if (args.quick) entries.resize(1), entries[0].range = 0.15;
  nlohmann::json rows = nlohmann::json::array();
  for (const Entry& e : entries) {
    const int index = parameter_index(sp, face_at_point(*part, job.turned(e.point), 1e-6), e.parameter);
    optimize::ProjectionOptions po;
    po.weights = projection_weights(sp, {index}, 1e-4, L);
    std::shared_ptr<const ComplianceState> base;
    auto at = [&](double s) {
      Eigen::VectorXd t = start.p;
      t[index] += s;
      const auto p = optimize::project(sp.constraints, t, start.p, sp.lower, sp.upper, {}, po);
      ComplianceState failed;
      if (!p.done) return failed;
      const ModifyResult m = modify_part(*part, model, sp, p.p);
      if (!m.done) return failed;
      return base ? compliance_at(m.part, *base, job.setup, nullptr) : compliance_start(m.part, job.setup);
    };
    base = std::make_shared<const ComplianceState>(at(0));
    if (!base->done) {
      std::fprintf(stderr, "%s: the start does not simulate: %s\n", e.label, base->message.c_str());
      return 1;
    }
    const double step = 0.01;
    ComplianceState left = at(0);
    for (int i = 1; i * step <= e.range + 1e-12; ++i) {
      const double s = i * step;
      ComplianceState right = at(s);
      if (!right.done || !left.done || counts(pieces_of(left)) == counts(pieces_of(right))) {
        left = std::move(right);
        continue;
      }
      const auto before = counts(pieces_of(left));
      double a = s - step, b = s;
      std::string failure;
      while (b - a > 1e-8 && failure.empty()) {
        const double m = 0.5 * (a + b);
        const ComplianceState sm = at(m);
        if (!sm.done) failure = sm.message.empty() ? "projection or write-back" : sm.message;
        else (counts(pieces_of(sm)) == before ? a : b) = m;
      }
      nlohmann::json row = {{"entry", e.label}, {"near", s}};
      if (!failure.empty()) {
        row["bisection_failed_at"] = 0.5 * (a + b);
        row["failure"] = failure;
        std::printf("%-22s near +%.2f: bisection met a refused model at +%.8f: %s\n", e.label, s, 0.5 * (a + b), failure.c_str());
      } else {
        const ComplianceState sa = at(a), sb = at(b), s1 = at(a - 0.002), s2 = at(a - 0.004);
        const double slope = (s1.compliance - s2.compliance) / 0.002;
        const double jump = (sb.compliance - sa.compliance) / sa.compliance;
        const double smooth = std::abs(slope) * (b - a) / sa.compliance;
        const Pieces pa = pieces_of(sa), pb = pieces_of(sb);
        std::set<std::array<int, 3>> cells;
        for (const auto& [c, f] : pa) cells.insert(c);
        for (const auto& [c, f] : pb) cells.insert(c);
        nlohmann::json changes = nlohmann::json::array();
        std::string text;
        for (const auto& c : cells) {
          const std::vector<double> fa = pa.count(c) ? pa.at(c) : std::vector<double>{};
          const std::vector<double> fb = pb.count(c) ? pb.at(c) : std::vector<double>{};
          if (fa.size() == fb.size()) continue;
          changes.push_back({{"cell", c}, {"before", fa}, {"after", fb}});
          char buf[64];
          text += " [";
          for (double f : fa) std::snprintf(buf, sizeof buf, "%.4f ", f), text += buf;
          text += "->";
          for (double f : fb) std::snprintf(buf, sizeof buf, " %.4f", f), text += buf;
          text += "]";
        }
        row.update({{"at", a}, {"relative_jump", jump}, {"relative_slope_times_interval", smooth}, {"cells", changes}});
        std::printf("%-22s at +%.7f: relative jump %+.2e (slope x interval %.1e), pieces%s\n", e.label, a, jump, smooth,
                    text.c_str());
      }
      rows.push_back(row);
      left = std::move(right);
    }
  }
  std::printf("wrote %s\n", write_bench_file(args.out, "piece_changes.json", rows.dump(2)).c_str());
  return 0;
}
