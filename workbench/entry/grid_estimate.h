// Size of a grid before it is built (thesis §6.3 cutting, §6.4 simulation): every entry that
// builds a grid (`parafab integrate`, `parafab simulate`) estimates first and refuses a job
// that would not fit in memory, with the estimate in the error and how to override it. Also the
// solver choices every grid job reads alike (element, Nitsche penalty).
#pragma once

#include <array>
#include <nlohmann/json.hpp>
#include <string>

#include "grid_cut.h"
#include "part_reader.h"
#include "xfem/linear_xfem.h"

namespace parafab::entry {

struct GridEstimate {
  std::array<double, 3> cells{0, 0, 0};  ///< cells per axis
  double cells_total = 0;
  double cut_cells = 0;    ///< ≈ area / h² (measured 1.4–2.2× the cells actually cut: an upper estimate)
  double memory_mb = 0;    ///< cutting and rules: per cut cell and per cell (measured, see .cpp)
  double seconds = 0;      ///< cutting and rules, one core (measured per cut cell, see .cpp)
  double physical_mb = 0;  ///< the machine's memory
  bool fits = true;        ///< memory_mb ≤ 70 % of physical_mb
};

GridEstimate estimate_grid(const occ::PartInfo& part, const occ::GridOptions& grid);

nlohmann::json to_json(const GridEstimate& e);

/// The job's "element" ("hex8" | "hex27"), or `default_element` when it names none.
xfem::ElementType element_of_job(const nlohmann::json& job, xfem::ElementType default_element);

/// The job's grid cut: the face route, the only one a job can ask for. `grid.method` may say
/// "face"; "splitter" (OCCT's Boolean splitter, kept as the tests' reference) and
/// `grid.block_cells` (its blocks) are refused with the reason.
void cut_of_job(const nlohmann::json& grid, occ::GridOptions& options);

/// The job's Nitsche penalty into `options`: "nitsche_penalty" ("fixed" | "local"), with
/// "nitsche_beta" (fixed only, > 0) or "nitsche_local_factor" (local only, > 1); a key that the
/// chosen penalty would not use is refused; "nitsche_beta" alone means "fixed". Without either,
/// "local" for the linear model on hex27 (`options.element`, set first) and "fixed" (β = 100)
/// otherwise: hex8's local penalty at κ = 4 is soft on a plate thinner than a cell (tip 1.14 ×
/// beam theory against fixed 1.04; hex27 0.997 with both), and the hyperelastic models'
/// linearized Nitsche terms lose accuracy with the smaller local penalty (resources/doc/simulation.md,
/// "Local Nitsche penalty").
/// "nitsche_surface_degree" (2..20): the least degree of the patch rules on curved clamped
/// faces (LinearXfemOptions::dirichlet_surface_degree, default 8; below surface_degree, 5 or
/// hex27's 8, it changes nothing).
void nitsche_of_job(const nlohmann::json& job, xfem::LinearXfemOptions& options, bool linear_model = true);

/// The job's "solver" into `options.solver`: {"type": "auto" | "cholmod" | "petsc", "ksp", "pc",
/// "rtol", "max_iterations", "petsc_from"} (xfem::LinearXfemOptions::Solver). "petsc" in a build
/// without PETSc is an input error.
void solver_of_job(const nlohmann::json& job, xfem::LinearXfemOptions& options);
/// Whether a solve of about `unknowns` takes the iterative (PETSc) path under `options.solver`.
bool iterative_solve(const xfem::LinearXfemOptions& options, double unknowns);

/// The default grid.cells for an element: the same node lattice for both (16 hex8 cells or
/// 8 hex27 cells along the part's longest side, nodes every half cell for hex27).
int default_cells(xfem::ElementType element);

/// Size of a linear solve on cells of size h (resources/doc/simulation.md, "Estimate first"): unknowns
/// 3 (m³V/h³ + b m²A/h²) (m = 2, b = 2 for hex27; m = 1, b = 1.5 for hex8) capped by the box's
/// nodes; CHOLMOD's factor 8·C·n^{4/3} bytes with C = 26 (compact parts, factor_mb) and C = 7
/// (thin-walled ones, factor_mb_min); the run's peak adds 5 (hex8) or 9 (hex27) kB per unknown
/// and 50 MB. Calibrated on the sample parts (tests/bench/bench_estimate.py).
/// With `iterative` (the PETSc path) the solve's memory is linear in the unknowns instead:
/// PETSc's copy of the stiffness plus AMG's hierarchy, kIterativeMbPerDof per unknown (hex8;
/// 2.4× for hex27's denser rows); factor_mb is then 0 and peak_mb = peak_mb_min.
struct SolveEstimate {
  double dofs = 0, factor_mb = 0, factor_mb_min = 0, peak_mb = 0, peak_mb_min = 0;
  bool iterative = false;
};
SolveEstimate estimate_solve(const occ::PartInfo& part, double h, xfem::ElementType element, bool iterative = false);

/// Throws parafab::Error with the estimate and `override_hint` unless e.fits.
void refuse_if_too_big(const GridEstimate& e, const std::string& what, const std::string& override_hint);

/// A face that is both supported and loaded is an input error naming both entries (the load would
/// act on a clamped face: no work, no effect, and certainly not what the job meant).
void refuse_loaded_supports(const std::vector<xfem::DirichletCondition>& supports,
                            const std::vector<xfem::TractionCondition>& loads);

/// A count or size for a message: an integer while it fits, else "1.2e+19" (std::lround of a
/// huge estimate would print -9223372036854775808).
std::string amount(double x);

}  // namespace parafab::entry
