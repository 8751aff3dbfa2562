// The simulation job of `parafab simulate` / parafab.simulate (thesis §6.4): a part, a JSON
// job (material, grid, supports, loads, gravity, outputs) and an output folder; returns the
// result JSON and writes result.json and result.vtu there. Format in README ("Simulation").
#pragma once

#include <nlohmann/json.hpp>
#include <string>

namespace parafab::entry {

/// Throws parafab::Error naming the offending job field for invalid input, or when the run
/// would not fit in memory (with the estimate).
nlohmann::json simulate_part_json(const std::string& part_path, const nlohmann::json& job,
                                  const std::string& out_dir);

}  // namespace parafab::entry
