// Saved models: one JSON document with the architecture, the flat parameter vector and the
// context it was trained in. Parameters are written with 17 significant digits, so a model
// read back predicts bit-identically.
#pragma once

#include <memory>
#include <string>

#include <nlohmann/json.hpp>

#include "csympnet/io/json_text.hpp"
#include "csympnet/models/model.hpp"

namespace csympnet {

inline constexpr const char* kModelFormat = "csympnet-model";
// Version 2 adds "checksum" (FNV-1a over architecture, meta and parameter bits); version 1
// files, which have none, are still read.
inline constexpr int kModelFormatVersion = 2;

struct SavedModel {
  Model model;
  Vector theta;
  nlohmann::json meta;  // free-form context: system, training recipe, seed, ...
};

// The checksum a model file carries ("fnv1a64:..."): FNV-1a over the architecture, the meta
// and the exact bits of every parameter. It detects corruption and accidental edits; it is
// not a signature (anyone can recompute it).
std::string model_checksum(const nlohmann::json& model, const nlohmann::json& meta,
                           const Vector& theta);

nlohmann::json model_to_json(const Model& model, const Vector& theta,
                             const nlohmann::json& meta = nlohmann::json::object());
SavedModel model_from_json(const nlohmann::json& doc, const std::string& where = "model");
// The model of an architecture (a model file's "model" entry), with a file's checks: its sizes
// bounded before anything is built. Errors are prefixed by `where`.
Model model_from_spec(const nlohmann::json& spec, const std::string& where = "model");
// Parses the text of a model file; `where` (the path) prefixes every message.
SavedModel model_from_text(const std::string& text, const std::string& where);

// The text of a model file, as save_model writes it (for a set committed with others).
std::string model_file_text(const Model& model, const Vector& theta,
                            const nlohmann::json& meta = nlohmann::json::object());
// Atomic write (temporary file, then rename).
void save_model(const std::string& path, const Model& model, const Vector& theta,
                const nlohmann::json& meta = nlohmann::json::object());
// Throws Error naming the file and what is wrong (not JSON — e.g. truncated —, wrong
// format/version, parameter count mismatch, non-finite values, checksum mismatch).
SavedModel load_model(const std::string& path);

// What a model file may hold, checked while it is parsed (docs/hardening.md, "Parser
// memory"): at most 64 levels of nesting, at most kMaxModelParams entries in "params" (the
// largest model there can be), and at most kMaxModelFileOtherValues values elsewhere (the
// architecture and "meta"). A file beyond them is refused before it can exhaust memory.
inline constexpr std::size_t kMaxModelFileOtherValues = 1'000'000;
JsonLimits model_file_limits();

}  // namespace csympnet
