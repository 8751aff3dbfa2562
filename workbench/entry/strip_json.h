// The strip JSON format shared by the CLI (`parafab strip`) and the Python module
// (`parafab.design_strip`): input parsing with errors that name the offending field, and
// the result as JSON. Documented in resources/doc/json-reference.md and
// resources/doc/strips.md ("The request and the result").
#pragma once

#include <nlohmann/json.hpp>

#include "json_write.h"

namespace parafab::entry {

/// Parses a strip request, designs the strip and returns the result JSON.
/// Throws parafab::Error naming the offending field for invalid input.
nlohmann::json design_strip_json(const nlohmann::json& request);
/// The same result with its per-sample arrays, outline and curve poles and knots as flat
/// columns (design_strip_json expands them; the Python binding converts them directly).
json_write::ColumnarResult design_strip_columns(const nlohmann::json& request);

/// {"error": {"message": ..., "kind": ...}}: what the CLI prints for bad input.
nlohmann::json error_json(const std::string& message, const std::string& kind);

}  // namespace parafab::entry

namespace parafab {
class BSplineCurve2;
}
namespace parafab::entry {
/// The "curve" field of a strip request (bspline, or points interpolated by a quartic), as
/// design_strip_json reads it; shared with strip-improve.
BSplineCurve2 parse_strip_curve(const nlohmann::json& request);
}  // namespace parafab::entry
