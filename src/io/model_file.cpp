#include "csympnet/io/model_file.hpp"

#include <cstring>

#include "csympnet/core/error.hpp"
#include "csympnet/core/hash.hpp"
#include "csympnet/io/files.hpp"

namespace csympnet {

namespace {

// FNV-1a over the architecture, the context and the exact bits of every parameter (bytes in
// little-endian order, so the checksum is the same on every platform).
std::string checksum_of(const nlohmann::json& model, const nlohmann::json& meta,
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

}  // namespace

nlohmann::json model_to_json(const Model& model, const Vector& theta, const nlohmann::json& meta) {
  require(theta.size() == model.n_params(), "model_to_json: parameter vector has the wrong size");
  nlohmann::json params = nlohmann::json::array();
  for (Index i = 0; i < theta.size(); ++i) params.push_back(theta(i));
  const nlohmann::json spec = model.hyperparams();
  return {{"format", kModelFormat}, {"version", kModelFormatVersion},
          {"model", spec},          {"n_params", model.n_params()},
          {"meta", meta},           {"checksum", checksum_of(spec, meta, theta)},
          {"params", params}};
}

SavedModel model_from_json(const nlohmann::json& doc, const std::string& where) {
  require(doc.is_object(), where + ": expected a JSON object");
  require(doc.contains("format") && doc["format"] == kModelFormat,
          where + ": not a csympnet model file (expected \"format\": \"" + kModelFormat + "\")");
  require(doc.contains("version") && doc["version"].is_number_integer(),
          where + ": missing integer \"version\"");
  const int version = doc["version"].get<int>();
  require(version == 1 || version == kModelFormatVersion,
          where + ": model format version " + std::to_string(version) +
              " is not supported (expected 1 or " + std::to_string(kModelFormatVersion) +
              "; a newer csympnet wrote it?)");
  require(doc.contains("model"), where + ": missing \"model\" (the architecture)");
  SavedModel out;
  try {
    out.model = make_model(doc["model"]);
  } catch (const Error& e) {
    throw Error(where + ": " + e.what());
  }
  require(doc.contains("params") && doc["params"].is_array(), where + ": missing array \"params\"");
  const auto& params = doc["params"];
  require(static_cast<Index>(params.size()) == out.model.n_params(),
          where + ": \"params\" has " + std::to_string(params.size()) +
              " entries but the architecture needs " + std::to_string(out.model.n_params()));
  out.theta.resize(out.model.n_params());
  for (Index i = 0; i < out.theta.size(); ++i) {
    const auto& v = params[static_cast<std::size_t>(i)];
    require(v.is_number(), where + ": params[" + std::to_string(i) + "] is not a number");
    out.theta(i) = v.get<double>();
  }
  require(out.theta.allFinite(), where + ": parameters contain NaN or Inf");
  out.meta = doc.value("meta", nlohmann::json::object());
  if (version >= 2) {  // version 1 files predate the checksum
    require(doc.contains("checksum") && doc["checksum"].is_string(),
            where + ": missing string \"checksum\" (required from format version 2)");
    const std::string expected = doc["checksum"].get<std::string>();
    const std::string actual = checksum_of(doc["model"], out.meta, out.theta);
    require(expected == actual, where + ": checksum mismatch (the file says " + expected +
                                    ", its contents give " + actual +
                                    "): it was modified or corrupted after it was written");
  }
  return out;
}

void save_model(const std::string& path, const Model& model, const Vector& theta,
                const nlohmann::json& meta) {
  write_text_atomic(path, model_to_json(model, theta, meta).dump(1) + "\n");
}

SavedModel load_model(const std::string& path) {
  const std::string text = read_text_file(path);
  nlohmann::json doc;
  try {
    doc = nlohmann::json::parse(text);
  } catch (const nlohmann::json::parse_error& e) {
    throw Error(path + ": not valid JSON (" + e.what() + ")");
  }
  return model_from_json(doc, path);
}

}  // namespace csympnet
