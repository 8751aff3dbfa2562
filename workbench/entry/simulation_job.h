// The simulation job's fields (thesis §6.4) as `parafab simulate` reads them, and the elastic
// objectives of `parafab optimize` (compliance, failure, target) with them: one parser into one
// typed struct in named parts (material, grid, conditions, solver options, run). Its keys are
// checked before (request_schema.cpp: unknown keys, integer ranges, leaf types); this reads the
// values, with errors naming the field. Format in resources/doc/simulation.md ("Simulation
// (linear XFEM)") and resources/doc/json-reference.md.
#pragma once

#include <Eigen/Core>
#include <memory>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "face_lookup.h"
#include "grid_estimate.h"
#include "grid_model.h"
#include "part_reader.h"
#include "xfem/linear_xfem.h"
#include "xfem/materials.h"

namespace parafab::entry {

/// The command that reads the job: its defaults and some of its messages differ.
enum class JobCommand { Simulate, Optimize };

/// The part whose faces a job names, by index or by a point on it. The face locator is built
/// on the first point (once per job, not per named face).
struct NamedPart {
  /// The optimizer's: points within 1e-6 of the part's diagonal (+1e-9), in the part's frame;
  /// a point that names no face is an error naming the entry ("supports[0]: no face of ...").
  explicit NamedPart(const occ::PartShape& part);
  /// `tolerance`: how far a point may lie from its face; `origin`: the local frame's origin
  /// (local_frame.h): job points are in the part's own frame and moved by −origin onto `part`;
  /// `entry_in_errors`: a missed point's error starts with the entry's path.
  NamedPart(const occ::PartShape& part, double tolerance, const Eigen::Vector3d& origin, bool entry_in_errors);
  ~NamedPart();
  NamedPart(const NamedPart&) = delete;
  NamedPart& operator=(const NamedPart&) = delete;

  const occ::PartShape& part;
  double tolerance;
  Eigen::Vector3d origin = Eigen::Vector3d::Zero();
  bool entry_in_errors = true;
  const occ::FaceLocator& locator() const;

 private:
  mutable std::unique_ptr<occ::FaceLocator> locator_;
};

/// The face `item` names: {"face": i} (validated) or {"point": [x, y, z]} on it; `path` names
/// the entry in errors ("supports[0]").
int face_index(const NamedPart& named, const nlohmann::json& item, const std::string& path);

/// What differs between the commands that read the job.
struct SimulationJobOptions {
  JobCommand command = JobCommand::Simulate;
  xfem::ElementType default_element = xfem::ElementType::Hex27;
  /// A hyperelastic material.model is allowed (otherwise an error: the optimizer's compliance
  /// and failure objectives run on a linear solve).
  bool hyperelastic_ok = true;

  /// `parafab simulate` (both commands' defaults side by side in simulation_job.cpp).
  static SimulationJobOptions simulate();
  /// `parafab optimize`'s elastic objectives; `hyperelastic_ok` where every elastic term has
  /// an adjoint through the tangent (the target shape).
  static SimulationJobOptions optimize(bool hyperelastic_ok);
};

/// The simulation job, typed; every default is the member's initializer or set by the parser
/// (simulation_job.cpp) from the command's SimulationJobOptions.
struct SimulationJob {
  /// "material" {E, nu, density, model} and "load_steps".
  struct Material {
    xfem::ElasticMaterial elastic;  ///< E (required), nu (default 0.3), density (default 0)
    std::string model = "linear";   ///< "linear" (small strain, one linear solve) or a hyperelastic law
    std::shared_ptr<const xfem::Material> law;  ///< the hyperelastic law (null: linear)
    int load_steps = 5;  ///< load steps of the hyperelastic Newton solve
    bool linear() const { return !law; }
  } material;

  /// "element" and "grid" {cells, cell_size, origin, method}, "quadrature" (the rules' tuning,
  /// thesis §6.3.3): cut by face, rules raised for the element.
  struct Grid {
    occ::GridModelOptions options;  ///< grid.cells default: default_cells(element)
  } grid;

  /// "supports", "loads" and "gravity" (into solver.gravity).
  struct Conditions {
    std::vector<xfem::DirichletCondition> supports;
    std::vector<xfem::TractionCondition> loads;  ///< traction per area (a force spread over its face)
    /// Per load: its total force, or zero for a traction (the optimizer spreads a force over the
    /// load face of every model, as `parafab simulate` does on its part).
    std::vector<xfem::Vec3> forces;
  } conditions;

  /// The solve: element, gravity, the Nitsche penalty, incompatible_modes, "reuse" (what an
  /// update reuses of the previous solve) and memory_limit_mb (default 70% of the memory).
  xfem::LinearXfemOptions solver;

  /// How `parafab simulate` runs it: "threads" (0: all cores), and grid.target / grid.max_cells
  /// (grids refined until the estimated relative error is below the target; 0: the given grid).
  struct Run {
    int threads = 0;
    double target = 0;
    int max_cells = 64;
  } run;
};

/// Reads the job's material, grid, conditions, solver options and run options (in that order,
/// the first invalid field an error naming it).
SimulationJob parse_simulation_job(const NamedPart& part, const nlohmann::json& job, const SimulationJobOptions& options);

/// The box, area and volume as estimate_grid and estimate_solve read them.
occ::PartInfo size_info(const occ::PartBoxArea& size);

/// The size of a job's solve before its grid is cut (grid_estimate.h) and what it may use.
struct JobSize {
  SolveEstimate solve;  ///< unknowns, factor and peak memory (compact and thin-walled figures)
  GridEstimate cut;     ///< cutting and rules
  double limit_mb = 0;     ///< the job's solver.memory_limit_mb
  double physical_mb = 0;  ///< the machine's memory
};
JobSize estimate_job_size(const occ::PartInfo& info, const occ::GridOptions& grid, const xfem::LinearXfemOptions& solver);

/// Refuses (parafab::Error with the estimate) a job whose thin-walled figure exceeds the limit,
/// or whose cut would not fit; between the figures the factor's exact size decides before it is
/// computed (SparseCholesky). The message says the command's remedy.
void refuse_if_too_big(const JobSize& size, JobCommand command);

}  // namespace parafab::entry
