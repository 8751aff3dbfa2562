// The simulation grid of a part (thesis §6.4): grid cut, one element per uncut interior cell
// (tensor Gauss rule) and per cut subvolume (moment-fitted rule), and which elements touch
// through a grid face, ready for xfem::solve_linear.
#pragma once

#include <atomic>
#include <memory>
#include <string>
#include <vector>

#include "grid_cut.h"
#include "xfem/linear_xfem.h"
#include "xfem/volume_rules.h"

namespace parafab::occ {

struct PartShape;

struct GridModelOptions {
  GridOptions grid;
  xfem::VolumeRuleOptions rule;
  int interior_points = 2;  ///< Gauss points per direction in uncut cells (exact for hex8 stiffness)
};

/// A cut subvolume whose volume rule did not come out Ok (status other than Ok, or the rule
/// threw): the element stays in the model (with the rule it got, possibly empty) and the
/// entries report it (simulate's `rule_failures`); it is never dropped silently.
struct RuleFailure {
  std::array<int, 3> cell{0, 0, 0};
  int subvolume = -1;  ///< index into cut->subvolumes
  std::string message;
  /// The flux refinement of some patch stopped at its depth cap (VolumeRuleOptions::max_depth)
  /// above its tolerance (VolumeRule::flux_capped_leaves > 0).
  bool refinement_capped = false;
};

struct GridModel {
  bool done = false;
  std::string message;
  /// Owns the subvolumes the elements point to; shared by copies of the model (a copy may change
  /// its elements' switches, never the cut).
  std::shared_ptr<GridCut> cut;
  std::vector<xfem::GridElement> elements;  ///< interior cells first, then cut subvolumes
  std::vector<std::array<int, 2>> adjacent; ///< element pairs sharing a grid face
  std::vector<RuleFailure> rule_failures;   ///< ordered by subvolume
  int rules_refinement_capped = 0;          ///< rule_failures with refinement_capped
  double cut_seconds = 0, rule_seconds = 0;
};

GridModel build_grid_model(const PartShape& part, const GridModelOptions& options = {});

/// `options` with rules of the degree `element` needs. Hex8: unchanged (2×2×2 Gauss in uncut
/// cells, moment fitting of degree 4: exact for the trilinear stiffness). Hex27: 3×3×3 Gauss in
/// uncut cells (exact for the triquadratic stiffness, degree 4 per coordinate) and moment
/// fitting of total degree 10 with every exponent ≤ 4 (121 functions) on 5³ points in cut
/// cells, flux patches of degree 10: every product of two gradients of triquadratic functions
/// (x⁴y⁴z² and the like) lies in that span, so the stiffness is integrated exactly and is
/// positive semidefinite whatever the signs of the weights. Spans without x⁴y⁴z² (total degree
/// 6 or 8) left the stiffness of small cut cells indefinite: CHOLMOD found turned beams not
/// positive definite whatever the Nitsche β (tests/occ_bridge/quadratic_xfem_test.cpp). Until
/// 2026-11-25 the full total-degree-10 span (286 functions) was fitted on 11³ points.
GridModelOptions rules_for_element(xfem::ElementType element, GridModelOptions options = {});

/// The model of `part`, a changed `old_part`, on the grid of `old`: only blocks around the
/// changed faces are cut again and get new rules; the rest are reused (recut_by_grid).
GridModel rebuild_grid_model(const PartShape& part, const GridModel& old, const PartShape& old_part,
                             const GridModelOptions& options = {}, RecutReport* report = nullptr);

/// The element of `grid` holding a point X (probes, surface vertices of the result), found
/// through the grid: the elements of X's cell and of its 26 neighbours whose box holds X (slack
/// 1e-6 of the box; X may lie on a cell face or, after plane shifts, just outside its cell).
/// Of those, the ones that hold X: an uncut cell, or a cut subvolume by point_in_subvolume
/// (cut_cell_classifier.h), which tells the pieces of a cell apart (the two sides of a slot
/// thinner than a cell); the one with the rule point nearest to X among them. When no piece is
/// known to hold X (a patch on a surface other than a plane, cylinder or sphere, X within the
/// test's band of a patch's loop, i.e. of an edge of the piece), the nearest rule point among
/// the candidates not known to miss X (else among all), which can pick the wrong side of a
/// turned slot (tests/occ_bridge/element_locator_test.cpp); nearest_rule_point_fallbacks()
/// counts these. A single candidate is returned untested. −1 when no element's box holds X.
/// Safe to call from several threads.
class ElementLocator {
 public:
  explicit ElementLocator(const GridModel& grid);
  int find(const xfem::Vec3& X) const;
  /// X on the part's surface with outward normal n: the element holding X − δ n, δ = 1e-3 of
  /// the smallest cell side (inside the material, clear of the patch X lies on).
  int find_on_surface(const xfem::Vec3& X, const xfem::Vec3& n) const;
  long nearest_rule_point_fallbacks() const { return fallbacks_.load(); }

 private:
  size_t id(const std::array<int, 3>& c) const {
    return (static_cast<size_t>(c[0]) * cells_[1] + c[1]) * cells_[2] + c[2];
  }
  const GridModel& grid_;
  std::array<int, 3> cells_;
  std::vector<int> first_, list_;  ///< elements by dense cell index (CSR: first_[c] .. first_[c + 1])
  double near_ = 0;                ///< point_in_subvolume's band: 1e-6 of the cell diagonal
  mutable std::atomic<long> fallbacks_{0};
};

}  // namespace parafab::occ
