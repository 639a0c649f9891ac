// Every single-bit corruption of a saved model file is either refused with a message naming
// the file, or (e.g. 'e' -> 'E' in an exponent) loads to exactly the same model.
#include <gtest/gtest.h>

#include <string>

#include <nlohmann/json.hpp>

#include "csympnet/core/error.hpp"
#include "csympnet/core/rng.hpp"
#include "csympnet/models/model_file.hpp"

namespace csympnet {
namespace {

using nlohmann::json;

TEST(ModelFileBitFlips, EveryFlipIsRefusedOrHarmless) {
  const Model model = make_model(json{
      {"type", "csympnet"}, {"d", 1}, {"core", {{"type", "la"}, {"layers", 2}, {"sublayers", 1}}}});
  Vector theta(model.n_params());
  Rng rng(3, "init");
  model.init_params(rng, theta);
  const json meta = {{"seed", 3}, {"note", "x"}};
  const std::string text = model_to_json(model, theta, meta).dump(1) + "\n";
  const SavedModel good = model_from_text(text, "m.json");
  ASSERT_EQ(good.theta, theta);

  std::size_t refused = 0, harmless = 0;
  for (std::size_t i = 0; i < text.size(); ++i) {
    for (int bit = 0; bit < 8; ++bit) {
      std::string bad = text;
      bad[i] = static_cast<char>(static_cast<unsigned char>(bad[i]) ^ (1U << bit));
      try {
        const SavedModel m = model_from_text(bad, "m.json");
        EXPECT_EQ(m.theta, theta) << "byte " << i << " bit " << bit;
        EXPECT_EQ(m.model.hyperparams(), model.hyperparams()) << "byte " << i << " bit " << bit;
        EXPECT_EQ(m.meta, meta) << "byte " << i << " bit " << bit;
        ++harmless;
      } catch (const Error& e) {
        EXPECT_EQ(std::string(e.what()).rfind("m.json: ", 0), 0u) << e.what();
        ++refused;
      }
    }
  }
  EXPECT_EQ(refused + harmless, 8 * text.size());
  EXPECT_GT(refused, 7 * text.size());  // almost every flip is caught
}

}  // namespace
}  // namespace csympnet
