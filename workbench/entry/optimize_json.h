// The shape optimization job of `parafab optimize` / parafab.optimize (thesis §6.5): a part,
// a JSON job (parameters, objective, constraints, max_iterations; supports/loads of the
// simulation job fix their faces; objective "compliance" also reads material, grid, supports,
// loads and gravity like `parafab simulate`) and an output folder for optimized.step, history.json and
// history.png. Format in resources/doc/optimization.md ("The job") and
// resources/doc/json-reference.md.
#pragma once

#include <functional>
#include <nlohmann/json.hpp>
#include <string>

namespace parafab::entry {

/// Called after every accepted iterate with {"iteration", "objective", "constraint_violation",
/// "seconds"}; returning false interrupts (the last valid model is written, status "interrupted").
using OptimizeProgressFn = std::function<bool(const nlohmann::json& iterate)>;

/// Polled before every evaluation: true interrupts the run as the progress callback's false
/// does, without waiting for the next accepted iterate (a SIGINT/SIGTERM flag).
using InterruptFn = std::function<bool()>;

/// Runs the optimization and returns the history JSON (also written to out_dir/history.json
/// with out_dir/optimized.step and, when matplotlib is there, out_dir/history.png). Throws
/// parafab::Error naming the offending job field (an objective that is not implemented yet,
/// "stress", included). The part file is only read. Interrupted (`interrupted`, or `progress`
/// returning false), it writes the same files for the best valid iterate so far, with the
/// history's status "interrupted"; every file is written under a temporary name and renamed.
nlohmann::json optimize_part_json(const std::string& part_path, const nlohmann::json& job,
                                  const std::string& out_dir, const OptimizeProgressFn& progress = {},
                                  const InterruptFn& interrupted = {});

}  // namespace parafab::entry
