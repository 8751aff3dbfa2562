// The C interface of the PETSc back end (libparafab_petsc.so), which petsc_system.cpp opens at
// run time with RTLD_DEEPBIND. Why a separate library: Ipopt links the sequential MUMPS, whose
// stand-in MPI exports MPI_Comm_rank and others that return "rank 0 of 1"; linked into one
// binary, PETSc's MPI calls would find those first. Opened with RTLD_DEEPBIND, PETSc and Open
// MPI resolve their symbols in their own dependencies first.
#pragma once

extern "C" {
/// 0 on success; else the message in error.
int parafab_petsc_initialize(char* error, int error_size);
int parafab_petsc_rank(void);
int parafab_petsc_size(void);
/// The rows [first, last) of this rank of a symmetric matrix with `rows` rows stored by columns
/// (column i = row i: outer/inner/values of a compressed column matrix, whole), the positions
/// of this rank's DOF nodes (3 per node, for the rigid-body near-nullspace). Null on failure:
/// *input_error = 1 when the ksp or pc name is unknown; error holds the message.
void* parafab_petsc_create(int rows, int first, int last, const int* outer, const int* inner, const double* values,
                           const double* coords, const char* ksp, const char* pc, double rtol, int max_iterations,
                           int* input_error, char* error, int error_size);
/// x (whole, every rank) with K x = b (whole); x0 may be null. 0 on success (converged or not:
/// *reason > 0 converged); else the message in error.
int parafab_petsc_solve(void* system, const double* b, const double* x0, double* x, int* iterations,
                        double* residual_norm, int* reason, char* reason_text, int reason_size, double* setup_seconds,
                        double* memory_mb, char* error, int error_size);
void parafab_petsc_destroy(void* system);
}
