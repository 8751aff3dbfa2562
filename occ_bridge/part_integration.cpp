#include "part_integration.h"

#include <chrono>

#include "occt_mass_properties.h"
#include "occt_shape.h"

namespace parafab::occ {

namespace {
double seconds_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}
}  // namespace

xfem::MassProperties cut_cell_properties(const IntegrationResult& result, const CutCell& cell) {
  xfem::MassAccumulator acc;
  for (int s : cell.subvolumes) acc.add(result.rules[s].rule.points, result.rules[s].rule.weights);
  return acc.result();
}

MassPropertyErrors compare(const xfem::MassProperties& a, const xfem::MassProperties& ref,
                           double diagonal) {
  MassPropertyErrors e;
  e.volume = std::abs(a.volume - ref.volume) / std::abs(ref.volume);
  e.center = (a.center - ref.center).norm() / diagonal;
  e.inertia = (a.inertia - ref.inertia).norm() / ref.inertia.norm();
  return e;
}

IntegrationResult integrate_part(const PartShape& part, const IntegrationOptions& o) {
  IntegrationResult r;
  auto t0 = std::chrono::steady_clock::now();
  r.cut = cut_by_grid(part, o.grid);
  r.cut_seconds = seconds_since(t0);
  if (!r.cut.done) {
    r.message = r.cut.message;
    return r;
  }
  t0 = std::chrono::steady_clock::now();
  xfem::MassAccumulator acc;
  r.rules.reserve(r.cut.subvolumes.size());
  for (const auto& sv : r.cut.subvolumes) {
    r.rules.push_back(xfem::volume_rule(sv, o.rule));
    const xfem::VolumeRule& vr = r.rules.back();
    acc.add(vr.rule.points, vr.rule.weights);
    r.rule_points += static_cast<int>(vr.rule.points.size());
    r.rules_not_ok += vr.status != xfem::RuleStatus::Ok;
    r.rules_refinement_capped += vr.flux_capped_leaves > 0;
    r.max_moment_residual = std::max(r.max_moment_residual, vr.moment_residual);
    r.max_closure_defect = std::max(r.max_closure_defect, vr.closure_defect);
  }
  for (const auto& ijk : r.cut.interior_cells) {
    const xfem::QuadratureRule3 q = xfem::tensor_gauss_rule(r.cut.cell_box(ijk), o.interior_points);
    acc.add(q.points, q.weights);
    r.rule_points += static_cast<int>(q.points.size());
  }
  r.by_rules = acc.result();
  r.rule_seconds = seconds_since(t0);
  if (o.occt_reference) {
    t0 = std::chrono::steady_clock::now();
    r.by_occt = occt_mass_properties(part, o.occt_precision);
    r.occt_seconds = seconds_since(t0);
    r.errors = compare(r.by_rules, r.by_occt, r.cut.grid.size().norm());
  }
  r.done = true;
  return r;
}

}  // namespace parafab::occ
