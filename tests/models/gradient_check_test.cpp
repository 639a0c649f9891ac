// The harness must accept correct derivatives and reject planted wrong ones.
#include "support/gradient_check.hpp"

#include <gtest/gtest.h>

#include "csympnet/models/one_step_map.hpp"
#include "support/model_fixtures.hpp"

namespace csympnet::testing {
namespace {

double rosenbrock(const Vector& x) {
  return 100.0 * std::pow(x(1) - x(0) * x(0), 2) + std::pow(1.0 - x(0), 2);
}

Vector rosenbrock_gradient(const Vector& x) {
  Vector g(2);
  g(0) = -400.0 * x(0) * (x(1) - x(0) * x(0)) - 2.0 * (1.0 - x(0));
  g(1) = 200.0 * (x(1) - x(0) * x(0));
  return g;
}

TEST(GradientCheck, AcceptsCorrectAndRejectsWrongScalarGradient) {
  const Vector x = Vector::LinSpaced(2, -1.2, 1.0);
  EXPECT_TRUE(check_gradient(rosenbrock, rosenbrock_gradient, x).ok());
  const auto wrong = [](const Vector& v) {
    Vector g = rosenbrock_gradient(v);
    g(1) *= 1.0 + 1e-4;
    return g;
  };
  EXPECT_FALSE(check_gradient(rosenbrock, wrong, x).ok());
}

TEST(GradientCheck, AcceptsCorrectAndRejectsWrongJacobian) {
  const auto f = [](const Vector& v) -> Vector { return v.array().sin() * v(0); };
  const auto jac = [](const Vector& v) -> Matrix {
    Matrix m = (v.array().cos() * v(0)).matrix().asDiagonal();
    m.col(0) += v.array().sin().matrix();
    return m;
  };
  const Vector x = Vector::LinSpaced(3, 0.3, 1.4);
  EXPECT_TRUE(check_jacobian(f, jac, x).ok());
  const auto wrong = [&](const Vector& v) -> Matrix {
    Matrix m = jac(v);
    m(2, 1) += 1e-4;
    return m;
  };
  EXPECT_FALSE(check_jacobian(f, wrong, x).ok());
}

// Delegates to a correct model but corrupts one derivative path.
class PlantedModel final : public OneStepMap {
 public:
  enum class Fault { kNone, kThetaEntry, kZinEntry, kJacobianEntry, kOverwrite };
  PlantedModel(std::unique_ptr<OneStepMap> inner, Fault fault)
      : inner_(std::move(inner)), fault_(fault) {}

  std::string type() const override { return inner_->type(); }
  Index dim() const override { return inner_->dim(); }
  Index n_params() const override { return inner_->n_params(); }
  void init_params(Rng& rng, ParamsRef theta) const override { inner_->init_params(rng, theta); }
  Matrix forward(ConstParams theta, const Matrix& z, const Vector& h,
                 ForwardCache* cache) const override {
    return inner_->forward(theta, z, h, cache);
  }
  void backward(ConstParams theta, const ForwardCache& cache, const Matrix& dz_out, ParamsRef grad,
                Matrix* dz_in) const override {
    if (fault_ == Fault::kOverwrite) grad.setZero();
    inner_->backward(theta, cache, dz_out, grad, dz_in);
    if (fault_ == Fault::kThetaEntry) grad(grad.size() / 2) += 1e-4 * (1.0 + grad.norm());
    if (fault_ == Fault::kZinEntry && dz_in != nullptr) (*dz_in)(0, 0) += 1e-4;
  }
  Matrix jacobian(ConstParams theta, const Vector& z, double h) const override {
    Matrix jac = inner_->jacobian(theta, z, h);
    if (fault_ == Fault::kJacobianEntry) jac(0, jac.cols() - 1) += 1e-4;
    return jac;
  }
  nlohmann::json hyperparams() const override { return inner_->hyperparams(); }

 private:
  std::unique_ptr<OneStepMap> inner_;
  Fault fault_;
};

TEST(GradientCheck, RejectsPlantedModelFaults) {
  const nlohmann::json spec = {
      {"type", "csympnet"}, {"d", 2}, {"core", {{"type", "la"}, {"layers", 2}, {"sublayers", 2}}}};
  Rng rng(11, "planted");
  using Fault = PlantedModel::Fault;
  for (const Fault fault : {Fault::kNone, Fault::kThetaEntry, Fault::kZinEntry,
                            Fault::kJacobianEntry, Fault::kOverwrite}) {
    const PlantedModel model(make_one_step_map(spec), fault);
    const Vector theta = random_theta(model, rng, 0.3);
    const Matrix z = rng.normal_matrix(model.dim(), 4, 1.0);
    const Vector h = random_steps(4, rng);
    const ModelCheck check = check_one_step_map(model, theta, z, h, rng);
    SCOPED_TRACE(check.report());
    EXPECT_EQ(check.d_theta.ok(), fault != Fault::kThetaEntry && fault != Fault::kOverwrite);
    EXPECT_EQ(check.d_zin.ok(), fault != Fault::kZinEntry);
    EXPECT_EQ(check.jacobian.ok(), fault != Fault::kJacobianEntry);
  }
}

}  // namespace
}  // namespace csympnet::testing
