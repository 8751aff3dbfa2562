// The part integration JSON of the CLI (`parafab integrate`): mass properties of a part from
// the cut-cell quadrature (thesis §6.3) beside OpenCASCADE's own, errors, counts and timings.
#pragma once

#include <nlohmann/json.hpp>
#include <string>

#include "part_integration.h"
#include "part_reader.h"

namespace parafab::entry {

struct IntegrateOptions {
  occ::ReadOptions read;
  occ::IntegrationOptions integration;
  bool estimate_only = false;  ///< return {part, estimate} without cutting
  bool force = false;          ///< run even when the estimate exceeds 70 % of the memory
};

/// Reads the part, estimates the grid (grid_estimate.h), refuses a grid that would not fit
/// (parafab::Error naming the estimate and --force) unless `force`, integrates it on the grid
/// and returns {part, estimate, grid, rules, occt, relative_errors, diagnostics, seconds}.
nlohmann::json integrate_part_json(const std::string& path, const IntegrateOptions& options = {});

}  // namespace parafab::entry
