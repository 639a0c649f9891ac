// Fits CSympNet-ID to the paper's S1 data (a damped oscillator, γ = 0.05) with the public
// C++ API of an installed csympnet, prints γ̂, and checks the learned map's conformal
// symplecticity DΦᵀ J DΦ = exp(−γ̂h) J at one state. Exit code 1 when that check fails.
//   fit_s1 [epochs]   (default 2000)
#include <cmath>
#include <cstdio>
#include <exception>
#include <string>

#include <csympnet/core/rng.hpp>
#include <csympnet/core/types.hpp>
#include <csympnet/models/model.hpp>
#include <csympnet/paper/preset.hpp>
#include <csympnet/paper/run.hpp>
#include <csympnet/train/trainer.hpp>

int main(int argc, char** argv) try {
  const long epochs = argc > 1 ? std::stol(argv[1]) : 2000;

  // The preset's training and validation pairs, drawn from seed 42.
  csympnet::RunConfig config = csympnet::default_run_config("s1", "csympnet");
  const csympnet::RunData data = csympnet::generate_run_data(config);

  // The preset's CSympNet-ID architecture, initialised from the seed's "init" stream.
  nlohmann::json spec = csympnet::model_spec_for(config.preset, "csympnet");
  spec["beta_init"] = config.beta_init;
  const csympnet::Model model = csympnet::make_model(spec);
  csympnet::Vector theta(model.n_params());
  csympnet::Rng init_rng(config.seed, "init");
  model.init_params(init_rng, theta);

  csympnet::TrainOptions options = config.train;
  options.epochs = epochs;
  const csympnet::TrainSummary summary =
      csympnet::train_model(model, theta, data.train, data.val, options);

  const double gamma_hat = model.damping_rate(theta).value();
  std::printf("csympnet: %ld parameters, %ld epochs, best validation loss %.3e\n",
              static_cast<long>(model.n_params()), summary.epochs_run, summary.best_val_loss);
  std::printf("gamma_hat = %.6f (true gamma = %.2f)\n", gamma_hat, config.preset.system.gamma);

  // The structure holds for any parameters: DΦᵀ J DΦ − exp(−γ̂h) J is round-off.
  const double h = 0.1;
  csympnet::Vector z(2);
  z << 0.5, -0.2;
  const csympnet::Matrix jac = model.map->jacobian(theta, z, h);
  const csympnet::Matrix j = csympnet::canonical_j(1);
  const double residual =
      (jac.transpose() * j * jac - std::exp(-gamma_hat * h) * j).cwiseAbs().maxCoeff();
  std::printf("structure residual max|DPhi^T J DPhi - exp(-gamma_hat h) J| = %.2e\n", residual);
  if (!std::isfinite(gamma_hat) || gamma_hat <= 0.0 || !(residual < 1e-12)) {
    std::fprintf(stderr, "fit_s1: unexpected result\n");
    return 1;
  }
  return 0;
} catch (const std::exception& e) {
  std::fprintf(stderr, "fit_s1: %s\n", e.what());
  return 2;
}
