// Building the JSON results of the entry points cheaply: a strip result holds ~3,000 small
// arrays ([x, y] points) and ~12,000 numbers, and nlohmann's generic routes (initializer lists,
// copies, the flattening destructor) cost as much as designing the strip (callgrind, issue 13).
#pragma once

#include <Eigen/Core>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "common/error.h"

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
/// coordinates(), a Python strip call runs 1.23-1.33x fewer instructions (callgrind, 2026-11; current figures
/// in resources/doc/strips.md, "Implementation notes: speed").
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

/// A large numeric array of a result kept flat until the caller needs it (see ColumnarResult).
struct Column {
  std::vector<std::string> path;  ///< keys from the root of the result
  std::vector<double> values;     ///< row by row
  int width = 1;                  ///< 1: [v, ...]; 2, 3: [[x, y(, z)], ...]
};

/// A result whose bulk (thousands of numbers and [x, y] rows) is held as flat columns: `tree`
/// has null where each column goes. expand() writes them into the tree (the CLI and the text
/// routes); the Python binding builds its lists straight from the columns instead, skipping
/// one small nlohmann array per row.
struct ColumnarResult {
  nlohmann::json tree;
  std::vector<Column> columns;

  void put(std::vector<std::string> path, std::vector<double> values, int width = 1) {
    PARAFAB_VERIFY(!path.empty() && width >= 1 && values.size() % static_cast<size_t>(width) == 0,
                   "result column: " << values.size() << " numbers do not make rows of " << width);
    nlohmann::json* at = &tree;
    for (const auto& key : path) at = &(*at)[key];
    *at = nullptr;
    columns.push_back({std::move(path), std::move(values), width});
  }
};

/// The rows of a column as nlohmann arrays (non-finite numbers stay as they are: dump() writes
/// them as null).
inline nlohmann::json column_json(const Column& c) {
  nlohmann::json a(nlohmann::json::value_t::array);
  auto& e = a.get_ref<nlohmann::json::array_t&>();
  const size_t w = static_cast<size_t>(c.width), rows = c.values.size() / w;
  e.reserve(rows);
  for (size_t r = 0; r < rows; ++r) {
    if (w == 1) {
      e.emplace_back(c.values[r]);
      continue;
    }
    nlohmann::json row(nlohmann::json::value_t::array);
    auto& re = row.get_ref<nlohmann::json::array_t&>();
    re.reserve(w);
    for (size_t k = 0; k < w; ++k) re.emplace_back(c.values[r * w + k]);
    e.push_back(std::move(row));
  }
  return a;
}

/// The whole result as one JSON tree.
inline nlohmann::json expand(ColumnarResult&& r) {
  for (const Column& c : r.columns) {
    nlohmann::json* at = &r.tree;
    for (const auto& key : c.path) at = &(*at)[key];
    *at = column_json(c);
  }
  return std::move(r.tree);
}

}  // namespace parafab::entry::json_write
