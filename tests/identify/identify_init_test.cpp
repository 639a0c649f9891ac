// identify() from a model file (`csympnet fit --init`, IdentifyConfig::init): what is kept (the
// core, θ, the units), what is refused (by the option's key, naming the file) and what the
// report records.
#include <unistd.h>

#include <filesystem>
#include <string>

#include <gtest/gtest.h>

#include "csympnet/core/options.hpp"
#include "csympnet/core/rng.hpp"
#include "csympnet/identify/identify.hpp"
#include "csympnet/integrators/reference.hpp"
#include "csympnet/models/model_file.hpp"
#include "csympnet/systems/system.hpp"

namespace csympnet {
namespace {

namespace fs = std::filesystem;

// A damped oscillator: `trajs` trajectories of 40 points from random starts (`seed`), step 0.1,
// noise 1e-3.
std::vector<Trajectory> oscillator(int trajs, std::uint64_t seed) {
  SystemSpec spec;
  spec.gamma = 0.1;
  const System sys(spec);
  const Matrix step = expm_propagator(sys, 0.1);
  Rng rng(seed, "identify-init-test");
  std::vector<Trajectory> out;
  for (int m = 0; m < trajs; ++m) {
    Trajectory t;
    t.t = Vector::LinSpaced(40, 0.0, 3.9);
    t.z.resize(2, 40);
    t.z.col(0) = rng.uniform_vector(2, -1.0, 1.0);
    for (Index k = 1; k < 40; ++k) t.z.col(k) = step * t.z.col(k - 1);
    for (Index k = 0; k < 40; ++k) t.z.col(k) += rng.normal_matrix(2, 1, 1e-3);
    out.push_back(t);
  }
  return out;
}

class IdentifyInitFile : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / ("csympnet_init_" + std::to_string(::getpid()));
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }
  std::string save(const std::string& name, const nlohmann::json& spec) {
    Model m = make_model(spec);
    Vector theta(m.n_params());
    Rng rng(1, "init");
    m.init_params(rng, theta);
    const std::string path = (dir_ / name).string();
    save_model(path, m, theta);
    return path;
  }
  // The key of the OptionError that building `settings` throws, and its message.
  static std::pair<std::string, std::string> refusal(const nlohmann::json& settings) {
    try {
      make_identify_config(settings);
    } catch (const OptionError& e) {
      return {e.key(), e.what()};
    }
    return {};
  }
  fs::path dir_;
};

const nlohmann::json kCore = {{"type", "g"}, {"layers", 2}, {"width", 4}};

TEST_F(IdentifyInitFile, RefusesWhatItCannotHonourByKeyAndFile) {
  const std::string sympnet = save("s.json", {{"type", "sympnet"}, {"d", 1}, {"core", kCore}});
  auto [key, what] = refusal({{"init", sympnet}});
  EXPECT_EQ(key, "init");
  EXPECT_NE(what.find(sympnet + ": a model of type 'sympnet'"), std::string::npos) << what;
  std::tie(key, what) = refusal({{"init", (dir_ / "missing.json").string()}});
  EXPECT_EQ(key, "init");
  EXPECT_NE(what.find("missing.json"), std::string::npos) << what;

  const std::string plain = save("c.json", {{"type", "csympnet"}, {"d", 1}, {"core", kCore}});
  EXPECT_EQ(refusal({{"init", plain}, {"core", kCore}}).first, "core");
  EXPECT_EQ(refusal({{"init", plain}, {"dof_scales", "learned"}}).first, "dof_scales");
  EXPECT_EQ(refusal({{"init", plain}, {"normalize", false}}).first, "");  // no units to keep
  const std::string normalised =
      save("n.json",
           {{"type", "csympnet"},
            {"d", 1},
            {"core", kCore},
            {"normalization",
             {{"q_shift", {0.5}}, {"q_scale", {2.0}}, {"p_scale", {1.0}}, {"time_scale", 0.1}}}});
  EXPECT_EQ(refusal({{"init", normalised}, {"normalize", false}}).first, "normalize");

  const std::string d2 = save("d2.json", {{"type", "csympnet"}, {"d", 2}, {"core", kCore}});
  const IdentifyConfig c = make_identify_config({{"init", d2}});
  try {
    identify(oscillator(4, 1), false, c);
    FAIL() << "a d = 2 model was fitted to d = 1 data";
  } catch (const OptionError& e) {
    EXPECT_EQ(e.key(), "init");
    EXPECT_NE(std::string(e.what()).find("d = 2 degrees of freedom, but the data have d = 1"),
              std::string::npos)
        << e.what();
  }
}

