// `parafab strip-improve` / parafab.strip_improve: fabricability optimization of a strip curve
// (thesis §4.6.2) and the §4.8.2 fairing of sampled curves. JSON in, JSON out; the request is
// a strip request (resources/doc/strips.md, "The request and the result") plus an optional "improve" object; the result carries
// the new B-spline, its R, the control-point move, the curve deviation, the iteration history
// and the strip designed for the new curve ("design", the strip result format).
#pragma once

#include <string>
#include <utility>
#include <vector>

#include <nlohmann/json.hpp>

#include "common/bspline.h"

namespace parafab::entry {

/// {"degree", "knots", "poles"} of a non-rational B-spline (the "bspline" curve input format).
nlohmann::json bspline_json(const BSplineCurve2& curve);

/// §4.8.2 fair fit of sampled points with spurious-inflection removal. `fair` is null (defaults)
/// or {"poles", "fairness", "min_separation", "end_separation"}; `path` names it in errors.
/// Returns the curve and a report {poles, fairness, min_separation, inflections_before,
/// inflections, inflection_s, rounds, done, max_error, message}.
/// Throws parafab::Error naming the field when `fair` is not a valid options object (or null).
void check_fair_options(const nlohmann::json& fair, const std::string& path);

std::pair<BSplineCurve2, nlohmann::json> fair_points_json(const std::vector<Vec2>& points,
                                                          const nlohmann::json& fair, const std::string& path);

/// target_R > 0 overrides request.improve.target_R. Throws parafab::Error naming the field.
nlohmann::json improve_strip_json(const nlohmann::json& request, double target_R = 0);

}  // namespace parafab::entry
