// The iterative solve of the XFEM systems at scale (thesis §6.4, the linear system of Eq. 6.22):
// PETSc's Krylov solvers (CG + smoothed-aggregation AMG by default) on the reduced stiffness,
// with the rigid-body modes of the DOF nodes as AMG's near-nullspace (block size 3). Under
// `mpirun -np N` the rows are split between the ranks (MatMPIAIJ, contiguous blocks of DOF
// nodes); every rank passes the whole matrix and right-hand side and gets the whole solution.
// Built without PETSc (PARAFAB_HAVE_PETSC undefined) petsc_available() is false and a
// PetscSystem cannot be made.
#pragma once

#include <Eigen/Core>
#include <Eigen/SparseCore>
#include <memory>
#include <string>
#include <vector>

#include "xfem/cut_geometry.h"

namespace parafab::xfem {

/// Whether this process can use PETSc: the build has it, its back end loads, and it was not
/// turned off by disallow_petsc_in_process.
bool petsc_available();
/// Turns PETSc off for this process, with the reason petsc_initialize then gives. The Python
/// module does so: an interpreter holds `environ` as a copy relocation, which Open MPI, opened
/// with RTLD_DEEPBIND, would bypass (a double free in MPI_Init was seen); Python runs large jobs
/// through the CLI instead. Call before anything uses PETSc.
void disallow_petsc_in_process(const std::string& reason);
/// PETSc (and MPI, unless already started) initialized once per process, without PETSc's signal
/// handlers (the CLI's SIGINT/SIGTERM stay its own) and with its error handler returning codes
/// (turned into parafab::Error). Honours the PETSC_OPTIONS environment variable. Throws
/// parafab::Error when PETSc is unavailable. Collective under mpirun: every rank must call it.
void petsc_initialize();
/// MPI rank and size of PETSC_COMM_WORLD (initializes PETSc); 0 and 1 without PETSc.
int petsc_rank();
int petsc_ranks();
/// The ranks the launcher gave this process (OMPI_COMM_WORLD_SIZE, PMI_SIZE; 1 when none),
/// read from the environment before anything is initialized.
int launched_ranks();
int launched_rank();

struct KrylovOptions {
  std::string ksp = "cg";   ///< a PETSc KSPType ("cg", "gmres", "minres", ...)
  std::string pc = "gamg";  ///< a PETSc PCType ("gamg", "hypre", "jacobi", "lu" with MUMPS, ...)
  /// ‖f − K u‖ / ‖f‖ at which the solve stops (the unpreconditioned residual).
  double rtol = 1e-9;
  int max_iterations = 10000;
};

struct KrylovResult {
  Eigen::VectorXd x;
  bool converged = false;
  int iterations = 0;
  double residual = 0;  ///< ‖f − K x‖ / ‖f‖
  std::string reason;   ///< PETSc's KSPConvergedReason, as text
  double seconds = 0;
};

/// One matrix handed to PETSc with its preconditioner built on the first solve; later solves
/// (adjoint right-hand sides) reuse both. Not copyable.
class PetscSystem {
 public:
  /// K: the symmetric positive definite reduced stiffness (both triangles stored), of size
  /// 3·nodes.size(); nodes: the position of each DOF node (the near-nullspace's rigid modes).
  /// Throws parafab::Error when PETSc is unavailable or rejects the matrix.
  PetscSystem(const Eigen::SparseMatrix<double>& K, const std::vector<Vec3>& nodes, const KrylovOptions& options);
  ~PetscSystem();
  PetscSystem(const PetscSystem&) = delete;
  PetscSystem& operator=(const PetscSystem&) = delete;

  /// K x = b (b whole on every rank; x whole on every rank), from x0 when given.
  KrylovResult solve(const Eigen::VectorXd& b, const Eigen::VectorXd& x0 = Eigen::VectorXd()) const;

  int rows() const { return rows_; }
  int ranks() const { return ranks_; }
  const KrylovOptions& options() const { return options_; }
  /// Matrix copy and near-nullspace; the preconditioner's setup (first solve) is in setup_seconds.
  double create_seconds = 0;
  mutable double setup_seconds = 0;
  /// PETSc's memory in MB after the preconditioner was built (PetscMemoryGetCurrentUsage on this rank).
  mutable double memory_mb = 0;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
  int rows_ = 0, ranks_ = 1;
  KrylovOptions options_;
};

}  // namespace parafab::xfem
