// Compliance C = fᵀu and its shape derivatives (thesis §6.5.3): by the rule derivatives of
// Eq. 6.30–6.31 (compliance_gradient: boundary integrals over the moving patches of the cut
// cells, one solve) and semi-analytic (central differences of the changed cut cells' element
// matrices, where a support's or load's patches move; see shape_compliance.h).
#include "shape_compliance.h"

#include <BRepAdaptor_Surface.hxx>
#include <Eigen/Geometry>
#include <BRepTools.hxx>
#include <BRep_Tool.hxx>
#include <Geom2d_Curve.hxx>
#include <TopoDS.hxx>
#include <TopExp.hxx>
#include <TopTools_IndexedDataMapOfShapeListOfShape.hxx>
#include <TopTools_ListOfShape.hxx>
#include <tbb/parallel_for.h>

#include <chrono>

#include <algorithm>
#include <array>
#include <cmath>
#include <map>
#include <optional>
#include <set>

#include "common/error.h"
#include "occt_shape.h"
#include "face_lookup.h"
#include "occt_mass_properties.h"
#include "part_reader.h"
#include "xfem/area_rules.h"
#include "xfem/curve_rules.h"
#include "xfem/nonlinear_xfem.h"
#include "xfem/quadrature_rule.h"

namespace parafab::occ {

namespace {

// The rules of every element together must integrate the part's volume (OCCT's): a cut that
// lost a piece (seen with the Boolean splitter on some perturbed bracket models, whole or
// re-cut) is refused instead of giving a wrong compliance or difference. `occt_volume`: OCCT's
// volume of `part` if already measured (rebuild_grid_model's RecutReport), else 0.
bool volume_matches(const GridModel& m, const PartShape& part, std::string& message, double& occt_volume) {
  double v = 0;
  for (const auto& e : m.elements)
    for (double w : e.rule.weights) v += w;
  if (!(occt_volume > 0)) occt_volume = occt_mass_properties(part).volume;
  const double ref = occt_volume;
  if (std::abs(v - ref) <= 1e-6 * std::abs(ref)) return true;
  message = "the grid cut's rules integrate a volume of " + std::to_string(v) + ", OCCT " + std::to_string(ref) +
            " (a cell piece was lost)";
  return false;
}

// The loads on `part`: total forces spread over the load face's area on this part.
std::vector<xfem::TractionCondition> tractions_on(const PartShape& part, const ComplianceSetup& setup) {
  std::vector<xfem::TractionCondition> t = setup.tractions;
  for (size_t i = 0; i < t.size() && i < setup.forces.size(); ++i)
    if (setup.forces[i].norm() > 0) t[i].traction = setup.forces[i] / face_area(part, t[i].face);
  return t;
}

ComplianceState solve_on(std::shared_ptr<const PartShape> part, GridModel&& model, const ComplianceSetup& setup,
                         double occt_volume = 0) {
  ComplianceState s;
  s.part = std::move(part);
  if (!model.done) {
    s.message = "the grid cut failed: " + model.message;
    return s;
  }
  if (!volume_matches(model, *s.part, s.message, occt_volume)) return s;
  s.occt_volume = occt_volume;
  auto m = std::make_shared<GridModel>(std::move(model));
  s.tractions = tractions_on(*s.part, setup);
  PARAFAB_VERIFY(!(setup.merge.enabled && setup.hyperelastic), "ComplianceSetup: merge (Eq. 6.24 ties) with a hyperelastic law, whose solve has no ties");
  if (setup.hyperelastic) {
    xfem::NonlinearXfemOptions no;
    no.boundary = setup.solver;
    no.load_steps = setup.load_steps;
    no.keep_factorization = true;
    const xfem::NonlinearXfemResult nr =
        xfem::solve_nonlinear(m->elements, m->adjacent, *setup.hyperelastic, setup.material, setup.dirichlet, s.tractions, no);
    s.model = std::move(m);
    if (!nr.converged) {
      s.message = "the hyperelastic XFEM solve failed: " + nr.message;
      return s;
    }
    s.solution = nr.as_linear();
    s.done = true;
    s.message = "ok";
    return s;
  }
  if (setup.merge.enabled && !m->elements.empty()) {  // Eq. 6.24: the gaps of pieces about to join, and their ties
    PieceGapOptions go;
    go.critical_distance = setup.merge.critical_fraction * m->elements.front().box.size().minCoeff();
    const PieceGapResult gr = piece_gaps(*s.part, *m, go);
    s.gap_seconds = gr.seconds;
    if (!gr.done) {
      s.model = std::move(m);
      s.message = "the merge penalty's gaps failed: " + gr.message;
      return s;
    }
    for (const PieceGap& gap : gr.gaps) {
      const std::vector<xfem::PieceTie> tie = piece_ties({gap}, *m, setup.material.youngs_modulus, setup.merge);
      if (tie.empty()) continue;
      s.gaps.push_back(gap);
      s.ties.push_back(tie[0]);
    }
  }
  s.solution = xfem::solve_linear(m->elements, m->adjacent, setup.material, setup.dirichlet, s.tractions, setup.solver, s.ties);
  s.model = std::move(m);
  if (!s.solution.solved) {
    s.message = "the linear XFEM solve failed: " + s.solution.message;
    return s;
  }
  // energy = ½uᵀKu − fᵀu and Ku = f at the solution (also with aggregation: u = T u_r), so
  // C = fᵀu = −2·energy.
  s.compliance = -2 * s.solution.energy;
  s.done = true;
  s.message = "ok";
  return s;
}

using Cell = std::array<int, 3>;

std::map<Cell, std::vector<int>> elements_by_cell(const GridModel& m) {
  std::map<Cell, std::vector<int>> by;
  for (size_t e = 0; e < m.elements.size(); ++e) by[m.elements[e].cell].push_back(static_cast<int>(e));
  return by;
}

// Rule centroid (box centre for an empty rule) and volume of an element.
std::pair<xfem::Vec3, double> centroid(const xfem::GridElement& el) {
  double w = 0;
  xfem::Vec3 c = xfem::Vec3::Zero();
  for (size_t i = 0; i < el.rule.points.size(); ++i) w += el.rule.weights[i], c += el.rule.weights[i] * el.rule.points[i];
  if (std::abs(w) < 1e-300) return {0.5 * (el.box.min + el.box.max), 0.0};
  return {c / w, w};
}

// The cells whose elements a re-cut (report r) may have changed: cells of new subvolumes and
// of old subvolumes not kept; every cell with a cut element when the cut was redone whole.
std::set<Cell> changed_cells(const GridModel& at, const GridModel& m, const RecutReport& r) {
  std::set<Cell> cells;
  const size_t at_first = at.elements.size() - at.cut->subvolumes.size();
  const size_t m_first = m.elements.size() - m.cut->subvolumes.size();
  if (r.full) {
    for (size_t e = at_first; e < at.elements.size(); ++e) cells.insert(at.elements[e].cell);
    for (size_t e = m_first; e < m.elements.size(); ++e) cells.insert(m.elements[e].cell);
    return cells;
  }
  std::vector<char> kept(at.cut->subvolumes.size(), 0);
  for (size_t s = 0; s < m.cut->subvolumes.size(); ++s) {
    const int k = s < r.kept_from.size() ? r.kept_from[s] : -1;
    if (k < 0) cells.insert(m.elements[m_first + s].cell);
    else kept[k] = 1;
  }
  for (size_t s = 0; s < kept.size(); ++s)
    if (!kept[s]) cells.insert(at.elements[at_first + s].cell);
  return cells;
}

// For every element of `base` (in order), the element of `other` in the same cell with the
// nearest centroid (greedy, each used once); empty if the counts differ.
std::vector<int> match(const GridModel& at, const std::vector<int>& base, const GridModel& m, const std::vector<int>& other) {
  if (base.size() != other.size()) return {};
  std::vector<int> out;
  std::vector<char> used(other.size(), 0);
  for (int b : base) {
    const xfem::Vec3 cb = centroid(at.elements[b]).first;
    int best = -1;
    double bd = 1e300;
    for (size_t j = 0; j < other.size(); ++j) {
      if (used[j]) continue;
      const double d = (centroid(m.elements[other[j]]).first - cb).norm();
      if (d < bd) bd = d, best = static_cast<int>(j);
    }
    used[best] = 1;
    out.push_back(other[best]);
  }
  return out;
}

// Gives `el` the frame of integrands outside the rules' span (xfem::GridElement::frame) of
// `from`, its match, unless el's own fitting box has left it: a side moved by more than a tenth
// of the own box's extent on that axis (a piece shrinking to a sliver: the field extended over a
// frame far larger than the piece overflows the failure metric's exponential). Then el keeps its
// own (a discrete switch, like a subvolume that appears).
void freeze_frame(xfem::GridElement& el, const xfem::GridElement& from) {
  el.frame.reset();
  if (!el.subvolume || !from.subvolume) return;
  const xfem::Box3 own = xfem::rule_box(el), F = xfem::rule_frame(from);
  const xfem::Vec3 slack = 0.1 * own.size();
  if (((F.min - own.min).cwiseAbs() - slack).maxCoeff() > 0 || ((F.max - own.max).cwiseAbs() - slack).maxCoeff() > 0) return;
  el.frame = F;
}

// Freezes the discrete switches of `m` at `from`: every cut element of `m` in a cell with as
// many elements in both (matched as the derivatives match them) switches on its match's
// switching fraction. Left to their own: cells whose element count changed (a subvolume appears
// or vanishes), elements uncut in `m` (the uncut reference element), and elements whose own
// fraction is below the incompatible-mode floor or more than half the aggregation threshold
// away from the match's (a big trial step: a sliver must not be treated as a normal element).
int freeze_switches(GridModel& m, const GridModel& from, const xfem::LinearXfemOptions& options) {
  const auto by_from = elements_by_cell(from), by_m = elements_by_cell(m);
  int frozen = 0;
  for (const auto& [cell, B] : by_from) {
    const auto it = by_m.find(cell);
    if (it == by_m.end() || it->second.size() != B.size()) continue;
    if (B.size() == 1 && !from.elements[B[0]].subvolume && !m.elements[it->second[0]].subvolume) continue;  // uncut
    const std::vector<int> matched = match(from, B, m, it->second);
    for (size_t i = 0; i < B.size(); ++i) {
      xfem::GridElement& el = m.elements[matched[i]];
      // The frame of integrands outside the rules' span, for every matched pair of cut elements.
      freeze_frame(el, from.elements[B[i]]);
      const double own = xfem::volume_fraction(el), other = xfem::switching_fraction(from.elements[B[i]]);
      if (!el.subvolume || own < options.incompatible_min_fraction ||
          std::abs(own - other) > 0.5 * options.aggregation_fraction)
        continue;
      el.switch_fraction = other;
      ++frozen;
    }
  }
  return frozen;
}

}  // namespace

ComplianceState compliance_start(std::shared_ptr<const PartShape> part, const ComplianceSetup& setup) {
  PARAFAB_VERIFY(setup.grid.grid.block_cells > 0, "compliance: grid.block_cells must be > 0 (the re-cut works by blocks)");
  PARAFAB_VERIFY(!setup.dirichlet.empty(), "compliance: the job needs supports");
  // The grid of the whole run gets a margin of at least a quarter cell on every side, so that
  // a part that grows a little stays inside it (leaving it forces a whole re-cut).
  GridModelOptions go = setup.grid;
  if (!go.grid.anchored) {
    const PartBox box = part_box(*part);
    const xfem::Vec3 ext = box.max - box.min, mid = 0.5 * (box.max + box.min);
    const double h = go.grid.cell_size > 0 ? go.grid.cell_size : ext.maxCoeff() / std::max(1, go.grid.cells_longest);
    go.grid.cell_size = h;
    go.grid.anchored = true;
    for (int a = 0; a < 3; ++a) go.grid.origin[a] = mid[a] - 0.5 * h * std::ceil(ext[a] / h + 0.5);
  }
  GridModel m = build_grid_model(*part, go);
  return solve_on(std::move(part), std::move(m), setup);
}

// Re-cuts keep the base grid's planes (GridOptions::recut_clearance): a plane a fresh cut would
// shift off a face extreme jumps over it as the extreme crosses (1.5e-4 of a cell each way), a
// jump of C the ties of Eq. 6.24 cannot smooth (PieceGaps.MergePenaltyAtASlotTipCrossingAGridPlane).
static GridModelOptions kept_planes(GridModelOptions o) {
  if (!(o.grid.recut_clearance > 0)) o.grid.recut_clearance = 1e-8;
  return o;
}

ComplianceState compliance_at(std::shared_ptr<const PartShape> part, const ComplianceState& base,
                              const ComplianceSetup& setup, const GridModel* switches_from) {
  PARAFAB_VERIFY(base.done && base.model, "compliance_at: the base state is not solved");
  RecutReport r;
  GridModel m = rebuild_grid_model(*part, *base.model, *base.part, kept_planes(setup.grid), &r);
  const int frozen = switches_from && m.done ? freeze_switches(m, *switches_from, setup.solver) : 0;
  ComplianceState s = solve_on(std::move(part), std::move(m), setup, r.occt_volume);  // OCCT's volume measured once
  s.recut_full = r.full;
  s.frozen_elements = frozen;
  if (frozen > 0 && s.model)
    s.switches_own = xfem::switches_match_own_fractions(s.model->elements, s.model->adjacent, setup.solver);
  if (s.model)
    for (const xfem::GridElement& el : s.model->elements)
      if (el.frame) {
        const xfem::Box3 a = *el.frame, b = xfem::rule_box(el);
        const double tol = 1e-9 * el.box.size().maxCoeff();
        if (((a.min - b.min).cwiseAbs().array() > tol).any() || ((a.max - b.max).cwiseAbs().array() > tol).any()) {
          s.frames_own = false;
          break;
        }
      }
  return s;
}

ComplianceState compliance_own_switches(std::shared_ptr<const PartShape> part, const GridModel& model,
                                        double occt_volume, const ComplianceSetup& setup) {
  PARAFAB_VERIFY(part && model.done && occt_volume > 0,
                 "compliance_own_switches: needs a solved state's part, model and OCCT volume (volume " << occt_volume << ")");
  GridModel m = model;
  for (xfem::GridElement& el : m.elements) el.switch_fraction = -1, el.frame.reset();
  return solve_on(std::move(part), std::move(m), setup, occt_volume);
}

ComplianceState compliance_own_frames(const ComplianceState& state) {
  PARAFAB_VERIFY(state.done && state.model && state.switches_own,
                 "compliance_own_frames: needs a solved state on its own switches");
  ComplianceState r = state;
  auto m = std::make_shared<GridModel>(*state.model);
  for (xfem::GridElement& el : m->elements) el.frame.reset();
  r.model = std::move(m);
  r.frames_own = true;
  return r;
}

ComplianceDerivative element_difference(const ComplianceState& at, std::shared_ptr<const PartShape> plus,
                                        std::shared_ptr<const PartShape> minus, double h, const ComplianceSetup& setup,
                                        const ElementTerm& term, const PairTerm& pair_term) {
  ComplianceDerivative d;
  PARAFAB_VERIFY(at.done && at.model, "element_difference: the state is not solved");
  PARAFAB_VERIFY(h > 0, "element_difference: step must be positive, got " << h);
  if (!plus && !minus) {
    d.message = "neither perturbed model exists";
    return d;
  }
  // Both perturbed models on the grid of `at` (grid planes and, through the kept blocks, the
  // fitting frames of every untouched cell fixed).
  GridModel models[2];
  std::set<Cell> cells;
  const std::shared_ptr<const PartShape> parts[2] = {plus, minus};
  bool have[2] = {false, false};
  std::vector<xfem::TractionCondition> side_tractions[2];
  for (int side = 0; side < 2; ++side) {
    if (!parts[side]) continue;
    RecutReport r;
    models[side] = rebuild_grid_model(*parts[side], *at.model, *at.part, kept_planes(setup.grid), &r);
    std::string why;
    if (!models[side].done || !volume_matches(models[side], *parts[side], why, r.occt_volume)) {
      d.message += (side ? "minus side: " : "plus side: ") + (models[side].done ? why : models[side].message) + "; ";
      continue;
    }
    have[side] = true;
    side_tractions[side] = tractions_on(*parts[side], setup);
    const std::set<Cell> c = changed_cells(*at.model, models[side], r);
    cells.insert(c.begin(), c.end());
  }
  if (!have[0] && !have[1]) {
    d.message = "the perturbed models could not be cut: " + d.message;
    return d;
  }
  // A load given as a total force has another traction on each side when its face's area
  // changes: then every cell with a patch on that face changes its load, re-cut or not.
  std::set<int> load_faces;
  for (size_t i = 0; i < at.tractions.size(); ++i)
    for (int side = 0; side < 2; ++side)
      if (have[side] && side_tractions[side][i].traction != at.tractions[i].traction) load_faces.insert(at.tractions[i].face);
  if (!load_faces.empty())
    for (const xfem::GridElement& el : at.model->elements)
      if (el.subvolume)
        for (const xfem::CutPatch& p : el.subvolume->patches)
          if (load_faces.count(p.source_face)) cells.insert(el.cell);
  const auto by_at = elements_by_cell(*at.model);
  std::map<Cell, std::vector<int>> by[2];
  for (int side = 0; side < 2; ++side)
    if (have[side]) by[side] = elements_by_cell(models[side]);
  const std::vector<int> none;
  auto list = [&](const std::map<Cell, std::vector<int>>& m, const Cell& c) -> const std::vector<int>& {
    const auto it = m.find(c);
    return it == m.end() ? none : it->second;
  };
  // Work items: (side, element of the perturbed model, element of `at` whose DOFs it uses, weight).
  struct Item {
    int side, element, base;
    double weight;  ///< ±1/(2h) (central) or ±1/h (one-sided); side −1: the element of `at`
  };
  std::vector<Item> items;
  std::map<Cell, std::array<bool, 2>> cell_ok;
  std::map<int, int> perturbed_of[2];  // element of `at` → its match in a perturbed model
  for (const Cell& c : cells) {
    const std::vector<int>& B = list(by_at, c);
    std::vector<int> matched[2];
    bool ok[2] = {false, false};
    for (int side = 0; side < 2; ++side)
      if (have[side]) {
        const std::vector<int>& P = list(by[side], c);
        ok[side] = P.size() == B.size();
        if (ok[side]) matched[side] = match(*at.model, B, models[side], P);
      }
    if ((have[0] && !ok[0]) || (have[1] && !ok[1])) {
      ++d.topology_switches;
    }
    cell_ok[c] = {ok[0], ok[1]};
    for (int side = 0; side < 2; ++side)
      if (ok[side])
        for (size_t i = 0; i < B.size(); ++i) perturbed_of[side][B[i]] = matched[side][i];
    if (B.empty()) continue;
    ++d.cells_changed;
    // The perturbed elements switch (incompatible modes) as their element of `at` does, and
    // integrate on its frame.
    for (int side = 0; side < 2; ++side)
      if (ok[side])
        for (size_t i = 0; i < B.size(); ++i) {
          xfem::GridElement& el = models[side].elements[matched[side][i]];
          el.switch_fraction = xfem::switching_fraction(at.model->elements[B[i]]);
          freeze_frame(el, at.model->elements[B[i]]);
        }
    for (size_t i = 0; i < B.size(); ++i) {
      if (ok[0] && ok[1]) {
        items.push_back({0, matched[0][i], B[i], 1 / (2 * h)});
        items.push_back({1, matched[1][i], B[i], -1 / (2 * h)});
      } else if (ok[0]) {
        items.push_back({0, matched[0][i], B[i], 1 / h});
        items.push_back({-1, B[i], B[i], -1 / h});
      } else if (ok[1]) {
        items.push_back({-1, B[i], B[i], 1 / h});
        items.push_back({1, matched[1][i], B[i], -1 / h});
      }
    }
  }
  std::vector<double> terms(items.size(), 0.0);
  tbb::parallel_for(size_t(0), items.size(), [&](size_t i) {
    const Item& it = items[i];
    const xfem::GridElement& el = it.side < 0 ? at.model->elements[it.element] : models[it.side].elements[it.element];
    const auto& tractions = it.side < 0 ? at.tractions : side_tractions[it.side];
    terms[i] = it.weight * term(el, tractions, it.base);
  });
  for (double t : terms) d.derivative += t;  // in item order: deterministic
  // Mode-tied pairs in changed cells (their weight and blend held at `at`'s).
  if (pair_term && !at.ties.empty()) {
    const std::vector<char> modes = xfem::mode_tied(at.model->elements, at.ties, setup.material, setup.solver);
    for (size_t t = 0; t < at.ties.size(); ++t) {
      const xfem::PieceTie& tie = at.ties[t];
      const auto it = cell_ok.find(at.model->elements[tie.element_a].cell);
      if (!modes[t] || it == cell_ok.end()) continue;
      const auto [ok0, ok1] = it->second;
      auto value = [&](int side) {  // −1: `at`'s own pair
        if (side < 0) return pair_term(at.model->elements[tie.element_a], at.model->elements[tie.element_b], tie);
        const auto& els = models[side].elements;
        return pair_term(els[perturbed_of[side].at(tie.element_a)], els[perturbed_of[side].at(tie.element_b)], tie);
      };
      if (ok0 && ok1) d.derivative += (value(0) - value(1)) / (2 * h);
      else if (ok0) d.derivative += (value(0) - value(-1)) / h;
      else if (ok1) d.derivative += (value(-1) - value(1)) / h;
    }
  }
  d.done = true;
  d.one_sided = !(have[0] && have[1]);
  d.message = d.message.empty() ? "ok" : d.message + "one-sided difference";
  return d;
}

ComplianceDerivative compliance_derivative(const ComplianceState& at, std::shared_ptr<const PartShape> plus,
                                           std::shared_ptr<const PartShape> minus, double h,
                                           const ComplianceSetup& setup) {
  PARAFAB_VERIFY(at.done && at.model, "compliance_derivative: the state is not solved");
  // Each term: 2uₑ·fₑ − uₑᵀKₑuₑ with uₑ the solution at the element's DOF nodes in `at`.
  return element_difference(at, std::move(plus), std::move(minus), h, setup,
                            [&](const xfem::GridElement& el, const std::vector<xfem::TractionCondition>& tractions,
                                int base) {
                              const xfem::ElementSystem es =
                                  xfem::element_system(el, setup.material, setup.dirichlet, tractions, setup.solver);
                              const Eigen::VectorXd ue = element_values(at.solution.u, at.solution.node[base]);
                              return 2 * ue.dot(es.f) - ue.dot(es.K * ue);
                            },
                            // A mode-tied pair: −uᵀ C u with C its joint condensation's correction.
                            [&](const xfem::GridElement& a, const xfem::GridElement& b, const xfem::PieceTie& tie) {
                              Eigen::VectorXd u(48);
                              u << element_values(at.solution.u, at.solution.node[tie.element_a]),
                                  element_values(at.solution.u, at.solution.node[tie.element_b]);
                              return -u.dot(xfem::tied_mode_correction(a, b, tie, setup.material, setup.solver) * u);
                            });
}

namespace {

// Σ N_k(X) v_k over an element's nodes (8 or 27, by v's size): the field the solve's load sees.
xfem::Vec3 nodal_field(const xfem::GridElement& el, const Eigen::VectorXd& v, const xfem::Vec3& X) {
  xfem::Vec3 d = xfem::Vec3::Zero();
  if (v.size() == 3 * 27) {
    Eigen::Matrix<double, 27, 1> N;
    Eigen::Matrix<double, 27, 3> G;
    xfem::triquadratic_shape(el.box, X, N, G);
    for (int k = 0; k < 27; ++k) d += N(k) * v.segment<3>(3 * k);
  } else {
    Eigen::Matrix<double, 8, 1> N;
    Eigen::Matrix<double, 8, 3> G;
    xfem::trilinear_shape(el.box, X, N, G);
    for (int k = 0; k < 8; ++k) d += N(k) * v.segment<3>(3 * k);
  }
  return d;
}

// Sign s of a face's implicit function: ∇φ·n_out = s|∇φ| over the face (φ of its parameter block
// at p; constant on a face). Evaluated at the centre of its uv bounds.
double implicit_sign(const PartShape& part, int face, const optimize::ParameterBlock& block, const Eigen::VectorXd& p) {
  const TopoDS_Face& original = part.face(face);
  const double orient = original.Orientation() == TopAbs_REVERSED ? -1.0 : 1.0;
  const TopoDS_Face forward = TopoDS::Face(original.Oriented(TopAbs_FORWARD));
  const BRepAdaptor_Surface surface(forward, false);
  double u0, u1, v0, v1;
  BRepTools::UVBounds(forward, u0, u1, v0, v1);
  gp_Pnt P;
  gp_Vec du, dv;
  surface.D1(0.5 * (u0 + u1), 0.5 * (v0 + v1), P, du, dv);
  const gp_Vec N = du.Crossed(dv);
  const optimize::Dual phi = optimize::implicit_function(block.kind, p.data() + block.offset, xfem::Vec3(P.X(), P.Y(), P.Z()));
  const int nb = block.size();
  const double dot = orient * (phi.g[nb] * N.X() + phi.g[nb + 1] * N.Y() + phi.g[nb + 2] * N.Z());
  return dot >= 0 ? 1.0 : -1.0;
}

}  // namespace

namespace {

// The exact route of compliance_gradient (adj null: J = C, λ = −u, load weight z = 2u, as
// written before the adjoint form, to the last bit) and of adjoint_shape_gradient (adj: λ given,
// z = −λ, J's own density on the moving patches). `who` names the caller in errors.
ComplianceGradient shape_gradient(const ComplianceState& at, const ComplianceSetup& setup, const ShapeParameters& sp,
                                  const Eigen::VectorXd& p, const std::vector<char>* moving, const ShapeAdjoint* adj,
                                  const char* who) {
  const auto t0 = std::chrono::steady_clock::now();
  PARAFAB_VERIFY(at.done && at.model, who << ": the state is not solved");
  PARAFAB_VERIFY(p.size() == sp.size(), who << ": p has " << p.size() << " entries, the parameters " << sp.size());
  const PartShape& part = *at.part;
  PARAFAB_VERIFY(static_cast<int>(sp.block_of_face.size()) == part.face_count(),
                 who << ": the parameters describe " << sp.block_of_face.size() << " faces, the part has "
                     << part.face_count());
  PARAFAB_VERIFY(!moving || static_cast<int>(moving->size()) == sp.size(),
                 who << ": `moving` has " << moving->size() << " entries, p " << sp.size());
  PARAFAB_VERIFY(!adj || adj->lambda.size() == at.solution.u.size(),
                 who << ": an adjoint of size " << (adj ? adj->lambda.size() : 0) << ", the state has "
                     << at.solution.u.size() << " unknowns");
  PARAFAB_VERIFY(!adj || !setup.hyperelastic, who << ": the adjoint form is built for linear elasticity only");
  ComplianceGradient r;
  r.gradient = Eigen::VectorXd::Zero(sp.size());
  r.incomplete.assign(sp.size(), 0);
  // Faces whose motion is wanted: some entry of their block (or pole block) is `moving`.
  std::vector<char> face_moves(part.face_count(), 1);
  if (moving)
    for (int f = 0; f < part.face_count(); ++f) {
      int offset = 0, size = 0;
      if (const optimize::ParameterBlock* b = sp.block(f)) offset = b->offset, size = b->size();
      else if (const PoleBlock* pb = sp.poles(f)) offset = pb->offset, size = pb->size();
      face_moves[f] = std::any_of(moving->begin() + offset, moving->begin() + offset + size, [](char m) { return m != 0; });
    }
  auto flag = [&](int face) {
    if (const optimize::ParameterBlock* b = sp.block(face))
      for (int k = 0; k < b->size(); ++k) r.incomplete[b->offset + k] = 1;
    if (const PoleBlock* b = sp.poles(face))
      for (int k = 0; k < b->size(); ++k) r.incomplete[b->offset + k] = 1;
  };
  // Supports and loads, and the faces sharing an edge with one of them: when such a neighbour
  // moves, the support's or load's patch gains or loses a strip along that edge. A support's or
  // load's own motion is differentiated below where its face is analytic, carries one kind of
  // condition (not a support and a load), a support's value is not a `field`, and every face
  // across its edges has a parameter block (whose normal gives the edge's slide) and carries no
  // condition (a neighbouring support's or load's patch would gain a strip not computed here).
  // Those that fail this are flagged.
  std::set<int> conditioned;
  for (const auto& d : setup.dirichlet) conditioned.insert(d.face);
  for (const auto& t : at.tractions) conditioned.insert(t.face);
  // The local Nitsche penalty (xfem::LinearXfemOptions::NitschePenalty::Local) of a clamped cut
  // cell is κΛ, Λ the top eigenvalue of that cell's flux matrix B against its bulk stiffness Â,
  // so it changes with every face that cuts the cell: dΛ = vᵀdBv − Λ vᵀdÂv (xfem::LocalPenaltyParts),
  // vᵀdÂv by Reynolds over the moving patches as the bulk term below, vᵀdBv along the clamped
  // patch's moving edges as the strip terms; then C changes by κ dΛ (2uᵀg − uᵀPu). Where Λ is
  // not a simple eigenvalue (gap ≤ 1e-6) the cell's moving faces are flagged instead (on a
  // B-spline face, the poles whose basis functions reach its patches): the optimizer then takes
  // the semi-analytic route, which re-evaluates whole element systems, penalty included.
  const bool local_penalty = setup.solver.nitsche_penalty == xfem::LinearXfemOptions::NitschePenalty::Local;
  std::set<int> supports;
  for (const auto& d : setup.dirichlet) supports.insert(d.face);
  std::map<int, std::vector<int>> neighbours;  // support/load face → moving faces sharing an edge with it
  std::map<int, std::vector<int>> own_sides;  // support or load whose own motion is differentiated → faces across its edges
  std::vector<double> sign(part.face_count(), 0.0);
  // J's own surface integral over F (the target objective): the faces across F's edges whose
  // motion slides them (`surface_sides`, with parameter blocks), and whether F's own motion is
  // differentiated (an analytic F whose every neighbour has a block: its normal gives the slide).
  const int surface_face = adj && adj->surface_density ? adj->surface_face : -1;
  PARAFAB_VERIFY(surface_face < part.face_count(), who << ": the surface density's face " << surface_face
                                                        << " is outside 0.." << part.face_count() - 1);
  std::vector<int> surface_sides;
  bool surface_own = false;
  {
    TopTools_IndexedDataMapOfShapeListOfShape edge_faces;
    TopExp::MapShapesAndAncestors(part.shape, TopAbs_EDGE, TopAbs_FACE, edge_faces);
    std::map<int, std::set<int>> sets, sides;
    std::set<int> refused;  // supports and loads with a neighbour that has no block or carries a condition
    std::set<int> surface_neighbours;
    // A B-spline face f next to a support or load (or F): the poles whose basis functions reach
    // the shared edge i move it (a strip term not computed here), flagged; the others (interior
    // poles of a clamped surface whose edges are its iso-boundaries) leave the edge in place and
    // are exact. Checked at 16 points of the edge's pcurve per knot span of the surface.
    const auto flag_edge_poles = [&](int i, int f) {
      const PoleBlock* pb = sp.poles(f);
      if (!pb) return;
      double t0, t1;
      const Handle(Geom2d_Curve) pc = BRep_Tool::CurveOnSurface(TopoDS::Edge(edge_faces.FindKey(i)), part.face(f), t0, t1);
      if (pc.IsNull()) {
        flag(f);
        return;
      }
      const int samples = 16 * (pb->surface.count_u - pb->surface.degree_u + pb->surface.count_v - pb->surface.degree_v);
      for (int k = 0; k <= samples; ++k) {
        const gp_Pnt2d uv = pc->Value(t0 + (t1 - t0) * k / samples);
        for (const PoleInfluence& w : pole_influence(pb->surface, uv.X(), uv.Y()))
          if (std::abs(w.value) > 1e-12)
            for (int c = 0; c < 3; ++c) r.incomplete[pb->offset + 3 * w.index + c] = 1;
      }
    };
    for (int i = 1; i <= edge_faces.Extent(); ++i) {
      std::vector<int> faces;
      for (TopTools_ListOfShape::Iterator it(edge_faces(i)); it.More(); it.Next()) faces.push_back(part.face_index(it.Value()));
      for (int g : faces)
        if (conditioned.count(g))
          for (int f : faces) {
            if (f != g) {
              if (!sp.block(f) || conditioned.count(f)) refused.insert(g);
              else sides[g].insert(f);
            }
            if (f != g && sp.block(f) && !conditioned.count(f)) sets[g].insert(f);
            if (f != g && !conditioned.count(f)) flag_edge_poles(i, f);
          }
      if (surface_face >= 0 && std::count(faces.begin(), faces.end(), surface_face))
        for (int f : faces)
          if (f != surface_face) {
            surface_neighbours.insert(f);
            flag_edge_poles(i, f);
          }
    }
    if (surface_face >= 0) {
      surface_own = sp.block(surface_face) != nullptr;
      for (int f : surface_neighbours) {
        if (!sp.block(f)) {
          surface_own = false;
          continue;
        }
        surface_sides.push_back(f);
        if (sign[f] == 0) sign[f] = implicit_sign(part, f, *sp.block(f), p);
      }
      if (!surface_own) flag(surface_face);
    }
    for (auto& [g, fs] : sets) {
      neighbours[g].assign(fs.begin(), fs.end());
      for (int f : fs)
        if (sign[f] == 0) sign[f] = implicit_sign(part, f, *sp.block(f), p);
    }
    std::set<int> loaded, fields;
    for (const auto& t : at.tractions) loaded.insert(t.face);
    for (const auto& d : setup.dirichlet)
      if (d.field) fields.insert(d.face);
    for (int g : conditioned) {
      if ((supports.count(g) && loaded.count(g)) || fields.count(g) || !sp.block(g) || refused.count(g)) flag(g);
      else own_sides[g].assign(sides[g].begin(), sides[g].end());
    }
  }
  // Loads given as total forces: traction F/A, so a change of the face's area A changes it.
  std::vector<int> spread;  // load indices with a force
  std::vector<double> load_area(at.tractions.size(), 0.0);
  for (size_t i = 0; i < at.tractions.size() && i < setup.forces.size(); ++i)
    if (setup.forces[i].norm() > 0) {
      spread.push_back(static_cast<int>(i));
      load_area[i] = setup.forces[i].norm() / at.tractions[i].traction.norm();
    }
  // Cut elements with a patch on a face that has parameters or on a support or load.
  const std::vector<xfem::GridElement>& elements = at.model->elements;
  std::vector<int> work;
  for (size_t e = 0; e < elements.size(); ++e)
    if (elements[e].subvolume)
      for (const xfem::CutPatch& patch : elements[e].subvolume->patches)
        if (sp.block(patch.source_face) || sp.poles(patch.source_face) || conditioned.count(patch.source_face) ||
            patch.source_face == surface_face) {
          work.push_back(static_cast<int>(e));
          break;
        }
  // The integrand ψ Vₙ is a polynomial of degree ≤ 4 (hex8) or 8 (hex27) per coordinate times a
  // velocity of degree ≤ 1 on planar patches; curved patches refine on their area.
  xfem::SurfaceRuleOptions so;
  so.area.degree = setup.solver.element == xfem::ElementType::Hex27 ? 10 : 6;
  so.refinement = xfem::RefinementOptions{1e-10, true, 6, 4};
  // A support's own motion integrates ∂ₙ(σ(u)n·u)-like densities: on a curved support degree 6
  // left 1e-4 of the derivative (the turned bracket's hole, the countersink: measured against
  // the pipeline's differences with its patch rules at degree 12), degree 10 agrees to 1e-6.
  xfem::SurfaceRuleOptions so_support = so;
  so_support.area.degree = setup.solver.element == xfem::ElementType::Hex27 ? 14 : 10;
  const xfem::QuadratureRule1& gauss = xfem::gauss_legendre(8);
  const bool gravity = setup.material.density != 0 && setup.solver.gravity.squaredNorm() > 0;
  struct Terms {
    std::vector<std::pair<int, double>> gradient;   // (entry of p, dC/dp contribution)
    std::vector<std::pair<int, double>> area;       // (load index · size(p) + entry, dA contribution)
    std::vector<std::pair<int, double>> work;       // (load index, ∫ z_h·t dA)
    std::vector<int> tangent;                       // faces met at a tangent edge of a support/load (or a moving load's own)
    std::vector<int> penalised;                     // moving faces in a cut cell with a local penalty
    std::set<int> penalised_poles;                  // entries of p: poles moving such a cell's patch
    int points = 0, edge_points = 0;
    bool used = false;
  };
  std::vector<Terms> terms(work.size());
  const int np = sp.size();
  // Pieces whose incompatible modes a tie condenses jointly: their ψ is the pair's.
  const std::vector<char> modes_tied = xfem::mode_tied(elements, at.ties, setup.material, setup.solver);
  std::map<int, std::pair<int, int>> tied_side;  // element → (tie, 0 for element_a, 1 for element_b)
  for (size_t t = 0; t < at.ties.size(); ++t)
    if (modes_tied[t]) {
      tied_side[at.ties[t].element_a] = {static_cast<int>(t), 0};
      tied_side[at.ties[t].element_b] = {static_cast<int>(t), 1};
    }
  // `own`: the element's BulkShapeDensity, built on its first moving patch and kept for the rest.
  auto bulk_density = [&](int e, const Eigen::VectorXd& ue, const std::vector<xfem::Vec3>& points,
                          std::optional<xfem::BulkShapeDensity>& own) {
    const auto it = tied_side.find(e);
    if (it == tied_side.end()) {
      if (!own) own.emplace(elements[e], ue, ue, setup.material, setup.solver);
      return (*own)(points);
    }
    const xfem::PieceTie& tie = at.ties[it->second.first];
    return xfem::tied_mode_shape_terms(elements, tie, element_values(at.solution.u, at.solution.node[tie.element_a]),
                                       element_values(at.solution.u, at.solution.node[tie.element_b]), setup.material,
                                       setup.solver, it->second.second, points)
        .density;
  };
  // The density of dJ on a moving patch, times Vₙ: −ψ(u, u) + 2ρg·u for the compliance;
  // ψ(λ, u) − ρg·λ + j (J's own density) for an adjoint (a mode-tied pair's ψ(λ, u) by
  // polarization of its quadratic form: ¼[ψ(u + λ) − ψ(u − λ)]).
  auto moving_density = [&](int e, const Eigen::VectorXd& ue, const Eigen::VectorXd& le,
                            const std::vector<xfem::Vec3>& points, std::optional<xfem::BulkShapeDensity>& own) {
    std::vector<double> d(points.size(), 0.0);
    if (points.empty()) return d;
    if (!adj) {
      const std::vector<double> psi = bulk_density(e, ue, points, own);
      for (size_t q = 0; q < points.size(); ++q) {
        d[q] = -psi[q];
        if (gravity) d[q] += 2 * setup.material.density * setup.solver.gravity.dot(at.solution.displacement(elements, e, points[q]));
      }
      return d;
    }
    std::vector<double> psi;
    const auto it = tied_side.find(e);
    if (it == tied_side.end()) {
      if (!own) own.emplace(elements[e], le, ue, setup.material, setup.solver);
      psi = (*own)(points);
    } else {
      const xfem::PieceTie& tie = at.ties[it->second.first];
      const std::vector<int>& na = at.solution.node[tie.element_a], &nb = at.solution.node[tie.element_b];
      const Eigen::VectorXd ua = element_values(at.solution.u, na), ub = element_values(at.solution.u, nb);
      const Eigen::VectorXd la = element_values(adj->lambda, na), lb = element_values(adj->lambda, nb);
      const std::vector<double> plus = xfem::tied_mode_shape_terms(elements, tie, ua + la, ub + lb, setup.material,
                                                                   setup.solver, it->second.second, points).density;
      const std::vector<double> minus = xfem::tied_mode_shape_terms(elements, tie, ua - la, ub - lb, setup.material,
                                                                    setup.solver, it->second.second, points).density;
      psi.resize(points.size());
      for (size_t q = 0; q < points.size(); ++q) psi[q] = 0.25 * (plus[q] - minus[q]);
    }
    const std::vector<double> own_density = adj->density ? adj->density(e, points) : std::vector<double>(points.size(), 0.0);
    PARAFAB_VERIFY(own_density.size() == points.size(),
                   who << ": the objective's density gives " << own_density.size() << " values for " << points.size() << " points");
    for (size_t q = 0; q < points.size(); ++q) {
      d[q] = psi[q] + own_density[q];
      if (gravity) d[q] -= setup.material.density * setup.solver.gravity.dot(nodal_field(elements[e], le, points[q]));
    }
    return d;
  };
  // The face of `faces` on whose surface a patch's loop segment lies (its ends and middle within
  // `tol` of the face's implicit zero set), or −1.
  auto segment_face = [&](const xfem::CutPatch& patch, const xfem::CurveSegment2& seg, const std::vector<int>& faces,
                          double tol) {
    for (int f : faces) {
      const optimize::ParameterBlock& b = *sp.block(f);
      const int nb = b.size();
      bool all = true;
      for (const xfem::Vec2& uv : {seg.start, seg.position(0.5), seg.end}) {
        xfem::Vec3 X, Xu, Xv;
        patch.surface->evaluate(uv.x(), uv.y(), X, Xu, Xv);
        const optimize::Dual phi = optimize::implicit_function(b.kind, p.data() + b.offset, X);
        const double gn = xfem::Vec3(phi.g[nb], phi.g[nb + 1], phi.g[nb + 2]).norm();
        if (!(gn > 0) || std::abs(phi.v) / gn > tol) { all = false; break; }
      }
      if (all) return f;
    }
    return -1;
  };
  // The cell wall (axis 0, 1, 2) on which a patch's loop segment lies (its ends and middle within
  // `tol` of one face of `box`), or −1.
  // A patch lying in a wall (its normal along the wall's) has no edge sliding along it.
  auto segment_wall = [&](const xfem::CutPatch& patch, const xfem::CurveSegment2& seg, const xfem::Box3& box, double tol) {
    xfem::Vec3 M, Mu, Mv;
    const xfem::Vec2 mid = seg.position(0.5);
    patch.surface->evaluate(mid.x(), mid.y(), M, Mu, Mv);
    const xfem::Vec3 normal = Mu.cross(Mv).normalized();
    for (int c = 0; c < 3; ++c)
      for (const double wall : {box.min[c], box.max[c]}) {
        if (std::abs(normal[c]) > 0.999) continue;
        bool all = true;
        for (const xfem::Vec2& uv : {seg.start, seg.position(0.5), seg.end}) {
          xfem::Vec3 X, Xu, Xv;
          patch.surface->evaluate(uv.x(), uv.y(), X, Xu, Xv);
          if (std::abs(X[c] - wall) > tol) { all = false; break; }
        }
        if (all) return c;
      }
    return -1;
  };
  // The own motion's edge term of a support's, load's (or F's) patch: Γ's edges slide along the
  // faces across them (`sides`), and with `walls` its piece's edges slide along the cell's walls.
  // At each Gauss point of such a loop segment, visit(X, n_Γ, α, ds) with α_k =
  // −Vₙ,k (n_Γ·n_F)/(ν·n_F) per entry of Γ's block (ν the outward conormal). Returns false (and
  // visits nothing more) where Γ runs (nearly) tangent into F (|n_F·ν| < 0.2) or along a wall
  // (< 0.05): the slide is ill-posed there. With `spine`, a plane Γ into which a swept F (a
  // fillet) runs tangent is the exception: with the tangency kept the edge is the foot on Γ of
  // F's spine point S, E = S − φ_Γ(S) n_Γ/|n_Γ|², so α_k = ν·∂E/∂p_k = −φ_Γ(S) ν·∂n_Γ/∂p_k/|n_Γ|²
  // (ν ⊥ n_Γ; ν·∂n_Γ/∂p_k = ∂φ_Γ/∂p_k(X + ν) − ∂φ_Γ/∂p_k(X), φ_Γ linear in X); F's own share
  // is its strip (ν·∂S/∂p of F's entries).
  auto own_edges = [&](const xfem::CutPatch& patch, const xfem::Box3& box, const optimize::ParameterBlock& b,
                       const std::vector<int>& sides, bool walls, bool spine,
                       const std::function<void(const xfem::Vec3&, const xfem::Vec3&, const std::vector<double>&, double)>& visit) {
    const double h = box.size().minCoeff();
    const int nb = b.size();
    std::vector<double> alpha(nb);
    for (const xfem::UvLoop& loop : xfem::to_uv_loops(patch.loops))
      for (const xfem::CurveSegment2& seg : loop) {
        const int on = segment_face(patch, seg, sides, 1e-6 * h);
        const int wall = on < 0 && walls ? segment_wall(patch, seg, box, 1e-6 * h) : -1;
        if (on < 0 && wall < 0) continue;
        const optimize::ParameterBlock* bf = on >= 0 ? sp.block(on) : nullptr;
        for (size_t q = 0; q < gauss.points.size(); ++q) {
          xfem::Vec3 X, Xu, Xv;
          const double t = gauss.points[q];
          const xfem::Vec2 uv = seg.position(t), duv = seg.derivative(t);
          patch.surface->evaluate(uv.x(), uv.y(), X, Xu, Xv);
          const xfem::Vec3 dX = Xu * duv.x() + Xv * duv.y();
          const double speed = dX.norm();
          if (!(speed > 0)) continue;
          const xfem::Vec3 n_uv = Xu.cross(Xv).normalized();
          const xfem::Vec3 conormal = (dX / speed).cross(n_uv);  // outward: the region is on the left
          const xfem::Vec3 n_g = patch.orientation * n_uv;
          xfem::Vec3 n_f = xfem::Vec3::Unit(std::max(wall, 0));
          if (bf) {
            const int nf = bf->size();
            const optimize::Dual phf = optimize::implicit_function(bf->kind, p.data() + bf->offset, X);
            n_f = xfem::Vec3(phf.g[nf], phf.g[nf + 1], phf.g[nf + 2]).normalized();
          }
          const double across = n_f.dot(conormal);
          const optimize::Dual phi = optimize::implicit_function(b.kind, p.data() + b.offset, X);
          const xfem::Vec3 grad(phi.g[nb], phi.g[nb + 1], phi.g[nb + 2]);
          const double gn = grad.norm();
          if (std::abs(across) < (bf ? 0.2 : 0.05)) {
            const bool swept = bf && (bf->kind == optimize::PrimitiveKind::cylinder ||
                                      bf->kind == optimize::PrimitiveKind::torus || bf->kind == optimize::PrimitiveKind::sphere);
            if (!spine || !swept || b.kind != optimize::PrimitiveKind::plane || !(gn > 0)) return false;
            const optimize::V3<optimize::Dual> S = optimize::spine_point(bf->kind, p.data() + bf->offset, X);
            const xfem::Vec3 Sv(S.x.v, S.y.v, S.z.v);
            const double depth = optimize::implicit_function(b.kind, p.data() + b.offset, Sv).v;
            const optimize::Dual shifted = optimize::implicit_function(b.kind, p.data() + b.offset, X + conormal);
            for (int k = 0; k < nb; ++k) alpha[k] = -depth * (shifted.g[k] - phi.g[k]) / (gn * gn);
            visit(X, patch.orientation * n_uv, alpha, gauss.weights[q] * speed);
            continue;
          }
          if (!(gn > 0)) continue;
          const double s = grad.dot(n_g) >= 0 ? 1.0 : -1.0;
          for (int k = 0; k < nb; ++k) alpha[k] = -(-s * phi.g[k] / gn) * n_g.dot(n_f) / across;
          visit(X, n_g, alpha, gauss.weights[q] * speed);
        }
      }
    return true;
  };
  // A loop segment of a patch lying on a moving neighbour F (`on`, with a block): at each Gauss
  // point visit(X, n_Γ, a, ds), a_k the edge's conormal speed inside Γ per entry of F's block. A
  // transversal edge moves with F's normal speed over n_F·ν. A swept face running tangent into
  // Γ (a fillet into a support: cylinder or torus; a ball end: sphere) touches it along its spine
  // offset onto Γ, so on the constraint manifold (tangency kept) the edge moves with the spine
  // point S nearest X: a = ν·∂S/∂p (optimize::spine_point; the null-space completion of
  // Fig. 6.12, case 2). Returns false (visiting nothing more) where a plane or cone runs tangent
  // into Γ.
  auto neighbour_slide = [&](const xfem::CutPatch& patch, const xfem::CurveSegment2& seg, int on,
                             const std::function<void(const xfem::Vec3&, const xfem::Vec3&, const std::vector<double>&, double)>& visit) {
    const optimize::ParameterBlock& b = *sp.block(on);
    const int nb = b.size();
    std::vector<double> speed_k(nb, 0.0);
    for (size_t q = 0; q < gauss.points.size(); ++q) {
      xfem::Vec3 X, Xu, Xv;
      const double t = gauss.points[q];
      const xfem::Vec2 uv = seg.position(t), duv = seg.derivative(t);
      patch.surface->evaluate(uv.x(), uv.y(), X, Xu, Xv);
      const xfem::Vec3 dX = Xu * duv.x() + Xv * duv.y();
      const double speed = dX.norm();
      if (!(speed > 0)) continue;
      const xfem::Vec3 n_uv = Xu.cross(Xv).normalized();
      const xfem::Vec3 tangent_dir = dX / speed, conormal = tangent_dir.cross(n_uv);  // region on the left
      const optimize::Dual phi = optimize::implicit_function(b.kind, p.data() + b.offset, X);
      const xfem::Vec3 grad(phi.g[nb], phi.g[nb + 1], phi.g[nb + 2]);
      const double gn = grad.norm();
      const xfem::Vec3 n_f = sign[on] * grad / gn;
      const double c = n_f.dot(conormal);
      if (std::abs(c) >= 0.2) {
        for (int k = 0; k < nb; ++k) speed_k[k] = (-sign[on] * phi.g[k] / gn) / c;
      } else if (b.kind == optimize::PrimitiveKind::cylinder || b.kind == optimize::PrimitiveKind::torus ||
                 b.kind == optimize::PrimitiveKind::sphere) {
        const optimize::V3<optimize::Dual> S = optimize::spine_point(b.kind, p.data() + b.offset, X);
        for (int k = 0; k < nb; ++k) speed_k[k] = conormal.x() * S.x.g[k] + conormal.y() * S.y.g[k] + conormal.z() * S.z.g[k];
      } else {
        return false;
      }
      visit(X, patch.orientation * n_uv, speed_k, gauss.weights[q] * speed);
    }
    return true;
  };
  tbb::parallel_for(size_t(0), work.size(), [&](size_t w) {
    const int e = work[w];
    const xfem::GridElement& el = elements[e];
    Terms& out = terms[w];
    const Eigen::VectorXd ue = element_values(at.solution.u, at.solution.node[e]);
    // λₑ, and the field the load's change is contracted with: zₑ = 2uₑ (compliance), −λₑ (adjoint).
    const Eigen::VectorXd le = adj ? element_values(adj->lambda, at.solution.node[e]) : Eigen::VectorXd();
    const Eigen::VectorXd ze = adj ? Eigen::VectorXd(-le) : Eigen::VectorXd(2 * ue);
    std::optional<xfem::BulkShapeDensity> density;  // of this element's (u, u), or (λ, u)
    const double h = el.box.size().minCoeff();
    const bool penalised =
        local_penalty && std::any_of(el.subvolume->patches.begin(), el.subvolume->patches.end(),
                                     [&](const xfem::CutPatch& patch) { return supports.count(patch.source_face) > 0; });
    // The local penalty's parts on this cell: dΛ per entry of p is gathered in `d_lambda`.
    xfem::LocalPenaltyParts parts;
    if (penalised) parts = xfem::local_penalty_parts(el, setup.material, setup.dirichlet, setup.solver);
    const bool simple = penalised && parts.clamped && parts.gap > 1e-6 && parts.mode.size() == ue.size();
    const double lambda = parts.flux_eigenvalue;
    std::map<int, double> d_lambda;
    for (const xfem::CutPatch& patch : el.subvolume->patches) {
      const bool own = own_sides.count(patch.source_face) > 0;  // a support or load whose own motion counts
      if (penalised && !simple && (!conditioned.count(patch.source_face) || own) && sp.block(patch.source_face))
        out.penalised.push_back(patch.source_face);
      // Bulk: Reynolds over the patches of moving faces (a support's or load's own motion that
      // is flagged above is not integrated here).
      const bool wanted = face_moves[patch.source_face] && (!conditioned.count(patch.source_face) || own);
      const optimize::ParameterBlock* block = wanted ? sp.block(patch.source_face) : nullptr;
      if (block) {
        const xfem::SurfaceRule sr = xfem::surface_rule(patch, so);
        if (!sr.points.empty()) {
          out.used = true;
          out.points += static_cast<int>(sr.points.size());
          const std::vector<double> dj = moving_density(e, ue, le, sr.points, density);
          const std::vector<double> psi_mode =
              simple ? xfem::bulk_shape_density(el, parts.mode, parts.mode, setup.material, setup.solver, sr.points)
                     : std::vector<double>{};
          const int nb = block->size();
          std::vector<double> sum(nb, 0.0);
          for (size_t q = 0; q < sr.points.size(); ++q) {
            const double density = dj[q];
            const optimize::Dual phi = optimize::implicit_function(block->kind, p.data() + block->offset, sr.points[q]);
            const xfem::Vec3 grad(phi.g[nb], phi.g[nb + 1], phi.g[nb + 2]);
            const double gn = grad.norm();
            if (!(gn > 0)) continue;
            const double s = grad.dot(sr.normals[q]) >= 0 ? 1.0 : -1.0;
            for (int k = 0; k < nb; ++k) sum[k] += sr.weights[q] * density * (-s * phi.g[k] / gn);  // Vₙ = ∂X/∂p_k·n
            if (simple)  // −Λ vᵀdÂv
              for (int k = 0; k < nb; ++k) d_lambda[block->offset + k] -= lambda * sr.weights[q] * psi_mode[q] * (-s * phi.g[k] / gn);
          }
          for (int k = 0; k < nb; ++k)
            if (sum[k] != 0) out.gradient.emplace_back(block->offset + k, sum[k]);
        }
      }
      // Bulk on a B-spline face: Vₙ = R_ij(u, v) n_c for coordinate c of pole (i, j), at the
      // rule's (u, v) on the B-rep's own surface (the patch's surface; the pole block's knots).
      const PoleBlock* poles = wanted ? sp.poles(patch.source_face) : nullptr;
      if (poles) {
        const xfem::SurfaceRule sr = xfem::surface_rule(patch, so);
        out.used = out.used || !sr.points.empty();
        out.points += static_cast<int>(sr.points.size());
        const std::vector<double> dj = moving_density(e, ue, le, sr.points, density);
        const std::vector<double> psi_mode =
            simple && !sr.points.empty()
                ? xfem::bulk_shape_density(el, parts.mode, parts.mode, setup.material, setup.solver, sr.points)
                : std::vector<double>{};
        std::map<int, double> sum;  // entry of p → contribution
        for (size_t q = 0; q < sr.points.size(); ++q) {
          const double density = dj[q];
          for (const PoleInfluence& w : pole_influence(poles->surface, sr.uv[q].x(), sr.uv[q].y())) {
            for (int c = 0; c < 3; ++c) sum[poles->offset + 3 * w.index + c] += sr.weights[q] * density * w.value * sr.normals[q][c];
            if (simple)  // −Λ vᵀdÂv
              for (int c = 0; c < 3; ++c)
                d_lambda[poles->offset + 3 * w.index + c] -= lambda * sr.weights[q] * psi_mode[q] * w.value * sr.normals[q][c];
            else if (penalised && std::abs(w.value) > 1e-12)  // this pole moves the penalised cell's patch
              for (int c = 0; c < 3; ++c) out.penalised_poles.insert(poles->offset + 3 * w.index + c);
          }
        }
        for (const auto& [i, v] : sum)
          if (v != 0) out.gradient.emplace_back(i, v);
      }
      if (patch.source_face == surface_face) {
        // J's own surface integral ∫_F g dA over the moving F (u_h frozen, g continuous across
        // cell walls: no wall terms): ∫_F (∂ₙg + κg) Vₙ dA + ∮ g α ds for F's own motion, as for
        // a load's, and ∮ g a ds where a neighbour's motion slides F's edges (its strips).
        std::vector<double> g;
        std::vector<xfem::Vec3> dg;
        const auto density_at = [&](const std::vector<xfem::Vec3>& points) {
          adj->surface_density(e, points, g, dg);
          PARAFAB_VERIFY(g.size() == points.size() && dg.size() == points.size(),
                         who << ": the surface density gives " << g.size() << " values and " << dg.size()
                             << " gradients for " << points.size() << " points");
        };
        out.used = true;
        if (surface_own && face_moves[surface_face]) {
          const optimize::ParameterBlock& b = *sp.block(surface_face);
          const int nb = b.size();
          std::vector<double> sum(nb, 0.0);
          const xfem::SurfaceRule sr = xfem::surface_rule(patch, so);
          out.points += static_cast<int>(sr.points.size());
          density_at(sr.points);
          for (size_t q = 0; q < sr.points.size(); ++q) {
            const optimize::Dual phi = optimize::implicit_function(b.kind, p.data() + b.offset, sr.points[q]);
            const xfem::Vec3 grad(phi.g[nb], phi.g[nb + 1], phi.g[nb + 2]);
            const double gn = grad.norm();
            if (!(gn > 0)) continue;
            const double s = grad.dot(sr.normals[q]) >= 0 ? 1.0 : -1.0;
            const double kappa = s * optimize::implicit_mean_curvature(b.kind, p.data() + b.offset, sr.points[q]);
            const double density = dg[q].dot(sr.normals[q]) + kappa * g[q];
            for (int k = 0; k < nb; ++k) sum[k] += sr.weights[q] * density * (-s * phi.g[k] / gn);
          }
          const bool tangent = !own_edges(patch, el.box, b, surface_sides, false, true,
                                          [&](const xfem::Vec3& X, const xfem::Vec3&, const std::vector<double>& alpha,
                                              double ds) {
                                            density_at({X});
                                            for (int k = 0; k < nb; ++k) sum[k] += g[0] * alpha[k] * ds;
                                            ++out.edge_points;
                                          });
          if (tangent) {
            out.tangent.push_back(surface_face);
          } else {
            for (int k = 0; k < nb; ++k)
              if (sum[k] != 0) out.gradient.emplace_back(b.offset + k, sum[k]);
          }
        }
        for (const xfem::UvLoop& loop : xfem::to_uv_loops(patch.loops))
          for (const xfem::CurveSegment2& seg : loop) {
            const int on = segment_face(patch, seg, surface_sides, 1e-6 * h);
            if (on < 0 || !face_moves[on]) continue;
            const int nb = sp.block(on)->size();
            std::vector<double> sum(nb, 0.0);
            const bool tangent = !neighbour_slide(patch, seg, on, [&](const xfem::Vec3& X, const xfem::Vec3&,
                                                                      const std::vector<double>& speed_k, double ds) {
              density_at({X});
              for (int k = 0; k < nb; ++k) sum[k] += g[0] * speed_k[k] * ds;
              ++out.edge_points;
            });
            if (tangent) {
              out.tangent.push_back(on);
              continue;
            }
            for (int k = 0; k < nb; ++k)
              if (sum[k] != 0) out.gradient.emplace_back(sp.block(on)->offset + k, sum[k]);
          }
      }
      if (!conditioned.count(patch.source_face)) continue;
      // A support's or load's patch: its Nitsche / traction terms (the last condition of each
      // kind on the face, as element_system takes them).
      const int g = patch.source_face;
      const xfem::DirichletCondition* dc = nullptr;
      for (const auto& d : setup.dirichlet) if (d.face == g) dc = &d;
      const xfem::TractionCondition* tc = nullptr;
      int load = -1;
      for (size_t i = 0; i < at.tractions.size(); ++i)
        if (at.tractions[i].face == g) tc = &at.tractions[i], load = static_cast<int>(i);
      out.used = true;
      const bool spread_load = load >= 0 && load_area[load] > 0;
      if (spread_load) {  // ∫ z_h·t dA over the load face, for the area term
        const xfem::SurfaceRule sr = xfem::surface_rule(patch, so);
        double sum = 0;
        for (size_t q = 0; q < sr.points.size(); ++q)
          sum += sr.weights[q] * xfem::boundary_term_density(el, ze, setup.material, setup.solver, nullptr, tc, sr.points[q], sr.normals[q]).load;
        out.work.emplace_back(load, sum);
      }
      if (own && wanted && tc) {
        // The load's own motion (the surface-integral form of Eq. 6.30): with uₕ frozen,
        //   d/ds ∫_Γ uₕ·t dA = ∫_Γ (∂ₙ(uₕ·t) + κ uₕ·t) Vₙ dA + ∮_∂Γ uₕ·t α ds,
        // κ = div n (implicit_mean_curvature), and along an edge where Γ slides on its neighbour
        // F, α = −Vₙ (n_Γ·n_F)/(ν·n_F) across the edge (ν the outward conormal). C gains twice
        // that (2uᵀdf); a total force's traction F/A also changes with dA = ∫ κ Vₙ dA + ∮ α ds.
        const optimize::ParameterBlock& b = *sp.block(g);
        const int nb = b.size();
        std::vector<double> sum(nb, 0.0), dA(nb, 0.0);
        const xfem::SurfaceRule sr = xfem::surface_rule(patch, so);  // its points are counted by the bulk term
        for (size_t q = 0; q < sr.points.size(); ++q) {
          const optimize::Dual phi = optimize::implicit_function(b.kind, p.data() + b.offset, sr.points[q]);
          const xfem::Vec3 grad(phi.g[nb], phi.g[nb + 1], phi.g[nb + 2]);
          const double gn = grad.norm();
          if (!(gn > 0)) continue;
          const double s = grad.dot(sr.normals[q]) >= 0 ? 1.0 : -1.0;
          const double kappa = s * optimize::implicit_mean_curvature(b.kind, p.data() + b.offset, sr.points[q]);
          const xfem::BoundaryTermDensity d =  // of z: 2u (compliance) or −λ
              xfem::boundary_term_density(el, ze, setup.material, setup.solver, nullptr, tc, sr.points[q], sr.normals[q]);
          const double density = d.load_gradient.dot(sr.normals[q]) + kappa * d.load;
          for (int k = 0; k < nb; ++k) {
            const double vn = -s * phi.g[k] / gn;
            sum[k] += sr.weights[q] * density * vn;
            dA[k] += sr.weights[q] * kappa * vn;
          }
        }
        // Its edges: loop segments on a face across one of Γ's edges (all three sample points on
        // that face's surface, within 1e-6·h). The others lie on cell walls or on Γ's own seam,
        // whose terms cancel between their two sides.
        const bool tangent = !own_edges(patch, el.box, b, own_sides.at(g), false, true,
                                        [&](const xfem::Vec3& X, const xfem::Vec3& n_g, const std::vector<double>& alpha,
                                            double ds) {
          const double load = xfem::boundary_term_density(el, ze, setup.material, setup.solver, nullptr, tc, X, n_g).load;
          for (int k = 0; k < nb; ++k) {
            sum[k] += load * alpha[k] * ds;
            dA[k] += alpha[k] * ds;
          }
          ++out.edge_points;
        });
        if (tangent) {
          out.tangent.push_back(g);
        } else {
          for (int k = 0; k < nb; ++k) {
            if (sum[k] != 0) out.gradient.emplace_back(b.offset + k, sum[k]);
            if (spread_load && dA[k] != 0) out.area.emplace_back(load * np + b.offset + k, dA[k]);
          }
        }
      }
      // (With the local penalty and Λ not simple, the patch is flagged above: no penalty to use.)
      if (own && wanted && dc && !(penalised && !simple)) {
        // A support's own motion (its Nitsche terms, Eq. 6.22, on a moving Γ): with uₕ frozen,
        //   d/ds ∫_Γ F(X, n) dA = ∫_Γ [(∂ₙF + κF) Vₙ − ∂F/∂n·∇_Γ Vₙ] dA + ∮_∂Γ F α ds,
        // the normal turning by n' = −∇_Γ Vₙ (optimize::implicit_normal_speed), α as for a load.
        // F = 2 l − k (2uᵀdf − uᵀdKu) for the compliance, l(z) + k(λ, u) for an adjoint (k's
        // bilinear form by polarization); with the local penalty (Λ simple) vᵀdBv is the same
        // integral of the flux density f = |Mσ(v)n|² of Λ's mode v.
        const optimize::ParameterBlock& b = *sp.block(g);
        const int nb = b.size();
        const double penalty = simple ? parts.penalty : -1;
        struct Field {
          double value = 0;
          xfem::Vec3 gradient = xfem::Vec3::Zero(), normal = xfem::Vec3::Zero();
        };
        const auto objective_field = [&](const xfem::Vec3& X, const xfem::Vec3& n) {
          const auto at_ = [&](const Eigen::VectorXd& v) {
            return xfem::boundary_term_density(el, v, setup.material, setup.solver, dc, nullptr, X, n, penalty);
          };
          Field F;
          if (!adj) {
            const xfem::BoundaryTermDensity d = at_(ue);
            F.value = 2 * d.load - d.stiffness;
            F.gradient = 2 * d.load_gradient - d.stiffness_gradient;
            F.normal = 2 * d.load_normal - d.stiffness_normal;
          } else {
            const xfem::BoundaryTermDensity dz = at_(ze), kp = at_(ue + le), km = at_(ue - le);
            F.value = dz.load + 0.25 * (kp.stiffness - km.stiffness);
            F.gradient = dz.load_gradient + 0.25 * (kp.stiffness_gradient - km.stiffness_gradient);
            F.normal = dz.load_normal + 0.25 * (kp.stiffness_normal - km.stiffness_normal);
          }
          return F;
        };
        const auto flux_field = [&](const xfem::Vec3& X, const xfem::Vec3& n) {
          const xfem::BoundaryTermDensity d =
              xfem::boundary_term_density(el, parts.mode, setup.material, setup.solver, dc, nullptr, X, n, penalty);
          return Field{d.flux, d.flux_gradient, d.flux_normal};
        };
        std::vector<double> sum(nb, 0.0), dB(nb, 0.0);
        const xfem::SurfaceRule sr = xfem::surface_rule(patch, so_support);  // degree 10/14, not counted in `points`
        for (size_t q = 0; q < sr.points.size(); ++q) {
          const xfem::Vec3& X = sr.points[q], &n = sr.normals[q];
          const optimize::NormalSpeed ns = optimize::implicit_normal_speed(b.kind, p.data() + b.offset, X);
          if (ns.speed.size() == 0) continue;  // ∇φ = 0 (an axis): no normal speed, as the bulk term skips
          const double s = ns.normal.dot(n) >= 0 ? 1.0 : -1.0;
          const double kappa = s * optimize::implicit_mean_curvature(b.kind, p.data() + b.offset, X);
          const Eigen::Matrix3d tangential = Eigen::Matrix3d::Identity() - n * n.transpose();
          const Field F = objective_field(X, n);
          const Field f = simple ? flux_field(X, n) : Field{};
          for (int k = 0; k < nb; ++k) {
            const double vn = s * ns.speed[k];
            const xfem::Vec3 dvn = s * (tangential * ns.gradient.row(k).transpose());
            sum[k] += sr.weights[q] * ((F.gradient.dot(n) + kappa * F.value) * vn - F.normal.dot(dvn));
            if (simple) dB[k] += sr.weights[q] * ((f.gradient.dot(n) + kappa * f.value) * vn - f.normal.dot(dvn));
          }
        }
        // Its edges: loop segments on a face across one of Γ's edges (as for a load's own
        // motion), and on the cell's walls: there the patch's piece in this cell slides along
        // the wall, and unlike a load's uₕ·t, F (σ(u)) jumps across the wall, so the two cells'
        // strips do not cancel (nor does a cell's own flux, whose B is its own).
        const bool tangent = !own_edges(patch, el.box, b, own_sides.at(g), true, true,
                                        [&](const xfem::Vec3& X, const xfem::Vec3& n_g, const std::vector<double>& alpha,
                                            double ds) {
          const Field F = objective_field(X, n_g);
          const Field f = simple ? flux_field(X, n_g) : Field{};
          for (int k = 0; k < nb; ++k) {
            sum[k] += F.value * alpha[k] * ds;
            dB[k] += f.value * alpha[k] * ds;
          }
          ++out.edge_points;
        });
        if (tangent) {
          out.tangent.push_back(g);
        } else {
          for (int k = 0; k < nb; ++k) {
            if (sum[k] != 0) out.gradient.emplace_back(b.offset + k, sum[k]);
            if (dB[k] != 0) d_lambda[b.offset + k] += dB[k];
          }
        }
      }
      const auto it = neighbours.find(g);
      // With the local penalty and Λ not simple the strips along a support's edges are not
      // integrated: the neighbours' patches in this (clamped, cut) cell are flagged above.
      if (it == neighbours.end() || (penalised && dc && !simple)) continue;
      // Loop segments of the patch that lie on a moving neighbour F (all three sample points on
      // F's surface): that edge moves inside the face with conormal speed a = Vₙ,F / (n_F·ν).
      for (const xfem::UvLoop& loop : xfem::to_uv_loops(patch.loops))
        for (const xfem::CurveSegment2& seg : loop) {
          const int on = segment_face(patch, seg, it->second, 1e-6 * h);
          if (on < 0) continue;
          const int nb = sp.block(on)->size();
          std::vector<double> sum(nb, 0.0), dA(nb, 0.0), dB(nb, 0.0);
          const double penalty = simple ? parts.penalty : -1;
          const bool tangent = !neighbour_slide(patch, seg, on, [&](const xfem::Vec3& X, const xfem::Vec3& n_g,
                                                                    const std::vector<double>& speed_k, double ds) {
            // (2 f_Γ − k_Γ)(u) for the compliance; f_Γ(z) + k_Γ(λ, u) for an adjoint (k_Γ's
            // bilinear form by polarization of its quadratic one).
            double strip = 0;
            if (!adj) {
              const xfem::BoundaryTermDensity d =
                  xfem::boundary_term_density(el, ue, setup.material, setup.solver, dc, tc, X, n_g, penalty);
              strip = 2 * d.load - d.stiffness;
            } else {
              const auto k = [&](const Eigen::VectorXd& v) {
                return xfem::boundary_term_density(el, v, setup.material, setup.solver, dc, nullptr, X, n_g, penalty).stiffness;
              };
              strip = xfem::boundary_term_density(el, ze, setup.material, setup.solver, dc, tc, X, n_g, penalty).load +
                      0.25 * (k(ue + le) - k(ue - le));
            }
            const double flux_mode =  // vᵀdBv density
                simple && dc ? xfem::boundary_term_density(el, parts.mode, setup.material, setup.solver, dc, nullptr, X,
                                                           n_g, penalty)
                                   .flux
                             : 0.0;
            for (int k = 0; k < nb; ++k) {
              sum[k] += strip * speed_k[k] * ds;
              dA[k] += speed_k[k] * ds;
              dB[k] += flux_mode * speed_k[k] * ds;
            }
            ++out.edge_points;
          });
          if (tangent) {
            out.tangent.push_back(on);
            continue;
          }
          const int offset = sp.block(on)->offset;
          for (int k = 0; k < nb; ++k) {
            if (sum[k] != 0) out.gradient.emplace_back(offset + k, sum[k]);
            if (spread_load && dA[k] != 0) out.area.emplace_back(load * np + offset + k, dA[k]);
            if (dB[k] != 0) d_lambda[offset + k] += dB[k];
          }
        }
    }
    // The penalty's change: dC = κ dΛ (2uᵀg − uᵀPu); for an adjoint dJ = κ dΛ (zᵀg + λᵀPu).
    if (simple) {
      const double weight = adj ? ze.dot(parts.load) + le.dot(parts.mass * ue) : 2 * ue.dot(parts.load) - ue.dot(parts.mass * ue);
      for (const auto& [i, dl] : d_lambda)
        if (dl != 0) out.gradient.emplace_back(i, setup.solver.nitsche_local_factor * dl * weight);
    }
  });
  std::vector<double> load_work(at.tractions.size(), 0.0);
  std::map<int, double> area_change;  // load · size(p) + entry → dA
  for (size_t w = 0; w < work.size(); ++w) {  // in element order: deterministic
    const Terms& t = terms[w];
    for (const auto& [i, v] : t.gradient) r.gradient[i] += v;
    for (const auto& [i, v] : t.area) area_change[i] += v;
    for (const auto& [i, v] : t.work) load_work[i] += v;
    for (int f : t.tangent) flag(f);
    for (int f : t.penalised) flag(f);
    for (int i : t.penalised_poles) r.incomplete[i] = 1;
    r.points += t.points + t.edge_points;
    r.edge_points += t.edge_points;
    if (t.used) ++r.elements;
  }
  // Total forces: t = F/A, so zᵀdf ∋ ∫ z_h·dt dA = −W dA/A with W = ∫ z_h·t dA (compliance:
  // z = 2u, the 2uᵀdf of dC; adjoint: z = −λ, the −λᵀdf of dJ).
  for (const auto& [key, dA] : area_change) {
    const int load = key / np, i = key % np;
    r.gradient[i] -= load_work[load] * dA / load_area[load];
  }
  // Eq. 6.24's ties: the energy ½Σ w‖u_a − u_b‖² with w = E·h·b(d(p)), so
  // dC = −Σ E·h·b'(d) d' ‖u_a − u_b‖² (d' from the faces at the gap's ends: piece_gap_gradient).
  // A mode-tied pair adds ‖α_a − α_b‖² to that factor and −θ'·∂(uᵀKu)/∂θ, θ = 1 − e^(−b).
  // For an adjoint, λᵀdK u: the same with −(λ_a − λ_b)·(u_a − u_b) for ‖u_a − u_b‖² (and the
  // mode-tied quadratic forms polarized).
  if (!at.ties.empty()) {
    std::vector<char> complete;
    const Eigen::MatrixXd dd = piece_gap_gradient(at.gaps, sp, p, &complete);
    for (size_t i = 0; i < at.ties.size(); ++i) {
      const PieceGap& gap = at.gaps[i];
      const double h = at.model->elements[gap.element_a].box.size().minCoeff();
      double db = 0;
      const double b = merge_penalty_b(gap.joined ? 0.0 : gap.distance, setup.merge.critical_fraction * h, setup.merge, &db);
      if (db == 0) continue;
      const std::vector<char>& floating = at.solution.floating;
      const std::vector<std::array<int, 2>> pairs = xfem::tied_nodes(at.model->elements, at.solution.node, at.ties[i]);
      bool blended = false;  // a floating node blended towards an unknown: T changes with d (no term here)
      for (const auto& [ia, ib] : pairs) blended |= !floating.empty() && floating[ia] != floating[ib];
      if (!complete[i] || blended) {
        ++r.ties_without_derivative;
        for (const GapEnd* end : {&gap.a, &gap.b})
          for (int f : end->faces) flag(f);
        continue;
      }
      const Eigen::VectorXd& u = at.solution.u;
      double squared = 0;
      for (const auto& [ia, ib] : pairs)
        if (floating.empty() || (!floating[ia] && !floating[ib])) {  // as the solve ties them
          const Eigen::Vector3d du = u.segment<3>(3 * ia) - u.segment<3>(3 * ib);
          squared += adj ? -(adj->lambda.segment<3>(3 * ia) - adj->lambda.segment<3>(3 * ib)).dot(du) : du.squaredNorm();
        }
      double blend_factor = 0;  // ∂(uᵀKu)/∂θ · dθ/db
      if (modes_tied[i]) {
        const xfem::PieceTie& tie = at.ties[i];
        const std::vector<int>& na = at.solution.node[tie.element_a], &nb = at.solution.node[tie.element_b];
        const auto terms_of = [&](const Eigen::VectorXd& va, const Eigen::VectorXd& vb) {
          return xfem::tied_mode_shape_terms(elements, tie, va, vb, setup.material, setup.solver, 0, {});
        };
        const Eigen::VectorXd ua = element_values(u, na), ub = element_values(u, nb);
        if (!adj) {
          const xfem::TiedModeShapeTerms m = terms_of(ua, ub);
          squared += m.d_weight;
          blend_factor = m.d_blend * std::exp(-b);
        } else {
          const Eigen::VectorXd la = element_values(adj->lambda, na), lb = element_values(adj->lambda, nb);
          const xfem::TiedModeShapeTerms plus = terms_of(ua + la, ub + lb), minus = terms_of(ua - la, ub - lb);
          squared -= 0.25 * (plus.d_weight - minus.d_weight);
          blend_factor = -0.25 * (plus.d_blend - minus.d_blend) * std::exp(-b);
        }
      }
      r.gradient -= (setup.material.youngs_modulus * h * squared + blend_factor) * db *
                    dd.row(static_cast<Eigen::Index>(i)).transpose();
    }
  }
  r.done = true;
  r.message = "ok";
  r.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return r;
}

}  // namespace

ComplianceGradient compliance_gradient(const ComplianceState& at, const ComplianceSetup& setup,
                                       const ShapeParameters& sp, const Eigen::VectorXd& p,
                                       const std::vector<char>* moving) {
  return shape_gradient(at, setup, sp, p, moving, nullptr, "compliance_gradient");
}

ComplianceGradient adjoint_shape_gradient(const ComplianceState& at, const ComplianceSetup& setup,
                                          const ShapeParameters& sp, const Eigen::VectorXd& p,
                                          const ShapeAdjoint& adjoint, const std::vector<char>* moving) {
  return shape_gradient(at, setup, sp, p, moving, &adjoint, "adjoint_shape_gradient");
}

bool exact_along(const ComplianceGradient& g, const Eigen::VectorXd& dp) {
  PARAFAB_VERIFY(dp.size() == static_cast<Eigen::Index>(g.incomplete.size()),
                 "exact_along: a direction of " << dp.size() << " entries, the gradient has " << g.incomplete.size());
  const double scale = dp.cwiseAbs().maxCoeff();
  for (Eigen::Index i = 0; i < dp.size(); ++i)
    if (g.incomplete[i] && std::abs(dp[i]) > 1e-6 * scale) return false;
  return true;
}

Eigen::VectorXd element_values(const Eigen::VectorXd& v, const std::vector<int>& nodes) {
  Eigen::VectorXd ve(3 * nodes.size());
  for (size_t a = 0; a < nodes.size(); ++a)
    for (int c = 0; c < 3; ++c) ve[3 * a + c] = v[3 * nodes[a] + c];
  return ve;
}

Eigen::VectorXd element_residual(const xfem::GridElement& el, const std::vector<xfem::TractionCondition>& tractions,
                                 const Eigen::VectorXd& ue, const ComplianceSetup& setup) {
  if (!setup.hyperelastic) {
    const xfem::ElementSystem es = xfem::element_system(el, setup.material, setup.dirichlet, tractions, setup.solver);
    return es.K * ue - es.f;
  }
  const xfem::ElementSystem boundary =
      xfem::element_system(el, setup.material, setup.dirichlet, tractions, setup.solver, /*include_bulk=*/false);
  return xfem::element_internal_force(el, *setup.hyperelastic, ue) + boundary.K * ue - boundary.f;
}

Eigen::VectorXd adjoint_of(const ComplianceState& state, const Eigen::VectorXd& dJ_du, const char* who) {
  PARAFAB_VERIFY(dJ_du.size() == state.solution.u.size(), who << ": the value carries no ∂J/∂u of this state (size "
                                                               << dJ_du.size() << ", u " << state.solution.u.size() << ")");
  return state.solution.solve_again(-dJ_du);
}

}  // namespace parafab::occ
