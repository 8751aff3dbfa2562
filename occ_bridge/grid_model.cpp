#include "grid_model.h"

#include <chrono>
#include <cmath>
#include <map>

#include <BRepGProp.hxx>
#include <GProp_GProps.hxx>

#include "common/error.h"
#include "occt_shape.h"

namespace parafab::occ {

namespace {

// Elements and adjacency of m.cut; `reused(s)` is a rule to reuse for subvolume s, or null.
template <class Reused>
void make_elements(GridModel& m, const GridModelOptions& o, const Reused& reused) {
  const auto t0 = std::chrono::steady_clock::now();
  const GridCut& g = *m.cut;
  std::map<std::array<int, 3>, int> interior;
  for (const auto& ijk : g.interior_cells) {
    xfem::GridElement e;
    e.cell = ijk;
    e.box = g.cell_box(ijk);
    e.rule = xfem::tensor_gauss_rule(e.box, o.interior_points);
    interior[ijk] = static_cast<int>(m.elements.size());
    m.elements.push_back(std::move(e));
  }
  const int first_cut = static_cast<int>(m.elements.size());
  for (const auto& sv : g.subvolumes) {
    xfem::GridElement e;
    e.box = sv.cell;
    const xfem::QuadratureRule3* rule = reused(static_cast<int>(m.elements.size()) - first_cut);
    e.rule = rule ? *rule : xfem::volume_rule(sv, o.rule).rule;
    e.subvolume = &sv;
    m.elements.push_back(std::move(e));
  }
  for (const auto& cell : g.cut_cells)
    for (int s : cell.subvolumes) m.elements[first_cut + s].cell = cell.index;
  // Adjacency: interior–interior neighbours, cut–cut and cut–interior connections.
  for (const auto& [ijk, e] : interior)
    for (int a = 0; a < 3; ++a) {
      std::array<int, 3> n = ijk;
      ++n[a];
      auto it = interior.find(n);
      if (it != interior.end()) m.adjacent.push_back({e, it->second});
    }
  for (const auto& [a, b] : g.connections) m.adjacent.push_back({first_cut + a, first_cut + b});
  for (const auto& [s, c] : g.interior_connections)
    m.adjacent.push_back({first_cut + s, interior.at(g.interior_cells[c])});
  m.rule_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  m.done = true;
}

}  // namespace

GridModel build_grid_model(const PartShape& part, const GridModelOptions& o) {
  GridModel m;
  const auto t0 = std::chrono::steady_clock::now();
  m.cut = std::make_unique<GridCut>(cut_by_grid(part, o.grid));
  m.cut_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  if (!m.cut->done) {
    m.message = m.cut->message;
    return m;
  }
  make_elements(m, o, [](int) -> const xfem::QuadratureRule3* { return nullptr; });
  if (m.cut->method == CutMethod::FaceCut) {
    // Safety net of the face route: the rules must hold OCCT's volume of the part; if not, the
    // part is cut again by the splitter and the reason kept.
    double volume = 0;
    for (const auto& e : m.elements)
      for (double w : e.rule.weights) volume += w;
    GProp_GProps props;
    BRepGProp::VolumeProperties(part.shape, props);
    if (std::abs(volume - props.Mass()) > 1e-6 * std::abs(props.Mass())) {
      GridModelOptions so = o;
      so.grid.method = CutMethod::Splitter;
      GridModel fallback = build_grid_model(part, so);
      fallback.cut->fallback_reason = "the face route's rules hold volume " + std::to_string(volume) +
                                      " against OCCT's " + std::to_string(props.Mass());
      fallback.cut_seconds += m.cut_seconds;
      return fallback;
    }
  }
  return m;
}

GridModel rebuild_grid_model(const PartShape& part, const GridModel& old, const PartShape& old_part,
                             const GridModelOptions& o, RecutReport* report) {
  PARAFAB_VERIFY(old.done, "rebuild_grid_model: the old model is not done");
  RecutReport local;
  RecutReport& r = report ? *report : local;
  GridModel m;
  const auto t0 = std::chrono::steady_clock::now();
  m.cut = std::make_unique<GridCut>(recut_by_grid(part, *old.cut, old_part, o.grid, &r));
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
  // Safety net: the rules must integrate the new part's volume (OCCT's). A change the dirty
  // regions missed would leave whole cells wrong; then the part is cut again whole.
  double volume = 0;
  for (const auto& e : m.elements)
    for (double w : e.rule.weights) volume += w;
  GProp_GProps props;
  BRepGProp::VolumeProperties(part.shape, props);
  if (std::abs(volume - props.Mass()) > 1e-6 * std::abs(props.Mass())) {
    r.verified = false;
    r.full = true;
    r.message = "the re-cut rules missed the new volume by " + std::to_string(volume - props.Mass()) +
                "; cut again whole";
    GridModelOptions fo = o;
    fo.grid.anchored = true;
    fo.grid.origin = old.cut->grid.min;
    fo.grid.cell_size = old.cut->cell_size.maxCoeff();
    GridModel full = build_grid_model(part, fo);
    full.cut_seconds += m.cut_seconds;
    return full;
  }
  return m;
}

}  // namespace parafab::occ
