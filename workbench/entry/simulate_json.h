// The simulation job of `parafab simulate` / parafab.simulate (thesis §6.4): a part, a JSON
// job (material, grid, supports, loads, gravity, outputs) and an output folder; returns the
// result JSON and writes result.json and result.vtu there. Format in resources/doc/simulation.md
// ("Simulation (linear XFEM)") and resources/doc/json-reference.md.
#pragma once

#include <Eigen/Core>
#include <memory>
#include <nlohmann/json.hpp>
#include <functional>
#include <string>

namespace parafab::occ {
struct PartShape;
struct GridModel;
}  // namespace parafab::occ
namespace parafab::xfem {
class LinearXfemSolver;
}  // namespace parafab::xfem

namespace parafab::entry {

/// Called at phase boundaries with the phase ("read", "cut", "assemble", "solve", "newton",
/// "results", "write") and the fraction of the run done; returning false cancels the run
/// (simulate_part_json then throws parafab::Error "simulation cancelled by the user").
using ProgressFn = std::function<bool(const char* phase, double fraction)>;

/// A simulation that keeps its grid model, so that a changed part (a parameter edit that moves
/// some faces) is re-cut only in the blocks the change touches (occ::rebuild_grid_model) and
/// solved again. Faces named by point are looked up again on the new part; by index, the index
/// is kept (CAD systems usually keep face order when only dimensions change).
class SimulationSession {
 public:
  /// Reads the part and checks the job; throws parafab::Error like simulate_part_json.
  SimulationSession(const std::string& part_path, const nlohmann::json& job);
  ~SimulationSession();
  /// Size of the run before running it: {"unknowns", "factor_mb" (a compact part),
  /// "factor_mb_min" (a thin-walled one), "peak_mb", "peak_mb_min" (the whole run), "limit_mb",
  /// "memory_mb" (physical), "fits" (with the compact figure), "may_fit", "cut"}. run() and
  /// update() refuse a run whose thin-walled figure exceeds limit_mb; between the figures the
  /// factor's exact size decides before it is computed.
  nlohmann::json estimate() const;
  /// Cuts, solves and reports (the result JSON of simulate_part_json).
  nlohmann::json run(const std::string& out_dir, const ProgressFn& progress = {});
  /// The same job on a changed part on the same grid; the result carries "recut" (changed
  /// faces and edges, blocks re-cut, subvolumes kept and new). On invalid input the session
  /// stays on its old part.
  nlohmann::json update(const std::string& new_part_path, const std::string& out_dir,
                        const ProgressFn& progress = {});

 private:
  struct Setup;
  void load_part(const std::string& part_path);
  void refuse_if_too_big() const;
  std::unique_ptr<Setup> parse_job() const;
  template <class Report>
  nlohmann::json run_to_target(const std::string& out_dir, const Report& report);
  template <class Report>
  nlohmann::json solve(const std::string& out_dir, const Report& report, const nlohmann::json& recut);

  nlohmann::json job_;
  std::string part_path_;
  /// The local frame's origin in the part's own frame (local_frame.h), fixed by the first part
  /// (an update keeps the grid, hence the frame): part_ and the model are local; job points
  /// are moved into it, reported positions (VTU points, centre of mass) back.
  Eigen::Vector3d frame_origin_ = Eigen::Vector3d::Zero();
  bool frame_set_ = false;
  std::shared_ptr<const occ::PartShape> part_;
  std::unique_ptr<Setup> setup_;
  std::unique_ptr<occ::GridModel> model_;
  /// Kept between runs and updates: a re-solve whose stiffness has the analyzed pattern reuses
  /// CHOLMOD's symbolic analysis.
  std::unique_ptr<xfem::LinearXfemSolver> linear_solver_;
  /// Kept between runs and updates: which points of cut elements OCCT found in the material
  /// (for the largest displacement and stress), per cell whose content did not change.
  struct InsideCache;
  std::unique_ptr<InsideCache> inside_cache_;
};

/// The job's "threads" (N > 0; default: all cores) bounds the threads of every phase of run()
/// and update() (a tbb::global_control for their duration); results do not depend on it.
/// Throws parafab::Error naming the offending job field for invalid input, or when the run
/// would not fit in memory (with the estimate). Writes result.json, result.vtu (cells and
/// cut-cell rule points) and surface.vtu (the triangulated B-rep with the fields) to out_dir.
nlohmann::json simulate_part_json(const std::string& part_path, const nlohmann::json& job,
                                  const std::string& out_dir, const ProgressFn& progress = {});

}  // namespace parafab::entry
