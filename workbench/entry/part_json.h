// The part inspection JSON shared by the CLI (`parafab inspect`): faces with types, mid-level
// parameters, NURBS and trimming loops, edges, tangency and coaxial relations (thesis §6.2.1, §6.5.1).
#pragma once

#include <nlohmann/json.hpp>
#include <string>

#include "face_model.h"
#include "part_reader.h"

namespace parafab::entry {

struct InspectOptions {
  occ::ReadOptions read;
  occ::FaceModelOptions model;
};

/// Reads the part at `path` (STEP or BREP) and returns its face model as JSON:
/// {source, solid, bbox, volume, area, faces, edges, relations}. Throws parafab::Error for
/// invalid input (see occ::read_part).
nlohmann::json inspect_part_json(const std::string& path, const InspectOptions& options = {});

}  // namespace parafab::entry
