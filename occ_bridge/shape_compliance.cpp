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
#include "shape_gradient_terms.h"
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

// The exact route of compliance_gradient (adj null: J = C, λ = −u, load weight z = 2u, as
// written before the adjoint form, to the last bit) and of adjoint_shape_gradient (adj: λ given,
// z = −λ, J's own density on the moving patches). `who` names the caller in errors. The terms
// (shape_gradient_terms.h) of each cut element with a moving patch are computed in parallel and
// summed in element order, then the ties'.
ComplianceGradient shape_gradient(const ComplianceState& at, const ComplianceSetup& setup, const ShapeParameters& sp,
                                  const Eigen::VectorXd& p, const std::vector<char>* moving, const ShapeAdjoint* adj,
                                  const char* who) {
  const auto t0 = std::chrono::steady_clock::now();
  ComplianceGradient r;
  r.incomplete.assign(sp.size(), 0);
  const detail::GradientContext c = detail::gradient_context(at, setup, sp, p, moving, adj, who, r.incomplete);
  r.gradient = Eigen::VectorXd::Zero(sp.size());
  const std::vector<int> work = detail::moving_elements(c);
  std::vector<detail::ElementTerms> terms(work.size());
  tbb::parallel_for(size_t(0), work.size(), [&](size_t w) { terms[w] = detail::element_terms(c, work[w]); });
  detail::sum_terms(c, terms, r);
  detail::tie_terms(c, r);
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
