// Strips from sections (thesis §4.8.2): `parafab sections PART JOB.json` and
// parafab.strip_sections: plane sections of a surface or solid, every section curve designed
// as a bending-active strip with the strip request of JOB["strip"]. Format in resources/doc/strips.md
// ("Strips from sections").
#pragma once

#include <nlohmann/json.hpp>
#include <string>

namespace parafab::entry {

/// Throws parafab::Error naming the offending job field; a curve that cannot be designed
/// carries its own "strip": {"error": ...} (or an infeasible strip result) instead.
nlohmann::json strip_sections_json(const std::string& part_path, const nlohmann::json& job);

}  // namespace parafab::entry
