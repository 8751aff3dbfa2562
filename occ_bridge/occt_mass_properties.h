// OpenCASCADE's own mass properties (BRepGProp), the reference for the cut-cell quadrature:
// for the whole part, and per grid cell through a Boolean common of the cell box with the part.
#pragma once

#include "xfem/cut_geometry.h"
#include "xfem/mass_properties.h"

namespace parafab::occ {

struct PartShape;

/// BRepGProp volume properties at relative precision `eps`.
xfem::MassProperties occt_mass_properties(const PartShape& part, double eps = 1e-10);

struct CellBooleanResult {
  bool done = false;
  xfem::MassProperties properties;
  int solids = 0;  ///< connected pieces in the cell
};

/// The cell box ∩ part by BRepAlgoAPI_Common, then BRepGProp (the per-cell reference route).
CellBooleanResult occt_cell_properties(const PartShape& part, const xfem::Box3& cell, double eps = 1e-10);

}  // namespace parafab::occ
