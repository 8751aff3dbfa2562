#include "xfem/petsc_system.h"

#include <dlfcn.h>
#include <unistd.h>

#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <mutex>
#include <set>
#include <type_traits>

#include "common/error.h"
#include "xfem/petsc/petsc_backend.h"

namespace parafab::xfem {

namespace {

int env_int(const char* name) {
  const char* v = std::getenv(name);
  return v && *v ? std::atoi(v) : -1;
}

// The back end's entry points (petsc/petsc_backend.h), from libparafab_petsc.so.
struct Backend {
  bool loaded = false;
  std::string why;  // why not, when not loaded
  decltype(&parafab_petsc_initialize) initialize = nullptr;
  decltype(&parafab_petsc_rank) rank = nullptr;
  decltype(&parafab_petsc_size) size = nullptr;
  decltype(&parafab_petsc_create) create = nullptr;
  decltype(&parafab_petsc_solve) solve = nullptr;
  decltype(&parafab_petsc_destroy) destroy = nullptr;
  bool initialized = false;
  std::string init_error;
};

// Where the back end may be, beside this binary (the build tree: the CLI, the module and the
// library in one folder) or in the install layout (bin/ or lib/python3/dist-packages/ →
// lib/parafab/); PARAFAB_PETSC_LIBRARY first.
std::vector<std::string> backend_candidates() {
  std::vector<std::string> out;
  if (const char* env = std::getenv("PARAFAB_PETSC_LIBRARY"); env && *env) out.emplace_back(env);
  std::string self;
  Dl_info info{};
  static const int anchor = 0;
  if (dladdr(&anchor, &info) && info.dli_fname && *info.dli_fname) self = info.dli_fname;
  std::error_code ec;
  const std::filesystem::path exe = std::filesystem::read_symlink("/proc/self/exe", ec);
  if (self.empty() || (!ec && std::filesystem::path(self).filename() == exe.filename())) self = exe.string();
  const std::filesystem::path dir = std::filesystem::weakly_canonical(self, ec).parent_path();
  const char* name = "libparafab_petsc.so";
  for (const auto& d : {dir, dir / ".." / "lib" / "parafab", dir / ".." / ".." / "parafab"})
    out.push_back((d / name).lexically_normal().string());
  return out;
}

Backend& backend() {
  static Backend b;
  static std::once_flag once;
  std::call_once(once, [] {
#ifndef PARAFAB_HAVE_PETSC
    b.why = "this build of ParaFab has no PETSc (install petsc-dev and rebuild)";
    return;
#else
    void* h = nullptr;
    std::string tried;
    for (const std::string& path : backend_candidates()) {
      if (!std::filesystem::exists(path)) {
        tried += (tried.empty() ? "" : ", ") + path;
        continue;
      }
      // RTLD_DEEPBIND: PETSc and MPI find their own MPI symbols before the sequential MUMPS's
      // stand-ins that Ipopt brought into the process (petsc_backend.h).
      h = dlopen(path.c_str(), RTLD_NOW | RTLD_LOCAL | RTLD_DEEPBIND);
      if (h) break;
      tried += (tried.empty() ? "" : ", ") + path + " (" + dlerror() + ")";
    }
    if (!h) {
      b.why = "the PETSc back end libparafab_petsc.so was not found or would not load (tried " + tried + ")";
      return;
    }
    auto sym = [&](auto& f, const char* name) {
      f = reinterpret_cast<std::remove_reference_t<decltype(f)>>(dlsym(h, name));
      return f != nullptr;
    };
    if (!(sym(b.initialize, "parafab_petsc_initialize") && sym(b.rank, "parafab_petsc_rank") &&
          sym(b.size, "parafab_petsc_size") && sym(b.create, "parafab_petsc_create") &&
          sym(b.solve, "parafab_petsc_solve") && sym(b.destroy, "parafab_petsc_destroy"))) {
      b.why = "libparafab_petsc.so lacks an entry point (a stale build?)";
      return;
    }
    b.loaded = true;
#endif
  });
  return b;
}

std::set<std::string> environment_names() {
  std::set<std::string> names;
  for (char** e = environ; e && *e; ++e) {
    const std::string entry = *e;
    names.insert(entry.substr(0, entry.find('=')));
  }
  return names;
}

double seconds_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

}  // namespace

int launched_ranks() {
  for (const char* name : {"OMPI_COMM_WORLD_SIZE", "PMI_SIZE", "PMIX_SIZE"})
    if (const int n = env_int(name); n > 0) return n;
  return 1;
}

int launched_rank() {
  for (const char* name : {"OMPI_COMM_WORLD_RANK", "PMI_RANK", "PMIX_RANK"})
    if (const int r = env_int(name); r >= 0) return r;
  return 0;
}

namespace {
std::string& disallowed() {
  static std::string why;
  return why;
}
}  // namespace

void disallow_petsc_in_process(const std::string& reason) { disallowed() = reason; }

bool petsc_available() { return disallowed().empty() && backend().loaded; }

void petsc_initialize() {
  if (!disallowed().empty()) PARAFAB_INPUT_ERROR(disallowed());
  Backend& b = backend();
  if (!b.loaded) PARAFAB_INPUT_ERROR(b.why);
  static std::once_flag once;
  std::call_once(once, [&] {
    const std::set<std::string> before = environment_names();
    char error[512] = {0};
    b.initialized = b.initialize(error, sizeof error) == 0;
    b.init_error = error;
    // A process not started by mpirun is its own MPI job (a singleton), and Open MPI puts that
    // job's variables into the environment; a CLI or mpirun started from here (the workbench
    // runs the CLI, a test runs mpirun) would inherit them and fail to start. They go again.
    if (launched_ranks() <= 1)
      for (const std::string& name : environment_names())
        if (!before.count(name))
          for (const char* prefix : {"OMPI_", "PMIX_", "OPAL_", "ORTE_", "PRTE_"})
            if (name.rfind(prefix, 0) == 0) unsetenv(name.c_str());
  });
  if (!b.initialized) PARAFAB_INPUT_ERROR(b.init_error);
}

int petsc_rank() {
  if (!petsc_available()) return 0;
  petsc_initialize();
  return backend().rank();
}

int petsc_ranks() {
  if (!petsc_available()) return 1;
  petsc_initialize();
  return backend().size();
}

struct PetscSystem::Impl {
  void* handle = nullptr;
  int first = 0, last = 0;
  ~Impl() {
    if (handle) backend().destroy(handle);
  }
};

PetscSystem::PetscSystem(const Eigen::SparseMatrix<double>& K, const std::vector<Vec3>& nodes,
                         const KrylovOptions& options)
    : impl_(std::make_unique<Impl>()), rows_(static_cast<int>(K.rows())), options_(options) {
  const auto t0 = std::chrono::steady_clock::now();
  PARAFAB_VERIFY(K.rows() == K.cols() && K.rows() == 3 * static_cast<Eigen::Index>(nodes.size()),
                 "PetscSystem: matrix " << K.rows() << " x " << K.cols() << " for " << nodes.size() << " nodes");
  PARAFAB_VERIFY(K.isCompressed(), "PetscSystem: the matrix must be compressed");
  PARAFAB_VERIFY(options.rtol > 0 && options.rtol < 1, "solver.rtol must be in (0, 1), got " << options.rtol);
  petsc_initialize();
  ranks_ = petsc_ranks();
  const int rank = petsc_rank();
  // Contiguous blocks of DOF nodes per rank.
  const long n_nodes = static_cast<long>(nodes.size());
  const long node0 = n_nodes * rank / ranks_, node1 = n_nodes * (rank + 1) / ranks_;
  impl_->first = static_cast<int>(3 * node0), impl_->last = static_cast<int>(3 * node1);
  std::vector<double> coords(3 * (node1 - node0));
  for (long k = node0; k < node1; ++k)
    for (int d = 0; d < 3; ++d) coords[3 * (k - node0) + d] = nodes[k](d);
  int input_error = 0;
  char error[512] = {0};
  impl_->handle = backend().create(rows_, impl_->first, impl_->last, K.outerIndexPtr(), K.innerIndexPtr(), K.valuePtr(),
                                   coords.data(), options.ksp.c_str(), options.pc.c_str(), options.rtol,
                                   options.max_iterations, &input_error, error, sizeof error);
  if (!impl_->handle) {
    if (input_error) PARAFAB_INPUT_ERROR(error);
    PARAFAB_VERIFY(false, error);
  }
  create_seconds = seconds_since(t0);
}

PetscSystem::~PetscSystem() = default;

KrylovResult PetscSystem::solve(const Eigen::VectorXd& b, const Eigen::VectorXd& x0) const {
  PARAFAB_VERIFY(b.size() == rows_, "PetscSystem::solve: right-hand side of size " << b.size() << ", expected " << rows_);
  PARAFAB_VERIFY(x0.size() == 0 || x0.size() == rows_, "PetscSystem::solve: start of size " << x0.size());
  KrylovResult r;
  const auto t0 = std::chrono::steady_clock::now();
  const double bn = b.norm();
  r.x = Eigen::VectorXd::Zero(rows_);
  // Every rank holds the same b: a zero one is zero everywhere, and no rank enters the solve.
  if (!(bn > 0)) {
    r.converged = true;
    r.reason = "zero right-hand side";
    return r;
  }
  int iterations = 0, reason = 0;
  double residual = 0, setup = 0, memory = 0;
  char reason_text[64] = {0}, error[512] = {0};
  const int status = backend().solve(impl_->handle, b.data(), x0.size() ? x0.data() : nullptr, r.x.data(), &iterations,
                                     &residual, &reason, reason_text, sizeof reason_text, &setup, &memory, error,
                                     sizeof error);
  PARAFAB_VERIFY(status == 0, error);
  if (setup > 0) setup_seconds = setup;
  memory_mb = memory;
  r.iterations = iterations;
  r.residual = residual / bn;
  r.converged = reason > 0;
  r.reason = reason_text;
  r.seconds = seconds_since(t0);
  return r;
}

}  // namespace parafab::xfem
