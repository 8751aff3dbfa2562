// Stability of strips (thesis §4.5) in the JSON format shared by the CLI
// (`parafab strip-stability`) and Python (`parafab.strip_stability`), and the `stability`
// field of every strip result.
#pragma once

#include <nlohmann/json.hpp>

#include "strips/jacobi_stability.h"

namespace parafab::entry {

/// The request's "stability" field: true/false or {"edges": n, "eigenvalue_check": bool,
/// "simulation_edges": n}. Returns false when the field says false. Throws parafab::Error
/// naming the field.
bool parse_stability_options(const nlohmann::json& request, StripStabilityOptions& options);

/// {stable, sigma, method, constraints, legendre, Z_end, min_Z, s, Z, seconds, message[,
/// eigenvalue {...}, agree, timings]}.
nlohmann::json stability_to_json(const StripStability& s, double length);

/// `parafab strip-stability`: a strip request (as for `parafab strip`) designed, then tested
/// by both methods; the result holds the design summary and the full stability object.
nlohmann::json strip_stability_json(const nlohmann::json& request);

}  // namespace parafab::entry
