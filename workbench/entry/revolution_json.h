// Surfaces of revolution tiled by strips (thesis §4.8.4): `parafab revolution JOB.json` and
// parafab.revolution_strips: a meridian from ⟨e₁,γ⟩κ = a + ⟨b,γ⟩ (CVODE) and the n strips
// that cover the surface without gaps. Format in resources/doc/strips.md
// ("Surfaces of revolution").
#pragma once

#include <nlohmann/json.hpp>

namespace parafab::entry {

/// Throws parafab::Error naming the offending field.
nlohmann::json revolution_strips_json(const nlohmann::json& job);

}  // namespace parafab::entry
