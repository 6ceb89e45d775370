#pragma once
// Internal: strict reading of evpipe's small YAML files with errors naming file and key path.

#include "evpipe/camera/error.hpp"
#include "text_file.hpp"

#include <fmt/format.h>
#include <yaml-cpp/yaml.h>

#include <initializer_list>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace evpipe::camera::detail {

/// Parses YAML text; syntax errors become ModelError(file, "", "YAML syntax error at line L, column C: ...").
inline YAML::Node parse_yaml(std::string_view text, const std::string& file) {
  try {
    return YAML::Load(std::string(strip_bom(text)));
  } catch (const YAML::Exception& e) {
    throw ModelError(
        file, "",
        fmt::format("YAML syntax error at line {}, column {}: {}", e.mark.line + 1, e.mark.column + 1, e.msg));
  }
}

/// The top-level map `section` of a document, which must be a map.
inline YAML::Node require_section(const YAML::Node& root, const std::string& file, const std::string& section) {
  if (!root.IsMap()) throw ModelError(file, "", fmt::format("expected a YAML map with a '{}:' key", section));
  YAML::Node node = root[section];
  if (!node) throw ModelError(file, section, "missing");
  if (!node.IsMap()) throw ModelError(file, section, "must be a map of keys");
  return node;
}

/// Rejects keys of `map` not in `allowed` (a misspelt key must not fall back to a default silently).
inline void reject_unknown_keys(const YAML::Node& map, std::initializer_list<std::string_view> allowed,
                                const std::string& file, const std::string& path) {
  for (const auto& kv : map) {
    const std::string key = kv.first.IsScalar() ? kv.first.Scalar() : std::string("<non-scalar key>");
    bool known = false;
    for (auto a : allowed) known = known || key == a;
    if (!known) {
      std::string list;
      for (auto a : allowed) {
        if (!list.empty()) list += ", ";
        list += a;
      }
      throw ModelError(file, fmt::format("{}.{}", path, key), fmt::format("unknown key (expected one of: {})", list));
    }
  }
}

/// A finite number from a scalar node.
inline double to_double(const YAML::Node& node, const std::string& file, const std::string& field) {
  if (!node.IsScalar()) throw ModelError(file, field, "must be a number");
  const auto v = parse_double(node.Scalar());
  if (!v) throw ModelError(file, field, fmt::format("not a finite number: '{}'", excerpt(node.Scalar())));
  return *v;
}

/// A required number `key` of `map`.
inline double require_double(const YAML::Node& map, const std::string& key, const std::string& file,
                             const std::string& path) {
  const YAML::Node node = map[key];
  if (!node) throw ModelError(file, path + "." + key, "missing");
  return to_double(node, file, path + "." + key);
}

/// An optional number `key` of `map`.
inline std::optional<double> optional_double(const YAML::Node& map, const std::string& key, const std::string& file,
                                             const std::string& path) {
  const YAML::Node node = map[key];
  if (!node || node.IsNull()) return std::nullopt;
  return to_double(node, file, path + "." + key);
}

/// A required integer `key` of `map`.
inline long long require_integer(const YAML::Node& map, const std::string& key, const std::string& file,
                                 const std::string& path) {
  const YAML::Node node = map[key];
  const std::string field = path + "." + key;
  if (!node) throw ModelError(file, field, "missing");
  if (!node.IsScalar()) throw ModelError(file, field, "must be an integer");
  const auto v = parse_int64(node.Scalar());
  if (!v) throw ModelError(file, field, fmt::format("not an integer: '{}'", excerpt(node.Scalar())));
  return *v;
}

/// A sequence of numbers (any length; the caller checks the count and names it).
inline std::vector<double> to_doubles(const YAML::Node& node, const std::string& file, const std::string& field) {
  if (!node.IsSequence()) throw ModelError(file, field, "must be a list of numbers, e.g. [1, 2, 3]");
  std::vector<double> out;
  out.reserve(node.size());
  for (std::size_t i = 0; i < node.size(); ++i)
    out.push_back(to_double(node[i], file, fmt::format("{}[{}]", field, i)));
  return out;
}

}  // namespace evpipe::camera::detail
