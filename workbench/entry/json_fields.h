// Reading typed fields from the JSON requests of the entry points, with errors that name the
// field and the offending value (parafab::Error via PARAFAB_INPUT_ERROR). Shared by the
// strip, rod, simulation and sections formats.
#pragma once

#include <Eigen/Core>
#include <cmath>
#include <initializer_list>
#include <nlohmann/json.hpp>
#include <string>

#include "common/error.h"

namespace parafab::entry::fields {

/// obj[key]; "missing PATH.key" if absent, and an error if obj is not an object.
inline const nlohmann::json& require(const nlohmann::json& obj, const char* key, const std::string& path) {
  if (!obj.is_object()) PARAFAB_INPUT_ERROR(path << " must be a JSON object, got " << obj.type_name());
  auto it = obj.find(key);
  if (it == obj.end()) PARAFAB_INPUT_ERROR("missing " << path << "." << key);
  return *it;
}

/// A finite number.
inline double number(const nlohmann::json& v, const std::string& path) {
  if (!v.is_number()) PARAFAB_INPUT_ERROR(path << " must be a number, got " << v.dump());
  const double x = v.get<double>();
  if (!std::isfinite(x)) PARAFAB_INPUT_ERROR(path << " is not finite");
  return x;
}

/// [x, y, z] of finite numbers.
inline Eigen::Vector3d vec3(const nlohmann::json& v, const std::string& path) {
  if (!v.is_array() || v.size() != 3) PARAFAB_INPUT_ERROR(path << " must be [x, y, z], got " << v.dump());
  return Eigen::Vector3d(number(v[0], path + "[0]"), number(v[1], path + "[1]"), number(v[2], path + "[2]"));
}

/// An integer in [lo, hi].
inline int integer(const nlohmann::json& v, const std::string& path, int lo, int hi) {
  if (!v.is_number_integer() || v.get<long long>() < lo || v.get<long long>() > hi)
    PARAFAB_INPUT_ERROR(path << " must be an integer " << lo << ".." << hi << ", got " << v.dump());
  return v.get<int>();
}

/// `obj` is an object whose keys are all among `keys` (an unknown key names the known ones).
inline void only(const nlohmann::json& obj, const std::string& path, std::initializer_list<const char*> keys) {
  if (!obj.is_object()) PARAFAB_INPUT_ERROR(path << " must be a JSON object, got " << obj.dump());
  for (auto it = obj.begin(); it != obj.end(); ++it) {
    bool ok = false;
    for (const char* k : keys) ok |= it.key() == k;
    if (!ok) {
      std::string list;
      for (const char* k : keys) list += std::string(list.empty() ? "" : ", ") + k;
      PARAFAB_INPUT_ERROR(path << "." << it.key() << " is not a known field (known: " << list << ")");
    }
  }
}

}  // namespace parafab::entry::fields
