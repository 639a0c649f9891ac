// Model files: exact round trip, versioning and the checksum that refuses modified files.
#include <gtest/gtest.h>

#include <filesystem>
#include <string>

#include <nlohmann/json.hpp>

#include "csympnet/core/error.hpp"
#include "csympnet/core/rng.hpp"
#include "csympnet/io/files.hpp"
#include "csympnet/models/model_file.hpp"

namespace csympnet {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

struct Fixture {
  Model model;
  Vector theta;
};

Fixture make(const std::string& type) {
  json spec = type == "csympnet" ? json{{"type", "csympnet"},
                                        {"d", 2},
                                        {"core", {{"type", "la"}, {"layers", 2}, {"sublayers", 2}}}}
                                 : json{{"type", type}, {"d", 2}, {"width", 5}};
  Fixture f{make_model(spec), Vector()};
  f.theta.resize(f.model.n_params());
  Rng rng(7, "init");
  f.model.init_params(rng, f.theta);
  return f;
}

std::string expect_refused(const json& doc) {
  try {
    model_from_json(doc, "m.json");
  } catch (const Error& e) {
    EXPECT_EQ(std::string(e.what()).rfind("m.json: ", 0), 0u) << e.what();
    return e.what();
  }
  ADD_FAILURE() << "accepted a bad model document";
  return "";
}

TEST(ModelFile, RoundTripIsBitExactAndCarriesAChecksum) {
  for (const char* type : {"csympnet", "map", "dhnn2"}) {
    const Fixture f = make(type);
    const json meta = {{"seed", 42}, {"note", "x"}, {"h", 0.1}};
    const json doc = json::parse(model_to_json(f.model, f.theta, meta).dump(1));
    EXPECT_EQ(doc["version"], kModelFormatVersion);
    EXPECT_EQ(doc["checksum"].get<std::string>().rfind("fnv1a64:", 0), 0u);
    const SavedModel back = model_from_json(doc, "m.json");
    EXPECT_EQ(back.model.type(), type);
    ASSERT_EQ(back.theta.size(), f.theta.size());
    for (Index i = 0; i < f.theta.size(); ++i) EXPECT_EQ(back.theta(i), f.theta(i)) << i;
    EXPECT_EQ(back.meta, meta);
  }
}

TEST(ModelFile, AnyChangeToParametersArchitectureOrMetaIsRefused) {
  const Fixture f = make("csympnet");
  const json good = json::parse(model_to_json(f.model, f.theta, {{"seed", 1}}).dump());
  json doc = good;
  // The smallest possible change to one parameter: one unit in the last place.
  const double v = doc["params"][3].get<double>();
  doc["params"][3] = std::nextafter(v, 1e300);
  EXPECT_NE(expect_refused(doc).find("checksum mismatch"), std::string::npos);
  doc = good;
  doc["meta"]["seed"] = 2;
  EXPECT_NE(expect_refused(doc).find("checksum mismatch"), std::string::npos);
  doc = good;
  doc["model"]["beta_init"] = 0.2;
  EXPECT_NE(expect_refused(doc).find("checksum mismatch"), std::string::npos);
  doc = good;
  doc.erase("checksum");
  EXPECT_NE(expect_refused(doc).find("\"checksum\""), std::string::npos);
}

// A downgrade to version 1 (which had no checksum), with or without the checksum and with
// edited parameters, is refused: otherwise the checksum could be bypassed by relabelling.
TEST(ModelFile, DowngradesAndUnknownVersionsAreRefused) {
  const Fixture f = make("ode");
  const json good = model_to_json(f.model, f.theta);
  json doc = good;
  doc["version"] = 1;
  EXPECT_NE(expect_refused(doc).find("version 1 (no checksum) is no longer read"),
            std::string::npos);
  doc["params"][0] = doc["params"][0].get<double>() + 1.0;
  EXPECT_NE(expect_refused(doc).find("version 1"), std::string::npos);
  doc.erase("checksum");
  EXPECT_NE(expect_refused(doc).find("version 1"), std::string::npos);
  for (const int v : {0, 3, -2}) {
    doc = good;
    doc["version"] = v;
    EXPECT_NE(expect_refused(doc).find("version " + std::to_string(v) + " is not supported"),
              std::string::npos);
  }
  EXPECT_EQ(model_from_json(good, "m.json").theta, f.theta);
}

// A key given twice would let an edit hide behind a checked first copy in readers that keep
// the first, and change the model in those (like nlohmann) that keep the last: refused.
TEST(ModelFile, RepeatedKeysAreRefused) {
  const Fixture f = make("csympnet");
  const std::string text = model_file_text(f.model, f.theta);
  EXPECT_EQ(model_from_text(text, "m.json").theta, f.theta);
  const std::size_t brace = text.find('{');
  ASSERT_NE(brace, std::string::npos);
  const std::string twice =
      text.substr(0, brace + 1) + R"("version": 2, )" + text.substr(brace + 1);
  try {
    model_from_text(twice, "m.json");
    ADD_FAILURE() << "accepted a repeated key";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("m.json: key 'version' appears twice"), std::string::npos)
        << e.what();
  }
}

TEST(ModelFile, TruncatedOrGarbageFilesAreRefusedWithTheirPath) {
  const Fixture f = make("csympnet");
  const fs::path dir = fs::temp_directory_path() / ("csympnet_model_" + std::to_string(::getpid()));
  fs::create_directories(dir);
  const std::string path = (dir / "model.json").string();
  save_model(path, f.model, f.theta);
  const std::string text = read_text_file(path);
  EXPECT_EQ(load_model(path).theta, f.theta);
  for (const std::size_t keep : {text.size() / 2, text.size() - 3, std::size_t{0}}) {
    write_text_atomic(path, text.substr(0, keep));
    try {
      load_model(path);
      ADD_FAILURE() << "accepted a file truncated to " << keep << " bytes";
    } catch (const Error& e) {
      EXPECT_NE(std::string(e.what()).find(path), std::string::npos) << e.what();
    }
  }
  write_text_atomic(path, std::string("\x00\xff\x13garbage", 10));
  EXPECT_THROW(load_model(path), Error);
  fs::remove_all(dir);
}

}  // namespace
}  // namespace csympnet
