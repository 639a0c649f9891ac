// Reading model specs (JSON) with errors that name the spec, the key and what was expected.
// Shared by the two factories (model_factory.cpp, vector_field_factory.cpp); internal.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <initializer_list>
#include <string>

#include <nlohmann/json.hpp>

#include "csympnet/core/error.hpp"
#include "csympnet/core/types.hpp"

namespace csympnet::specs {

inline void require_object(const nlohmann::json& spec, const std::string& where) {
  require(spec.is_object(), [&] { return where + ": expected a JSON object, got " + spec.dump(); });
}

inline void reject_unknown_keys(const nlohmann::json& spec, const std::string& where,
                                std::initializer_list<const char*> allowed) {
  for (const auto& item : spec.items()) {
    const bool known = std::any_of(allowed.begin(), allowed.end(),
                                   [&](const char* key) { return item.key() == key; });
    if (known) continue;
    std::string list;
    for (const char* key : allowed) list += std::string(list.empty() ? "" : ", ") + key;
    throw Error(where + ": unknown key '" + item.key() + "'; expected only the keys " + list);
  }
}

inline std::string get_type(const nlohmann::json& spec, const std::string& where,
                            const char* valid) {
  require(spec.contains("type"), [&] {
    return where + ": missing key 'type' (expected one of: " + std::string(valid) + ")";
  });
  require(spec.at("type").is_string(), [&] {
    return where + ": key 'type' = " + spec.at("type").dump() +
           ", expected a string (one of: " + valid + ")";
  });
  return spec.at("type").get<std::string>();
}

inline Index get_count(const nlohmann::json& spec, const char* key, const std::string& where) {
  require(spec.contains(key),
          [&] { return where + ": missing key '" + key + "' (expected an integer >= 1)"; });
  const nlohmann::json& value = spec.at(key);
  require(value.is_number_integer(), [&] {
    return where + ": key '" + key + "' = " + value.dump() + ", expected an integer >= 1";
  });
  const auto count = value.get<std::int64_t>();
  require(count >= 1, [&] {
    return where + ": key '" + key + "' = " + std::to_string(count) + ", expected an integer >= 1";
  });
  return static_cast<Index>(count);
}

inline bool get_flag(const nlohmann::json& spec, const char* key, const std::string& where) {
  if (!spec.contains(key)) return false;
  const nlohmann::json& value = spec.at(key);
  require(value.is_boolean(), [&] {
    return where + ": key '" + key + "' = " + value.dump() + ", expected true or false";
  });
  return value.get<bool>();
}

// β of the damped models: finite and nonzero (d|β|/dβ vanishes at 0, so β = 0 never trains).
inline double get_beta_init(const nlohmann::json& spec, const std::string& where, double fallback) {
  if (!spec.contains("beta_init")) return fallback;
  const nlohmann::json& value = spec.at("beta_init");
  require(value.is_number(), [&] {
    return where + ": key 'beta_init' = " + value.dump() + ", expected a nonzero number";
  });
  const double beta = value.get<double>();
  require(std::isfinite(beta) && beta != 0.0, [&] {
    return where + ": key 'beta_init' = " + value.dump() +
           ", expected a finite nonzero number (d|beta|/dbeta vanishes at 0)";
  });
  return beta;
}

}  // namespace csympnet::specs
