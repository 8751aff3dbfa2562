// `parafab strip-improve` / parafab.strip_improve: fabricability optimization of a strip curve
// (thesis §4.6.2) and the §4.8.2 fairing of sampled curves. JSON in, JSON out; the request is
// a strip request (README "JSON formats") plus an optional "improve" object; the result carries
// the new B-spline, its R, the control-point move, the curve deviation, the iteration history
// and the strip designed for the new curve ("design", the strip result format).
#pragma once

#include <nlohmann/json.hpp>

namespace parafab::entry {

/// target_R > 0 overrides request.improve.target_R. Throws parafab::Error naming the field.
nlohmann::json improve_strip_json(const nlohmann::json& request, double target_R = 0);

}  // namespace parafab::entry
