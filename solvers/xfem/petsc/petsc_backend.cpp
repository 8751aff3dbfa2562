// The PETSc back end of xfem::PetscSystem (see petsc_backend.h): CG + smoothed-aggregation AMG
// on the reduced XFEM stiffness (thesis §6.4, Eq. 6.22) with the rigid-body modes as AMG's
// near-nullspace, rows split between the MPI ranks (MatMPIAIJ).
#include "petsc_backend.h"

#include <petscksp.h>

#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>
#include <vector>

namespace {

void put(char* out, int size, const std::string& text) {
  if (out && size > 0) std::snprintf(out, static_cast<size_t>(size), "%s", text.c_str());
}

std::string describe(PetscErrorCode ierr, const char* call) {
  const char* text = nullptr;
  PetscErrorMessage(ierr, &text, nullptr);
  return std::string("PETSc: ") + (text ? text : "error") + " (code " + std::to_string(ierr) + ") in " + call;
}

struct Failure {
  std::string message;
};

#define CHECK(call)                                                   \
  do {                                                                \
    const PetscErrorCode parafab_ierr_ = (call);                      \
    if (parafab_ierr_) throw Failure{describe(parafab_ierr_, #call)}; \
  } while (0)

struct System {
  Mat A = nullptr;
  KSP ksp = nullptr;
  Vec b = nullptr, x = nullptr, whole = nullptr;
  VecScatter gather = nullptr;  // the distributed solution to every rank
  PetscInt first = 0, last = 0, rows = 0;
  int size = 1;
  bool set_up = false;
  ~System() {
    PetscBool finalized = PETSC_FALSE;
    PetscFinalized(&finalized);
    if (finalized) return;  // PETSc freed everything at exit
    if (gather) VecScatterDestroy(&gather);
    if (whole) VecDestroy(&whole);
    if (b) VecDestroy(&b);
    if (x) VecDestroy(&x);
    if (ksp) KSPDestroy(&ksp);
    if (A) MatDestroy(&A);
  }
};

// An option in PETSc's database unless the user gave it (PETSC_OPTIONS).
void set_default(const char* name, const char* value) {
  PetscBool given = PETSC_FALSE;
  PetscOptionsHasName(nullptr, nullptr, name, &given);
  if (!given) PetscOptionsSetValue(nullptr, name, value);
}

void finalize_at_exit() {
  PetscBool finalized = PETSC_FALSE;
  PetscFinalized(&finalized);
  if (!finalized) PetscFinalize();
}

}  // namespace

extern "C" {

int parafab_petsc_initialize(char* error, int error_size) {
  PetscBool done = PETSC_FALSE;
  PetscInitialized(&done);
  if (done) return 0;
  const bool launched_by_mpirun = std::getenv("OMPI_COMM_WORLD_SIZE") || std::getenv("PMI_SIZE") || std::getenv("PMIX_RANK");
  // Before initialization these only go into the options database: PETSc's signal handlers
  // would take SIGINT/SIGTERM from the CLI's own (a safe interruption of optimize).
  PetscOptionsSetValue(nullptr, "-no_signal_handler", nullptr);
  const PetscErrorCode ierr = PetscInitializeNoArguments();  // honours PETSC_OPTIONS
  if (ierr) {
    put(error, error_size, "PETSc could not be initialized (code " + std::to_string(ierr) + ")");
    return 1;
  }
  PetscPushErrorHandler(PetscReturnErrorHandler, nullptr);  // codes, not printed tracebacks
  // Finalized at exit under mpirun, which expects it of every rank. A singleton (a process not
  // started by mpirun, e.g. Python) is left to end without: Open MPI's finalize crashed at the
  // interpreter's exit (mca_base_var_group_deregister), and no launcher waits for it.
  if (launched_by_mpirun) std::atexit(finalize_at_exit);
  return 0;
}

int parafab_petsc_rank(void) {
  PetscMPIInt r = 0;
  MPI_Comm_rank(PETSC_COMM_WORLD, &r);
  return r;
}

int parafab_petsc_size(void) {
  PetscMPIInt n = 1;
  MPI_Comm_size(PETSC_COMM_WORLD, &n);
  return n;
}

void* parafab_petsc_create(int rows, int first, int last, const int* outer, const int* inner, const double* values,
                           const double* coords, const char* ksp, const char* pc, double rtol, int max_iterations,
                           int* input_error, char* error, int error_size) {
  *input_error = 0;
  auto* s = new System;
  try {
    s->rows = rows, s->first = first, s->last = last, s->size = parafab_petsc_size();
    const PetscInt m = last - first;
    std::vector<PetscInt> ia(m + 1);
    for (PetscInt i = 0; i <= m; ++i) ia[i] = outer[first + i] - outer[first];
    const PetscInt* ja = inner + outer[first];
    const PetscScalar* a = values + outer[first];
    CHECK(MatCreate(PETSC_COMM_WORLD, &s->A));
    CHECK(MatSetSizes(s->A, m, m, rows, rows));
    CHECK(MatSetBlockSize(s->A, 3));
    CHECK(MatSetType(s->A, s->size > 1 ? MATMPIAIJ : MATSEQAIJ));
    if (s->size > 1) CHECK(MatMPIAIJSetPreallocationCSR(s->A, ia.data(), ja, a));
    else CHECK(MatSeqAIJSetPreallocationCSR(s->A, ia.data(), ja, a));
    CHECK(MatSetOption(s->A, MAT_SYMMETRIC, PETSC_TRUE));
    CHECK(MatSetOption(s->A, MAT_SPD, PETSC_TRUE));
    // Near-nullspace: the six rigid-body modes of the DOF nodes (AMG's coarse spaces).
    Vec c = nullptr;
    CHECK(MatCreateVecs(s->A, &s->x, &s->b));
    CHECK(VecDuplicate(s->x, &c));
    CHECK(VecSetBlockSize(c, 3));
    PetscScalar* cv = nullptr;
    CHECK(VecGetArray(c, &cv));
    for (PetscInt i = 0; i < m; ++i) cv[i] = coords[i];
    CHECK(VecRestoreArray(c, &cv));
    MatNullSpace near = nullptr;
    CHECK(MatNullSpaceCreateRigidBody(c, &near));
    CHECK(MatSetNearNullSpace(s->A, near));
    CHECK(MatNullSpaceDestroy(&near));
    CHECK(VecDestroy(&c));
    CHECK(KSPCreate(PETSC_COMM_WORLD, &s->ksp));
    CHECK(KSPSetOperators(s->ksp, s->A, s->A));
    if (KSPSetType(s->ksp, ksp)) {
      *input_error = 1;
      throw Failure{std::string("solver.ksp \"") + ksp + "\" is not a Krylov solver of this PETSc (e.g. \"cg\", \"gmres\", \"minres\")"};
    }
    PC p = nullptr;
    CHECK(KSPGetPC(s->ksp, &p));
    if (PCSetType(p, pc)) {
      *input_error = 1;
      throw Failure{std::string("solver.pc \"") + pc + "\" is not a preconditioner of this PETSc (e.g. \"gamg\", \"hypre\", \"jacobi\")"};
    }
    // GAMG's Chebyshev smoothers from a safer estimate of the largest eigenvalue: with PETSc's
    // (10 iterations, ×1.1) the smoothed preconditioner of the turned L-bracket on 96 hex8 cells
    // (369,192 unknowns, K positive definite) came out indefinite (DIVERGED_INDEFINITE_PC);
    // 30 iterations and ×1.3 converge in 90 CG iterations. PETSC_OPTIONS overrides both.
    if (std::string(pc) == "gamg") {
      set_default("-mg_levels_ksp_chebyshev_esteig", "0,0.1,0,1.3");
      set_default("-mg_levels_esteig_ksp_max_it", "30");
    }
    CHECK(KSPSetNormType(s->ksp, KSP_NORM_UNPRECONDITIONED));  // rtol on ‖f − K u‖ / ‖f‖
    CHECK(KSPSetTolerances(s->ksp, rtol, 0.0, PETSC_DEFAULT, max_iterations));
    CHECK(KSPSetFromOptions(s->ksp));  // PETSC_OPTIONS may override (-ksp_monitor, ...)
    if (s->size > 1) CHECK(VecScatterCreateToAll(s->x, &s->gather, &s->whole));
    return s;
  } catch (const Failure& f) {
    put(error, error_size, f.message);
    delete s;
    return nullptr;
  }
}

int parafab_petsc_solve(void* system, const double* b, const double* x0, double* x, int* iterations,
                        double* residual_norm, int* reason, char* reason_text, int reason_size, double* setup_seconds,
                        double* memory_mb, char* error, int error_size) {
  auto* s = static_cast<System*>(system);
  try {
    PetscScalar* v = nullptr;
    CHECK(VecGetArray(s->b, &v));
    for (PetscInt i = s->first; i < s->last; ++i) v[i - s->first] = b[i];
    CHECK(VecRestoreArray(s->b, &v));
    CHECK(VecGetArray(s->x, &v));
    for (PetscInt i = s->first; i < s->last; ++i) v[i - s->first] = x0 ? x0[i] : 0.0;
    CHECK(VecRestoreArray(s->x, &v));
    CHECK(KSPSetInitialGuessNonzero(s->ksp, x0 ? PETSC_TRUE : PETSC_FALSE));
    *setup_seconds = 0;
    if (!s->set_up) {
      PetscLogDouble t0 = 0, t1 = 0;
      PetscTime(&t0);
      CHECK(KSPSetUp(s->ksp));
      PC p = nullptr;
      CHECK(KSPGetPC(s->ksp, &p));
      CHECK(PCSetUp(p));
      PetscTime(&t1);
      *setup_seconds = t1 - t0;
      s->set_up = true;
    }
    PetscLogDouble mem = 0;
    PetscMemoryGetCurrentUsage(&mem);
    *memory_mb = mem / 1e6;
    CHECK(KSPSolve(s->ksp, s->b, s->x));
    KSPConvergedReason r;
    CHECK(KSPGetConvergedReason(s->ksp, &r));
    PetscInt its = 0;
    CHECK(KSPGetIterationNumber(s->ksp, &its));
    PetscReal rn = 0;
    CHECK(KSPGetResidualNorm(s->ksp, &rn));
    *iterations = static_cast<int>(its), *residual_norm = rn, *reason = static_cast<int>(r);
    put(reason_text, reason_size, KSPConvergedReasons[r]);
    const PetscScalar* w = nullptr;
    if (s->size > 1) {
      CHECK(VecScatterBegin(s->gather, s->x, s->whole, INSERT_VALUES, SCATTER_FORWARD));
      CHECK(VecScatterEnd(s->gather, s->x, s->whole, INSERT_VALUES, SCATTER_FORWARD));
      CHECK(VecGetArrayRead(s->whole, &w));
      std::memcpy(x, w, sizeof(double) * s->rows);
      CHECK(VecRestoreArrayRead(s->whole, &w));
    } else {
      CHECK(VecGetArrayRead(s->x, &w));
      std::memcpy(x, w, sizeof(double) * s->rows);
      CHECK(VecRestoreArrayRead(s->x, &w));
    }
    return 0;
  } catch (const Failure& f) {
    put(error, error_size, f.message);
    return 1;
  }
}

void parafab_petsc_destroy(void* system) { delete static_cast<System*>(system); }

}  // extern "C"
