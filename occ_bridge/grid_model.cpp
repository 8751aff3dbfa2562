#include "grid_model.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <chrono>
#include <algorithm>
#include <cmath>
#include <map>
#include <sstream>

#include <BRepGProp.hxx>
#include <GProp_GProps.hxx>

#include "common/error.h"
#include "cut_cell_classifier.h"
#include "occt_mass_properties.h"
#include "occt_shape.h"

namespace parafab::occ {

namespace {

// Elements and adjacency of m.cut; `reused(s)` is a rule to reuse for subvolume s, or null.
template <class Reused>
void make_elements(GridModel& m, const GridModelOptions& o, const Reused& reused) {
  const auto t0 = std::chrono::steady_clock::now();
  const GridCut& g = *m.cut;
  // Element of every interior cell, by dense cell index (−1: none); i-major like std::map's
  // lexicographic order, so adjacency lists keep their order.
  const std::array<int, 3> nc = g.cells;
  auto cell_id = [&](const std::array<int, 3>& c) { return (static_cast<size_t>(c[0]) * nc[1] + c[1]) * nc[2] + c[2]; };
  std::vector<int> interior(static_cast<size_t>(nc[0]) * nc[1] * nc[2], -1);
  const int n_interior = static_cast<int>(g.interior_cells.size());
  const int first_cut = static_cast<int>(m.elements.size()) + n_interior;
  m.elements.resize(first_cut + g.subvolumes.size());
  for (int i = 0; i < n_interior; ++i) interior.at(cell_id(g.interior_cells[i])) = first_cut - n_interior + i;
  // Rules in parallel (TBB): every element's rule depends on its cell or subvolume only, so the
  // model is the same for every thread count.
  tbb::parallel_for(tbb::blocked_range<int>(0, n_interior, 256), [&](const tbb::blocked_range<int>& r) {
    for (int i = r.begin(); i != r.end(); ++i) {
      xfem::GridElement& e = m.elements[first_cut - n_interior + i];
      e.cell = g.interior_cells[i];
      e.box = g.cell_box(e.cell);
      e.rule = xfem::tensor_gauss_rule(e.box, o.interior_points);
    }
  });
  // Rule failures are collected per subvolume and reported in subvolume order.
  std::vector<std::string> failure(g.subvolumes.size());
  std::vector<char> capped(g.subvolumes.size(), 0);
  tbb::parallel_for(tbb::blocked_range<int>(0, static_cast<int>(g.subvolumes.size()), 1),
                    [&](const tbb::blocked_range<int>& r) {
    for (int s = r.begin(); s != r.end(); ++s) {
      const xfem::Subvolume& sv = g.subvolumes[s];
      xfem::GridElement& e = m.elements[first_cut + s];
      e.box = sv.cell;
      const xfem::QuadratureRule3* rule = reused(s);
      if (rule) {
        e.rule = *rule;
      } else {
        try {
          xfem::VolumeRule vr = xfem::volume_rule(sv, o.rule);
          capped[s] = vr.flux_capped_leaves > 0;
          if (vr.status != xfem::RuleStatus::Ok || capped[s]) {
            std::ostringstream msg;
            msg << xfem::to_string(vr.status) << " (volume fraction " << vr.volume / sv.cell.volume()
                << ", moment residual " << vr.moment_residual << ", flux error estimate " << vr.flux_error_estimate
                << ", refinement depth " << vr.flux_depth;
            if (capped[s]) msg << ", " << vr.flux_capped_leaves << " patch region(s) at the depth cap " << o.rule.max_depth;
            msg << ")";
            failure[s] = msg.str();
          }
          e.rule = std::move(vr.rule);
        } catch (const Error& err) {  // a degenerate subvolume: no rule, reported
          failure[s] = std::string("no rule: ") + err.what();
        }
      }
      e.subvolume = &sv;
    }
  });
  for (size_t s = 0; s < failure.size(); ++s)
    if (!failure[s].empty()) m.rule_failures.push_back({{0, 0, 0}, static_cast<int>(s), failure[s], capped[s] != 0});
  for (const auto& cell : g.cut_cells)
    for (int s : cell.subvolumes) m.elements[first_cut + s].cell = cell.index;
  for (auto& f : m.rule_failures) f.cell = m.elements[first_cut + f.subvolume].cell;
  m.rules_refinement_capped = 0;
  for (const auto& f : m.rule_failures) m.rules_refinement_capped += f.refinement_capped;
  // Adjacency: interior–interior neighbours, cut–cut and cut–interior connections.
  for (int i = 0; i < nc[0]; ++i)
    for (int j = 0; j < nc[1]; ++j)
      for (int k = 0; k < nc[2]; ++k) {
        const std::array<int, 3> ijk{i, j, k};
        const int e = interior[cell_id(ijk)];
        if (e < 0) continue;
        for (int a = 0; a < 3; ++a) {
          std::array<int, 3> n = ijk;
          if (++n[a] >= nc[a]) continue;
          const int o = interior[cell_id(n)];
          if (o >= 0) m.adjacent.push_back({e, o});
        }
      }
  for (const auto& [a, b] : g.connections) m.adjacent.push_back({first_cut + a, first_cut + b});
  for (const auto& [s, c] : g.interior_connections)
    m.adjacent.push_back({first_cut + s, interior.at(cell_id(g.interior_cells[c]))});
  m.rule_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  m.done = true;
}

}  // namespace

GridModel build_grid_model(const PartShape& part, const GridModelOptions& o) {
  GridModel m;
  const auto t0 = std::chrono::steady_clock::now();
  m.cut = std::make_shared<GridCut>(cut_by_grid(part, o.grid));
  m.cut_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  if (!m.cut->done) {
    m.message = m.cut->message;
    return m;
  }
  make_elements(m, o, [](int) -> const xfem::QuadratureRule3* { return nullptr; });
  if (m.cut->method == CutMethod::FaceCut) {
    // Safety net of the face route: the rules must hold OCCT's volume of the part; if not, the
    // grid is shifted and the part cut again (GridOptions::shift_retries), or the model fails.
    double volume = 0;
    for (const auto& e : m.elements)
      for (double w : e.rule.weights) volume += w;
    // Adaptive precision: BRepGProp's fixed rule is off by ~1e-5 on B-spline faces.
    const double occt_volume = occt_mass_properties(part, 1e-9).volume;
    if (std::abs(volume - occt_volume) > 1e-6 * std::abs(occt_volume)) {
      const std::string reason = "the face route's rules hold volume " + std::to_string(volume) +
                                 " against OCCT's " + std::to_string(occt_volume);
      for (int k = 1; k <= o.grid.shift_retries; ++k) {
        GridModelOptions so = o;
        so.grid = shifted_grid(*m.cut, o.grid, k);
        GridModel shifted = build_grid_model(part, so);
        if (shifted.done) {
          shifted.cut->retry_reason = reason;
          shifted.cut->grid_shift = so.grid.origin - m.cut->origin;
          shifted.cut_seconds += m.cut_seconds;
          return shifted;
        }
      }
      m.done = false;
      m.message = reason + (o.grid.shift_retries > 0 ? " (also on the shifted grids)" : "");
      return m;
    }
  }
  return m;
}

GridModelOptions rules_for_element(xfem::ElementType element, GridModelOptions o) {
  if (element == xfem::ElementType::Hex27) {
    o.interior_points = std::max(o.interior_points, 3);
    o.rule.degree = std::max(o.rule.degree, 10);
    o.rule.max_exponent = 4;  // the triquadratic stiffness needs a, b, c ≤ 4 only
    o.rule.points_per_direction = std::max(o.rule.points_per_direction, o.rule.max_exponent + 1);
    o.rule.patch.degree = std::max(o.rule.patch.degree, 10);
  }
  return o;
}

GridModel rebuild_grid_model(const PartShape& part, const GridModel& old, const PartShape& old_part,
                             const GridModelOptions& o, RecutReport* report) {
  PARAFAB_VERIFY(old.done, "rebuild_grid_model: the old model is not done");
  RecutReport local;
  RecutReport& r = report ? *report : local;
  GridModel m;
  const auto t0 = std::chrono::steady_clock::now();
  m.cut = std::make_shared<GridCut>(recut_by_grid(part, *old.cut, old_part, o.grid, &r));
  m.cut_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  if (!m.cut->done) {
    m.message = m.cut->message;
    return m;
  }
  const int old_first_cut = static_cast<int>(old.cut->interior_cells.size());
  make_elements(m, o, [&](int s) -> const xfem::QuadratureRule3* {
    if (r.full || s >= static_cast<int>(r.kept_from.size()) || r.kept_from[s] < 0) return nullptr;
    return &old.elements[old_first_cut + r.kept_from[s]].rule;
  });
  // Failures of kept rules stay reported.
  const size_t first_cut = m.elements.size() - m.cut->subvolumes.size();
  for (const auto& f : old.rule_failures)
    for (size_t s = 0; s < r.kept_from.size() && !r.full; ++s)
      if (r.kept_from[s] == f.subvolume)
        m.rule_failures.push_back({m.elements[first_cut + s].cell, static_cast<int>(s), f.message, f.refinement_capped});
  std::sort(m.rule_failures.begin(), m.rule_failures.end(),
            [](const RuleFailure& a, const RuleFailure& b) { return a.subvolume < b.subvolume; });
  m.rules_refinement_capped = 0;
  for (const auto& f : m.rule_failures) m.rules_refinement_capped += f.refinement_capped;
  // Safety net: the rules must integrate the new part's volume (OCCT's). A change the dirty
  // regions missed would leave whole cells wrong; then the part is cut again whole.
  double volume = 0;
  for (const auto& e : m.elements)
    for (double w : e.rule.weights) volume += w;
  const double occt_volume = occt_mass_properties(part, 1e-9).volume;
  r.occt_volume = occt_volume;
  if (std::abs(volume - occt_volume) > 1e-6 * std::abs(occt_volume)) {
    r.verified = false;
    r.full = true;
    r.cells_recut = r.old_cut_cells;  // all of them
    r.message = "the re-cut rules missed the new volume by " + std::to_string(volume - occt_volume) +
                "; cut again whole";
    GridModelOptions fo = o;
    fo.grid.anchored = true;
    fo.grid.origin = old.cut->grid.min;
    fo.grid.cell_size = old.cut->cell_size.maxCoeff();
    fo.grid.shift_retries = 0;  // the kept grid
    GridModel full = build_grid_model(part, fo);
    full.cut_seconds += m.cut_seconds;
    return full;
  }
  return m;
}

ElementLocator::ElementLocator(const GridModel& grid) : grid_(grid), cells_(grid.cut->cells) {
  const size_t n = static_cast<size_t>(cells_[0]) * cells_[1] * cells_[2];
  first_.assign(n + 1, 0);
  for (const auto& el : grid.elements) ++first_[id(el.cell) + 1];
  for (size_t c = 0; c < n; ++c) first_[c + 1] += first_[c];
  list_.resize(grid.elements.size());
  std::vector<int> fill(first_.begin(), first_.end() - 1);
  for (size_t e = 0; e < grid.elements.size(); ++e) list_[fill[id(grid.elements[e].cell)]++] = static_cast<int>(e);
  near_ = 1e-6 * grid.cut->cell_size.norm();
}

int ElementLocator::find(const xfem::Vec3& X) const {
  const auto& cut = *grid_.cut;
  std::array<int, 3> c{};
  for (int a = 0; a < 3; ++a) {
    const auto& pl = cut.planes[a];
    c[a] = static_cast<int>(std::upper_bound(pl.begin(), pl.end(), X[a]) - pl.begin());
  }
  // Candidates: elements whose box holds X, with the distance of their nearest rule point.
  std::vector<std::pair<int, double>> candidates;
  for (int di = -1; di <= 1; ++di)
    for (int dj = -1; dj <= 1; ++dj)
      for (int dk = -1; dk <= 1; ++dk) {
        const std::array<int, 3> n{c[0] + di, c[1] + dj, c[2] + dk};
        if (n[0] < 0 || n[1] < 0 || n[2] < 0 || n[0] >= cells_[0] || n[1] >= cells_[1] || n[2] >= cells_[2]) continue;
        for (int i = first_[id(n)]; i < first_[id(n) + 1]; ++i) {
          const int e = list_[i];
          const auto& el = grid_.elements[e];
          const xfem::Vec3 slack = 1e-6 * el.box.size();
          if (((X - el.box.min + slack).array() < 0).any() || ((el.box.max + slack - X).array() < 0).any()) continue;
          double d = 1e300;
          for (const xfem::Vec3& P : el.rule.points) d = std::min(d, (P - X).norm());
          candidates.emplace_back(e, d);
        }
      }
  if (candidates.empty()) return -1;
  if (candidates.size() == 1) return candidates[0].first;
  auto nearest = [](const std::vector<std::pair<int, double>>& list) {
    return std::min_element(list.begin(), list.end(), [](const auto& a, const auto& b) { return a.second < b.second; })->first;
  };
  // Elements that hold X, else those not known to miss it (undecided), else all candidates.
  std::vector<std::pair<int, double>> holding, maybe;
  for (const auto& cd : candidates) {
    const xfem::Subvolume* sv = grid_.elements[cd.first].subvolume;
    const SubvolumeTest test = sv ? point_in_subvolume(*sv, X, near_) : SubvolumeTest::Inside;
    if (test == SubvolumeTest::Inside || test == SubvolumeTest::OnBoundary) holding.push_back(cd);
    else if (test == SubvolumeTest::Undecided) maybe.push_back(cd);
  }
  if (!holding.empty()) return nearest(holding);
  ++fallbacks_;
  return nearest(maybe.empty() ? candidates : maybe);
}

int ElementLocator::find_on_surface(const xfem::Vec3& X, const xfem::Vec3& n) const {
  const double delta = 1e-3 * grid_.cut->cell_size.minCoeff();
  const double length = n.norm();
  return find(length > 0 ? xfem::Vec3(X - delta / length * n) : X);
}

}  // namespace parafab::occ
