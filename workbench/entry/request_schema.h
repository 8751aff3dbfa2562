// The known keys of every JSON request and job, in one table per format: checked before a
// request is parsed (an unknown key is an error naming it and the nearest known key; an integer
// field holding 2.5 is an error), and printed as resources/doc/json-reference.md by
// `parafab reference` (tests/docs check that the file is current).
#pragma once

#include <memory>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

namespace parafab::entry::schema {

struct Node;
using NodePtr = std::shared_ptr<const Node>;

/// One key of an object: its name, what it holds, and a line of documentation.
struct Field {
  std::string name;
  NodePtr node;
  std::string doc;
};

/// What a value holds. Objects list their keys; arrays their item; leaves a type name. A value
/// of another JSON type than the node's (a boolean where an object may stand, "auto" for a list)
/// is left to the parser, which knows the alternatives and says them.
struct Node {
  enum class Kind { Leaf, Object, Array };
  Kind kind = Kind::Leaf;
  std::string type;  // leaves: "number", "integer", "boolean", "string", "[x, y, z]", ...
  long long min = 0, max = 0;  // integer leaves: the allowed range
  std::vector<Field> fields;   // objects
  NodePtr base;                // objects: the keys of another object come too (strip-improve: strip's)
  std::string base_name;       // how the reference names the base ("the strip request")
  NodePtr item;                // arrays
};

/// How deeply a request may nest (objects and lists): the deepest format needs 6; the copies and
/// checks of a request nested thousands deep would exhaust the stack.
constexpr int kMaxDepth = 64;

/// The request formats, one per entry (CLI subcommand, Python function).
enum class Format { Strip, StripImprove, StripStabilize, Rod, Simulation, Optimization, Sections, Revolution };

/// The schema of a format, and its name in messages ("simulation job").
const NodePtr& of(Format format);
std::string name_of(Format format);

/// Checks `request` against the known keys of `format`: every object's keys (an unknown key
/// throws parafab::Error "griid: unknown key in the simulation job, did you mean \"grid\"?")
/// and the integer fields (whole numbers in range). Types other than these are the parsers'.
void check(const nlohmann::json& request, Format format);

/// The same on any value against any node; `path` names it in messages ("" for the top).
void check(const nlohmann::json& value, const Node& node, const std::string& path, const std::string& what);

/// The nearest of `candidates` to `word` (edit distance, at most a third of its length, at
/// least 2), or "" if none is that near.
std::string nearest(const std::string& word, const std::vector<std::string>& candidates);

/// The JSON reference (Markdown): one table per object of every format.
std::string reference_markdown();

}  // namespace parafab::entry::schema
