// The rod JSON format shared by the CLI (`parafab rod`) and the Python module
// (`parafab.design_rod`): a space curve (3D B-spline or points), material, loads, w_reg and
// the section choice in; the designed Kirchhoff rod (complex, twist, elliptical sections,
// end frames, load iterations, optional forward simulation) out. SI units.
#pragma once

#include <nlohmann/json.hpp>

namespace parafab::entry {

/// Parses a rod request, designs the rod (thesis §5.7–5.8) and returns the result JSON;
/// with "validate": true also simulates the designed rod (discrete elastic rod).
/// Throws parafab::Error naming the offending field for invalid input (and for κ = 0,
/// naming the arc length).
nlohmann::json design_rod_json(const nlohmann::json& request);

}  // namespace parafab::entry
