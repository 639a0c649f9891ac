#include "csympnet/io/model_file.hpp"

#include "csympnet/core/error.hpp"
#include "csympnet/io/files.hpp"

namespace csympnet {

nlohmann::json model_to_json(const Model& model, const Vector& theta, const nlohmann::json& meta) {
  require(theta.size() == model.n_params(), "model_to_json: parameter vector has the wrong size");
  nlohmann::json params = nlohmann::json::array();
  for (Index i = 0; i < theta.size(); ++i) params.push_back(theta(i));
  return {{"format", kModelFormat},
          {"version", kModelFormatVersion},
          {"model", model.hyperparams()},
          {"n_params", model.n_params()},
          {"meta", meta},
          {"params", params}};
}

SavedModel model_from_json(const nlohmann::json& doc, const std::string& where) {
  require(doc.is_object(), where + ": expected a JSON object");
  require(doc.contains("format") && doc["format"] == kModelFormat,
          where + ": not a csympnet model file (expected \"format\": \"" + kModelFormat + "\")");
  require(doc.contains("version") && doc["version"].is_number_integer(),
          where + ": missing integer \"version\"");
  const int version = doc["version"].get<int>();
  require(version == kModelFormatVersion,
          where + ": model format version " + std::to_string(version) +
              " is not supported (expected " + std::to_string(kModelFormatVersion) + ")");
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
