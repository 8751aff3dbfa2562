// Building the JSON results of the entry points cheaply: a strip result holds ~3,000 small
// arrays ([x, y] points) and ~12,000 numbers, and nlohmann's generic routes (initializer lists,
// copies, the flattening destructor) cost as much as designing the strip (callgrind, issue 13).
#pragma once

#include <Eigen/Core>
#include <nlohmann/json.hpp>

namespace parafab::entry::json_write {

/// [v0, v1, ...] of a fixed-size Eigen vector, built in place (json::array({x, y}) goes
/// through an initializer list of json_refs and copies every element).
template <class Vector>
nlohmann::json coordinates(const Eigen::MatrixBase<Vector>& v) {
  nlohmann::json a(nlohmann::json::value_t::array);
  auto& e = a.get_ref<nlohmann::json::array_t&>();
  e.reserve(static_cast<size_t>(v.size()));
  for (Eigen::Index i = 0; i < v.size(); ++i) e.emplace_back(static_cast<double>(v[i]));
  return a;
}

/// Empties `j` bottom-up, so that destroying it afterwards is cheap. nlohmann 3.11's destructor
/// moves every node of a tree once more onto a growing stack (to bound recursion on hostile
/// input); the results built here are a few levels deep, so plain recursion is safe. With it and
/// coordinates(), a Python strip call runs 1.23-1.33x fewer instructions (callgrind, README).
/// `j` is an empty container (or the unchanged scalar) afterwards.
inline void dismantle(nlohmann::json& j) {
  if (j.is_array()) {
    auto& a = j.get_ref<nlohmann::json::array_t&>();
    for (auto& e : a)
      if (e.is_structured()) dismantle(e);
    a.clear();
  } else if (j.is_object()) {
    auto& o = j.get_ref<nlohmann::json::object_t&>();
    for (auto& kv : o)
      if (kv.second.is_structured()) dismantle(kv.second);
    o.clear();
  }
}

}  // namespace parafab::entry::json_write