TEST_F(IdentifyInitFile, KeepsTheFilesCoreThetaAndUnits) {
  // A first fit, saved as `fit` saves it: with its normalisation.
  IdentifyConfig first_config;
  first_config.core = {{"type", "la"}, {"layers", 3}, {"sublayers", 4}};
  first_config.epochs = 1000;
  first_config.lm_iterations = 20;
  const IdentifyResult first = identify(oscillator(6, 1), false, first_config);
  const std::string path = (dir_ / "first.json").string();
  save_model(path, first.model, first.theta);
  const std::string checksum = model_to_json(first.model, first.theta)["checksum"];

  // Other data: a fresh fit would normalise them otherwise; the file's units stay.
  const IdentifyConfig c = make_identify_config({{"init", path}, {"lm_iterations", 1}});
  const IdentifyResult r = identify(oscillator(6, 2), false, c);
  EXPECT_EQ(r.model.hyperparams(), first.model.hyperparams());
  EXPECT_EQ(nlohmann::json(r.normalization), nlohmann::json(first.normalization));
  EXPECT_EQ(r.training.epochs_run, 0);
  EXPECT_EQ(r.choices["epochs"], 0);
  const nlohmann::json report = identify_report(r);
  EXPECT_EQ(report["init"]["file"], path);
  EXPECT_EQ(report["init"]["checksum"], checksum);
  EXPECT_EQ(report["config"]["init"], report["init"]);
  // No AdamW: the loss before LM is the file's θ on these data, at the level the first fit
  // reached, far below that of a fresh core of the same kind (near the identity map).
  IdentifyConfig fresh_config = first_config;
  fresh_config.epochs = 1;
  fresh_config.lm_iterations = 1;
  const IdentifyResult fresh = identify(oscillator(6, 2), false, fresh_config);
  EXPECT_LT(r.training.best_val_loss, 1e-2 * fresh.training.best_val_loss);
  EXPECT_LT(r.training.best_val_loss, 2.0 * first.training.best_val_loss);
  EXPECT_EQ(r.lm.iterations, 1);
}

// A model file whose map, at its parameters, overflows on the data (library coefficients of
// 1e300) is named as the cause, by --init's key and file, for states and positions alike; it
// once surfaced as "windows: non-finite value", blamed on the data.
TEST_F(IdentifyInitFile, AStartThatIsNotFiniteOnTheDataNamesTheFile) {
  const Model m = make_model(
      {{"type", "csympnet"},
       {"d", 1},
       {"core", {{"type", "library"}, {"terms", {"q1^2", "q1"}}, {"order", 6}, {"substeps", 1}}}});
  Vector theta(m.n_params());
  Rng rng(1, "unused");  // the map draws nothing
  m.init_params(rng, theta);
  const Index damping = *m.damping_param_index();
  for (Index i = 0; i < theta.size(); ++i)
    if (i != damping) theta(i) = 1e300;
  const std::string path = (dir_ / "huge.json").string();
  save_model(path, m, theta);
  const IdentifyConfig c = make_identify_config({{"init", path}, {"lm_iterations", 1}});
  const std::vector<Trajectory> states = oscillator(6, 1);
  std::vector<Trajectory> positions;
  for (const Trajectory& t : states) positions.push_back({t.t, t.z.topRows(1), {}});
  for (bool positions_only : {false, true}) {
    try {
      positions_only ? identify_positions(positions, c) : identify(states, false, c);
      FAIL() << "fitted from a start that overflows, positions only: " << positions_only;
    } catch (const OptionError& e) {
      EXPECT_EQ(e.key(), "init");
      const std::string what = e.what();
      EXPECT_NE(what.find(path + ": the model's map at the file's parameters predicts "
                                 "non-finite states"),
                std::string::npos)
          << what;
    }
  }
}

}  // namespace
}  // namespace csympnet
