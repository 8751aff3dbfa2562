#include "grid_model.h"

#include <chrono>
#include <map>

namespace parafab::occ {

GridModel build_grid_model(const PartShape& part, const GridModelOptions& o) {
  GridModel m;
  auto t0 = std::chrono::steady_clock::now();
  m.cut = std::make_unique<GridCut>(cut_by_grid(part, o.grid));
  m.cut_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  if (!m.cut->done) {
    m.message = m.cut->message;
    return m;
  }
  t0 = std::chrono::steady_clock::now();
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
    e.rule = xfem::volume_rule(sv, o.rule).rule;
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
  return m;
}

}  // namespace parafab::occ
