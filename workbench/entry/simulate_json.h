// The simulation job of `parafab simulate` / parafab.simulate (thesis §6.4): a part, a JSON
// job (material, grid, supports, loads, gravity, outputs) and an output folder; returns the
// result JSON and writes result.json and result.vtu there. Format in README ("Simulation").
#pragma once

#include <nlohmann/json.hpp>
#include <functional>
#include <string>

namespace parafab::entry {

/// Called at phase boundaries with the phase ("read", "cut", "assemble", "solve", "newton",
/// "results", "write") and the fraction of the run done; returning false cancels the run
/// (simulate_part_json then throws parafab::Error "simulation cancelled by the user").
using ProgressFn = std::function<bool(const char* phase, double fraction)>;

/// Throws parafab::Error naming the offending job field for invalid input, or when the run
/// would not fit in memory (with the estimate). Writes result.json, result.vtu (cells and
/// cut-cell rule points) and surface.vtu (the triangulated B-rep with the fields) to out_dir.
nlohmann::json simulate_part_json(const std::string& part_path, const nlohmann::json& job,
                                  const std::string& out_dir, const ProgressFn& progress = {});

}  // namespace parafab::entry
