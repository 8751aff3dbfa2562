// Cut sheets of a designed strip: the flat outline at true scale in millimetres, as ASCII DXF
// (R12: POLYLINE/VERTEX/SEQEND, LINE and TEXT entities on named layers) and as SVG (mm units,
// viewBox in mm). Pure file formatting of a strip result JSON (strip_json.h); no numerics.
//
// Layers / SVG groups: OUTLINE (the strip; for composite strips OUTER, the broad strip of
// constant width, and INNER, the narrow strip w2(s)), HOLES (diamonds of perforated strips),
// CLAMPS (a line across the strip at both ends), TEXT (name, and per end: clamp position s and
// tangent angle of the curve there).
#pragma once

#include <string>

#include <nlohmann/json.hpp>

namespace parafab::entry {

std::string strip_outline_dxf(const nlohmann::json& result);
std::string strip_outline_svg(const nlohmann::json& result);

/// Writes DXF or SVG by the extension of `path` (.dxf / .svg, case-insensitive). Throws
/// parafab::Error for an infeasible result, a result without outline or an unknown extension.
void write_strip_outline(const nlohmann::json& result, const std::string& path);

}  // namespace parafab::entry
