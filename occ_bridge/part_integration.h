// Integration over a B-rep part on a fixed grid (thesis §6.3): cut the part by the grid,
// build a moment-fitted volume rule for every cut subvolume and a tensor Gauss rule for every
// interior cell, and compare the resulting mass properties with OpenCASCADE's own.
#pragma once

#include <string>
#include <vector>

#include "grid_cut.h"
#include "xfem/mass_properties.h"
#include "xfem/volume_rules.h"

namespace parafab::occ {

struct PartShape;

struct IntegrationOptions {
  GridOptions grid;
  xfem::VolumeRuleOptions rule;
  int interior_points = 2;        ///< Gauss points per direction in uncut cells (exact to degree 3)
  bool occt_reference = true;     ///< also compute BRepGProp properties of the whole part
  double occt_precision = 1e-10;  ///< BRepGProp relative precision
};

struct MassPropertyErrors {
  double volume = 0;   ///< |ΔV| / V
  double center = 0;   ///< |Δc| / bounding-box diagonal
  double inertia = 0;  ///< ‖ΔI‖_F / ‖I‖_F
};

struct IntegrationResult {
  bool done = false;
  std::string message;
  GridCut cut;                         ///< the cut (cells, subvolumes, connectivity)
  std::vector<xfem::VolumeRule> rules; ///< one per cut subvolume (same order)
  xfem::MassProperties by_rules;
  xfem::MassProperties by_occt;
  MassPropertyErrors errors;           ///< rules against OCCT
  int rule_points = 0;
  int rules_not_ok = 0;                ///< rules whose status is not Ok
  int rules_refinement_capped = 0;     ///< rules whose flux refinement hit its depth cap
  double max_moment_residual = 0;
  double max_closure_defect = 0;
  double cut_seconds = 0, rule_seconds = 0, occt_seconds = 0;
};

/// Mass properties of one cut cell from the rules of its subvolumes.
xfem::MassProperties cut_cell_properties(const IntegrationResult& result, const CutCell& cell);

MassPropertyErrors compare(const xfem::MassProperties& a, const xfem::MassProperties& ref,
                           double diagonal);

/// Never throws for a part the splitter cannot cut (done = false, message); throws
/// parafab::Error for invalid options.
IntegrationResult integrate_part(const PartShape& part, const IntegrationOptions& options = {});

}  // namespace parafab::occ
