#include "csympnet/models/model_file.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>

#include "../kernels/registry.hpp"
#include "csympnet/core/error.hpp"
#include "csympnet/core/hash.hpp"
#include "csympnet/io/files.hpp"
#include "csympnet/io/json_text.hpp"
#include "csympnet/models/dof_scaled_map.hpp"
#include "csympnet/models/hamiltonian_library.hpp"
#include "csympnet/models/normalized_map.hpp"

namespace csympnet {

namespace {

// The model constructors compute parameter counts as products of the sizes in the spec
// (layers x sublayers x d^2, width^2, ...) without overflow checks. A file's sizes come from
// outside, so their product is bounded first: with every size product P <= 2^28 each such
// count stays below P^2 <= 2^56. A real model that large could not be stored in a file anyway.
constexpr double kMaxSizeProduct = 268435456.0;  // 2^28

std::string short_number(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.3g", v);
  return buf;
}

void product_of_sizes(const nlohmann::json& spec, double& product) {
  if (spec.is_number_integer()) {
    product *= std::max(1.0, std::abs(spec.get<double>()));
  } else if (spec.is_object() || spec.is_array()) {
    for (const auto& item : spec) product_of_sizes(item, product);
  }
}

// What a map's parameters must satisfy beyond being finite: a library map's inverse mass
// positive definite (hamiltonian_library.hpp). The wrappers keep the inner map's θ first.
void check_map_params(const Model& model, const Vector& theta, const std::string& where) {
  const OneStepMap* map = model.map.get();
  for (;;) {
    if (const auto* n = dynamic_cast<const NormalizedMap*>(map)) {
      map = &n->inner();
    } else if (const auto* s = dynamic_cast<const DofScaledMap*>(map)) {
      map = &s->inner();
    } else {
      break;
    }
  }
  if (const auto* lib = dynamic_cast<const HamiltonianLibraryMap*>(map))
    lib->check_inverse_mass(theta.head(lib->n_params()), where);
}

}  // namespace

// FNV-1a over the architecture, the context and the exact bits of every parameter (bytes in
// little-endian order, so the checksum is the same on every platform).
std::string model_checksum(const nlohmann::json& model, const nlohmann::json& meta,
                           const Vector& theta) {
  std::uint64_t h = fnv1a64(model.dump());
  h = fnv1a64(meta.dump(), h);
  for (Index i = 0; i < theta.size(); ++i) {
    std::uint64_t bits = 0;
    std::memcpy(&bits, &theta(i), sizeof bits);
    char bytes[8];
    for (int b = 0; b < 8; ++b) bytes[b] = static_cast<char>((bits >> (8 * b)) & 0xffU);
    h = fnv1a64(std::string_view(bytes, 8), h);
  }
  return "fnv1a64:" + hex64(h);
}

nlohmann::json model_to_json(const Model& model, const Vector& theta, const nlohmann::json& meta) {
  require(theta.size() == model.n_params(), "model_to_json: parameter vector has the wrong size");
  nlohmann::json params = nlohmann::json::array();
  for (Index i = 0; i < theta.size(); ++i) params.push_back(theta(i));
  const nlohmann::json spec = model.hyperparams();
  // The arithmetic of the cores' products in the writing process (which trained the parameters,
  // for every writer here), where it is not the default; a default file stays as it was.
  nlohmann::json m = meta;
  if (kernels::arithmetic() != kernels::kDefaultArithmetic && m.is_object() &&
      !m.contains("arithmetic")) {
    m["arithmetic"] = kernels::to_string(kernels::arithmetic());
  }
  return {{"format", kModelFormat},
          {"version", kModelFormatVersion},
          {"model", spec},
          {"n_params", model.n_params()},
          {"meta", m},
          {"checksum", model_checksum(spec, m, theta)},
          {"params", params}};
}

Model model_from_spec(const nlohmann::json& spec, const std::string& where) {
  double sizes = 1.0;
  product_of_sizes(spec, sizes);
  require(sizes <= kMaxSizeProduct, [&] {
    return where + ": the architecture's sizes multiply to " + short_number(sizes) +
           ", more than any model file can hold; expected sizes whose product is at most " +
           std::to_string(static_cast<long long>(kMaxSizeProduct));
  });
  try {
    return make_model(spec);
  } catch (const Error& e) {
    throw Error(where + ": " + e.what());
  }
}

SavedModel model_from_json(const nlohmann::json& doc, const std::string& where) {
  require(doc.is_object(), [&] { return where + ": expected a JSON object"; });
  require(doc.contains("format") && doc["format"] == kModelFormat, [&] {
    return where + ": not a csympnet model file (expected \"format\": \"" + kModelFormat + "\")";
  });
  require(doc.contains("version") && doc["version"].is_number_integer(), [&] {
    return where + ": missing integer \"version\"; expected \"version\": " +
           std::to_string(kModelFormatVersion);
  });
  const auto version = doc["version"].get<std::int64_t>();
  // Version 1 predates the checksum: reading it would let anyone edit a file's parameters and
  // relabel it "version": 1 to pass. Every version read carries a checksum.
  require(version != 1, [&] {
    return where +
           ": model format version 1 (no checksum) is no longer read: it cannot be told "
           "from a file whose checksum was removed; expected version " +
           std::to_string(kModelFormatVersion) +
           " (fit or train the model again with this csympnet)";
  });
  require(version == kModelFormatVersion, [&] {
    return where + ": model format version " + std::to_string(version) +
           " is not supported (expected " + std::to_string(kModelFormatVersion) +
           "; a newer csympnet wrote it?)";
  });
  require(doc.contains("model"), [&] {
    return where +
           ": missing \"model\"; expected the architecture, e.g. {\"type\": \"csympnet\", ...}";
  });
  SavedModel out;
  out.model = model_from_spec(doc["model"], where);
  require(doc.contains("params") && doc["params"].is_array(),
          [&] { return where + ": missing array \"params\"; expected the flat parameter vector"; });
  const auto& params = doc["params"];
  require(static_cast<Index>(params.size()) == out.model.n_params(), [&] {
    return where + ": \"params\" has " + std::to_string(params.size()) +
           " entries but the architecture needs " + std::to_string(out.model.n_params()) +
           "; expected one entry per parameter";
  });
  // n_params is redundant (the architecture fixes it) but written since version 1; a file
  // that disagrees with itself is damaged.
  if (doc.contains("n_params"))
    require(doc["n_params"].is_number_integer() &&
                doc["n_params"].get<std::int64_t>() == out.model.n_params(),
            [&] {
              return where + ": \"n_params\" = " + doc["n_params"].dump().substr(0, 40) +
                     " but the architecture has " + std::to_string(out.model.n_params()) +
                     " parameters; expected them to agree";
            });
  out.theta.resize(out.model.n_params());
  for (Index i = 0; i < out.theta.size(); ++i) {
    const auto& v = params[static_cast<std::size_t>(i)];
    require(v.is_number(), [&] {
      return where + ": params[" + std::to_string(i) + "] is not a number (" +
             v.dump().substr(0, 40) + "); expected a finite number";
    });
    out.theta(i) = v.get<double>();
    require(std::isfinite(out.theta(i)), [&] {
      return where + ": params[" + std::to_string(i) + "] = " + v.dump() +
             " is not finite; expected finite numbers";
    });
  }
  out.meta = doc.value("meta", nlohmann::json::object());
  {
    require(doc.contains("checksum") && doc["checksum"].is_string(), [&] {
      return where +
             ": missing string \"checksum\"; expected the checksum every model file carries";
    });
    const std::string expected = doc["checksum"].get<std::string>();
    const std::string actual = model_checksum(doc["model"], out.meta, out.theta);
    require(expected == actual, [&] {
      return where + ": checksum mismatch (the file says " + expected + ", its contents give " +
             actual +
             "): it was modified or corrupted after it was written; "
             "expected the file exactly as csympnet wrote it";
    });
  }
  check_map_params(out.model, out.theta, where);
  return out;
}

std::string model_file_text(const Model& model, const Vector& theta, const nlohmann::json& meta) {
  return model_to_json(model, theta, meta).dump(1) + "\n";
}

void save_model(const std::string& path, const Model& model, const Vector& theta,
                const nlohmann::json& meta) {
  write_text_atomic(path, model_file_text(model, theta, meta));
}

JsonLimits model_file_limits() {
  JsonLimits l;
  l.max_depth = 64;
  l.bulk_key = "params";
  l.max_bulk_values = static_cast<std::size_t>(kMaxModelParams);
  l.max_other_values = kMaxModelFileOtherValues;
  return l;
}

SavedModel model_from_text(const std::string& text, const std::string& where) {
  return model_from_json(
      parse_json_text(text, where, "a csympnet model file (was it truncated or overwritten?)",
                      model_file_limits()),
      where);
}

SavedModel load_model(const std::string& path) {
  return model_from_text(read_text_file(path), path);
}

}  // namespace csympnet
