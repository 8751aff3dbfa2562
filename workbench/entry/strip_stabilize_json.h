// `parafab strip-stabilize` / parafab.stabilize_strip: stability recovery of a strip curve
// (thesis §4.5.4, Algorithm 4.2). JSON in, JSON out; the request is a strip request (resources/doc/strips.md,
// "The request and the result") plus an optional "stabilize" object; the result carries the verdicts and
// conjugate points before/after, the new B-spline, R, the control-point move, the curve
// deviation, the iteration history and the strip designed for the new curve ("design").
#pragma once

#include <nlohmann/json.hpp>

namespace parafab::entry {

/// R_max > 0 overrides request.stabilize.R_max. Throws parafab::Error naming the field.
nlohmann::json stabilize_strip_json(const nlohmann::json& request, double R_max = 0);

}  // namespace parafab::entry
