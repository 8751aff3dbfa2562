// The strip JSON format shared by the CLI (`parafab strip`) and the Python module
// (`parafab.design_strip`): input parsing with errors that name the offending field, and
// the result as JSON. Documented in README.md ("JSON formats").
#pragma once

#include <nlohmann/json.hpp>

namespace parafab::entry {

/// Parses a strip request, designs the strip and returns the result JSON.
/// Throws parafab::Error naming the offending field for invalid input.
nlohmann::json design_strip_json(const nlohmann::json& request);

/// {"error": {"message": ..., "kind": ...}}: what the CLI prints for bad input.
nlohmann::json error_json(const std::string& message, const std::string& kind);

}  // namespace parafab::entry
