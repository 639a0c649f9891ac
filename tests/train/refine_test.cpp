#include "csympnet/train/refine.hpp"

#include <gtest/gtest.h>

#include "csympnet/core/error.hpp"
#include "csympnet/train/loss.hpp"
#include "csympnet/train/objective.hpp"
#include "csympnet/train/residual_jacobian.hpp"
#include "csympnet/train/trainer.hpp"
#include "support/gradient_check.hpp"
#include "support/model_fixtures.hpp"
#include "support/train_fixtures.hpp"

namespace csympnet {
namespace {

using testing::check_jacobian;
using testing::random_steps;
using testing::random_theta;

PairSet random_refine_pairs(Index dim, Index n, Rng& rng) {
  PairSet p;
  p.z0 = rng.normal_matrix(dim, n, 1.0);
  p.z1 = rng.normal_matrix(dim, n, 1.0);
  p.h = random_steps(n, rng);
  return p;
}

class ResidualJacobianTest : public ::testing::TestWithParam<const char*> {};

TEST_P(ResidualJacobianTest, MatchesFiniteDifferences) {
  const auto map = make_one_step_map(nlohmann::json::parse(GetParam()));
  Rng rng(11, GetParam());
  for (int rep = 0; rep < 2; ++rep) {
    const Vector theta = random_theta(*map, rng, 0.3, 0.4);
    const PairSet pairs = random_refine_pairs(map->dim(), 4, rng);
    const auto r = [&](const Vector& th) { return one_step_residuals(*map, th, pairs); };
    const auto jac = [&](const Vector& th) -> Matrix { return residual_jacobian(*map, th, pairs); };
    const auto check = check_jacobian(r, jac, theta);
    EXPECT_TRUE(check.ok()) << check.report("residual Jacobian");
  }
}

TEST_P(ResidualJacobianTest, GivesTheLossGradient) {
  // dL/dθ = (2/N) Jᵀ r, computed by an independent path (one batched reverse pass).
  const auto map = make_one_step_map(nlohmann::json::parse(GetParam()));
  Rng rng(12, GetParam());
  const Vector theta = random_theta(*map, rng, 0.3, 0.4);
  const PairSet pairs = random_refine_pairs(map->dim(), 6, rng);
  Vector grad;
  one_step_loss(*map, theta, pairs, &grad);
  const Vector from_jac = (2.0 / 6.0) * residual_jacobian(*map, theta, pairs).transpose() *
                          one_step_residuals(*map, theta, pairs);
  EXPECT_LE((grad - from_jac).norm(), 1e-12 * (1.0 + grad.norm()));
}

INSTANTIATE_TEST_SUITE_P(
    Maps, ResidualJacobianTest,
    ::testing::Values(R"({"type":"csympnet","d":1,"core":{"type":"la","layers":3,"sublayers":4}})",
                      R"({"type":"csympnet","d":2,"core":{"type":"g","layers":3,"width":5}})",
                      R"({"type":"sympnet","d":2,"core":{"type":"la","layers":2,"sublayers":3}})",
                      R"({"type":"sympnet","d":1,"core":{"type":"g","layers":4,"width":6}})"));

TEST(ResidualJacobian, CheckCatchesAPlantedWrongEntry) {
  const auto map = make_one_step_map(nlohmann::json::parse(
      R"({"type":"csympnet","d":1,"core":{"type":"la","layers":2,"sublayers":2}})"));
  Rng rng(13, "planted");
  const Vector theta = random_theta(*map, rng, 0.3, 0.4);
  const PairSet pairs = random_refine_pairs(2, 3, rng);
  const auto r = [&](const Vector& th) { return one_step_residuals(*map, th, pairs); };
  const auto wrong = [&](const Vector& th) -> Matrix {
    Matrix j = residual_jacobian(*map, th, pairs);
    j(3, map->n_params() - 1) *= 1.0 + 1e-3;  // the β column of one residual
    return j;
  };
  EXPECT_FALSE(check_jacobian(r, wrong, theta).ok());
}

// Damped rotation data (the exact flow of s1), for the optimiser tests.
PairSet rotation_pairs(Index n, std::uint64_t seed) {
  return testing::damped_rotation_pairs(n, seed, "rotation");
}

using Trained = testing::TrainedMap;

Trained adamw_start() {
  return testing::adamw_trained_rotation_map();
}

// Both LM implementations: Ceres' (dense QR) and the normal-equations one with BLAS.
class RefineLm : public ::testing::TestWithParam<const char*> {};

TEST_P(RefineLm, GoesFarBelowMoreAdamW) {
  Trained t = adamw_start();
  // The same start, given 2,000 more AdamW epochs instead of 50 LM iterations: LM ends at
  // least ten times lower (measured: 83x; the best-validation iterate is kept).
  Trained more = adamw_start();
  TrainOptions o2;
  o2.epochs = 2000;
  o2.adamw.lr = 1e-3;
  o2.lr_schedule = LrSchedule::kCosine;
  train_parameters(make_one_step_objective(*more.map, more.train, more.val), more.theta, o2);
  const double adamw_loss = one_step_loss(*more.map, more.theta, more.train);

  RefineOptions o;
  o.method = RefineMethod::kLm;
  o.linear_solver = parse_linear_solver(GetParam());
  o.iterations = 50;
  const RefineSummary s = refine_one_step_map(*t.map, t.theta, t.train, t.val, o);
  EXPECT_GT(s.iterations, 0);
  EXPECT_LT(s.train_loss_after, 0.1 * adamw_loss) << s.brief_report();
  EXPECT_LE(s.val_loss_after, s.val_loss_before);
  EXPECT_EQ(s.val_loss_after, one_step_loss(*t.map, t.theta, t.val));
  EXPECT_LT(std::abs(*t.map->damping_rate(t.theta) - 0.05),
            std::abs(*more.map->damping_rate(more.theta) - 0.05));
}

TEST(Refine, LbfgsLowersTheLoss) {
  Trained t = adamw_start();
  RefineOptions o;
  o.method = RefineMethod::kLbfgs;
  o.iterations = 200;
  const RefineSummary s = refine_one_step_map(*t.map, t.theta, t.train, t.val, o);
  EXPECT_GT(s.iterations, 0);
  EXPECT_LT(s.train_loss_after, 0.1 * s.train_loss_before) << s.brief_report();
  EXPECT_LE(s.val_loss_after, s.val_loss_before);
}

TEST_P(RefineLm, IsDeterministicAndNoneLeavesThetaAlone) {
  Trained a = adamw_start(), b = adamw_start();
  RefineOptions o;
  o.method = RefineMethod::kLm;
  o.linear_solver = parse_linear_solver(GetParam());
  o.iterations = 10;
  refine_one_step_map(*a.map, a.theta, a.train, a.val, o);
  refine_one_step_map(*b.map, b.theta, b.train, b.val, o);
  EXPECT_EQ(a.theta, b.theta);
  const Vector before = a.theta;
  o.method = RefineMethod::kNone;
  const RefineSummary s = refine_one_step_map(*a.map, a.theta, a.train, a.val, o);
  EXPECT_EQ(a.theta, before);
  EXPECT_EQ(s.iterations, 0);
}

TEST_P(RefineLm, KeepsTheBestValidationIterate) {
  // Validation data from another damping rate: the kept iterate's validation loss is the
  // lowest seen, never above the start, although training drives the loss elsewhere.
  Trained t = adamw_start();
  PairSet other = rotation_pairs(10, 2);
  other.z1 *= 1.01;
  RefineOptions o;
  o.method = RefineMethod::kLm;
  o.linear_solver = parse_linear_solver(GetParam());
  o.iterations = 30;
  const RefineSummary s = refine_one_step_map(*t.map, t.theta, t.train, other, o);
  EXPECT_LE(s.val_loss_after, s.val_loss_before);
  Trained u = adamw_start();
  o.keep_best_validation = false;
  const RefineSummary last = refine_one_step_map(*u.map, u.theta, u.train, other, o);
  EXPECT_LE(last.train_loss_after, s.train_loss_after);
}

INSTANTIATE_TEST_SUITE_P(Solvers, RefineLm, ::testing::Values("dense_qr", "blas_normal_cholesky"));

// Every second-stage optimiser hands its iterates to the same IterationMonitor
// (callbacks.hpp): progress is reported in its own stage, a callback can end it, patience ends
// it, and the kept iterate is the best validation loss the callback saw.
struct Stage {
  RefineMethod method;
  LinearSolver solver;
  const char* name;
  RefineOptions options(long iterations) const {
    RefineOptions o;
    o.method = method;
    o.linear_solver = solver;
    o.iterations = iterations;
    return o;
  }
};
class RefineCallbacks : public ::testing::TestWithParam<Stage> {};

TEST_P(RefineCallbacks, ProgressSeesEveryAcceptedIterateAndCanStop) {
  const Stage st = GetParam();
  const RefineOptions o = st.options(40);
  Trained full = adamw_start();
  std::vector<TrainProgress> seen;
  IterationCallbacks cb;
  cb.progress = [&seen](const TrainProgress& p) {
    seen.push_back(p);
    return true;
  };
  const RefineSummary s = refine_one_step_map(*full.map, full.theta, full.train, full.val, o, cb);
  ASSERT_GE(seen.size(), 3u) << s.brief_report();
  double lowest = s.val_loss_before;
  for (std::size_t k = 0; k < seen.size(); ++k) {
    EXPECT_STREQ(seen[k].stage, st.method == RefineMethod::kLm ? "lm" : "lbfgs");
    EXPECT_EQ(seen[k].epochs, 40);
    EXPECT_TRUE(k == 0 || seen[k].epoch > seen[k - 1].epoch);
    EXPECT_GT(seen[k].gamma_hat, 0.0);
    lowest = std::min(lowest, seen[k].val_loss);
    EXPECT_EQ(seen[k].best_val_loss, lowest);
  }
  EXPECT_EQ(s.val_loss_after, lowest);
  EXPECT_FALSE(s.stopped);

  // The same run, told to stop at the second report: it ends there, keeps the best so far.
  Trained cut = adamw_start();
  long calls = 0;
  cb.progress = [&calls](const TrainProgress&) { return ++calls < 2; };
  const RefineSummary c = refine_one_step_map(*cut.map, cut.theta, cut.train, cut.val, o, cb);
  EXPECT_TRUE(c.stopped);
  EXPECT_EQ(c.termination, "stopped by the progress callback");
  EXPECT_EQ(calls, 2);
  EXPECT_EQ(c.val_loss_after, std::min({s.val_loss_before, seen[0].val_loss, seen[1].val_loss}));
  EXPECT_LE(c.iterations, seen[1].epoch + 1);
}

TEST_P(RefineCallbacks, PatienceEndsTheStageAfterTheBest) {
  const Stage st = GetParam();
  const RefineOptions o = st.options(200);
  // Validation data from another damping rate, so that validation stops improving early.
  Trained t = adamw_start();
  PairSet other = rotation_pairs(10, 2);
  other.z1 *= 1.01;
  IterationCallbacks cb;
  cb.patience = 3;
  const RefineSummary s = refine_one_step_map(*t.map, t.theta, t.train, other, o, cb);
  EXPECT_FALSE(s.stopped);  // patience is a normal end, not an interruption
  if (s.termination == "no better validation loss in 3 iterations") {
    EXPECT_EQ(s.iterations, s.best_iteration + 3) << s.brief_report();
  } else {  // a tolerance came first
    EXPECT_LE(s.iterations, s.best_iteration + 3) << s.brief_report();
  }
  EXPECT_LT(s.iterations, 200) << s.brief_report();
}

INSTANTIATE_TEST_SUITE_P(
    Optimisers, RefineCallbacks,
    ::testing::Values(Stage{RefineMethod::kLm, LinearSolver::kDenseQr, "ceres_lm"},
                      Stage{RefineMethod::kLm, LinearSolver::kBlasNormalCholesky, "csympnet_lm"},
                      Stage{RefineMethod::kLbfgs, LinearSolver::kDenseQr, "lbfgs"}),
    [](const ::testing::TestParamInfo<Stage>& i) { return std::string(i.param.name); });

TEST(Refine, BothLevenbergMarquardtsReachTheSameFloor) {
  // Two implementations of one method, different step control details (Ceres scales the
  // Jacobian's columns): from the same start both reach the loss floor, and the same γ̂.
  Trained a = adamw_start(), b = adamw_start();
  RefineOptions o;
  o.method = RefineMethod::kLm;
  o.iterations = 200;
  o.keep_best_validation = false;
  const RefineSummary sa = refine_one_step_map(*a.map, a.theta, a.train, a.val, o);
  o.linear_solver = LinearSolver::kBlasNormalCholesky;
  const RefineSummary sb = refine_one_step_map(*b.map, b.theta, b.train, b.val, o);
  EXPECT_LT(sb.train_loss_after, 2.0 * sa.train_loss_after) << sa.brief_report() << "\n"
                                                            << sb.brief_report();
  EXPECT_LT(sa.train_loss_after, 2.0 * sb.train_loss_after);
  EXPECT_NEAR(*a.map->damping_rate(a.theta), *b.map->damping_rate(b.theta), 1e-6);
}

TEST(Refine, RejectsBadOptionsByName) {
  try {
    parse_refine_method("newton");
    FAIL() << "accepted method 'newton'";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("--refine"), std::string::npos) << e.what();
  }
  RefineOptions o;
  o.iterations = 0;
  EXPECT_THROW(o.validate(), Error);
  EXPECT_THROW(parse_linear_solver("sparse"), Error);
}

// Every value has one spelling, read back to itself; any other text is refused with a
// message naming the option and every accepted spelling.
TEST(Refine, EnumsRoundTripThroughTheirSpellings) {
  const std::vector<std::string> methods = {"none", "lm", "lbfgs"};
  EXPECT_EQ(refine_method_names(), methods);
  for (RefineMethod m : {RefineMethod::kNone, RefineMethod::kLm, RefineMethod::kLbfgs})
    EXPECT_EQ(parse_refine_method(to_string(m)), m);
  const std::vector<std::string> solvers = {"dense_qr", "dense_normal_cholesky",
                                            "blas_normal_cholesky"};
  EXPECT_EQ(linear_solver_names(), solvers);
  for (LinearSolver s : {LinearSolver::kDenseQr, LinearSolver::kDenseNormalCholesky,
                         LinearSolver::kBlasNormalCholesky})
    EXPECT_EQ(parse_linear_solver(to_string(s)), s);
  // A JSON options block reads back to the same options.
  RefineOptions o;
  o.method = RefineMethod::kLbfgs;
  o.linear_solver = LinearSolver::kDenseNormalCholesky;
  o.iterations = 7;
  const RefineOptions back = nlohmann::json(o).get<RefineOptions>();
  EXPECT_EQ(back.method, o.method);
  EXPECT_EQ(back.linear_solver, o.linear_solver);
  EXPECT_EQ(back.iterations, 7);
}

TEST(Refine, RefusesEveryOtherSpellingNamingTheOption) {
  for (const char* bad : {"", "auto", "LM", "newton", " lm"}) {
    try {
      parse_refine_method(bad, "refine");
      FAIL() << "accepted method '" << bad << "'";
    } catch (const Error& e) {
      EXPECT_EQ(std::string(e.what()),
                std::string("refine must be 'none', 'lm' or 'lbfgs', got '") + bad + "'");
    }
  }
  try {
    parse_linear_solver("sparse");
    FAIL() << "accepted solver 'sparse'";
  } catch (const Error& e) {
    EXPECT_EQ(std::string(e.what()),
              "refine.linear_solver (--refine-solver) must be 'dense_qr', "
              "'dense_normal_cholesky' or 'blas_normal_cholesky', got 'sparse'");
  }
  EXPECT_THROW(nlohmann::json({{"method", "auto"}}).get<RefineOptions>(), Error);
}

}  // namespace
}  // namespace csympnet
