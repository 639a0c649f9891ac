#include <gtest/gtest.h>

#include "csympnet/experiments/fit.hpp"

namespace csympnet {
namespace {

RefineOptions resolved(Index n_pairs, Index dim, Index n_params) {
  RefineOptions r;
  r.method = "auto";
  resolve_auto_refine(r, n_pairs, dim, n_params);
  return r;
}

TEST(FitDefaults, AutoRefineScalesTheSecondStageWithTheProblem) {
  // s1-sized: Ceres' dense QR, as before the normal-equations LM existed.
  RefineOptions r = resolved(80, 2, 115);
  EXPECT_EQ(r.method, "lm");
  EXPECT_EQ(r.linear_solver, "dense_qr");
  // s3-sized (400 pairs, 2d = 20, 4201 parameters): LM on the normal equations.
  r = resolved(400, 20, 4201);
  EXPECT_EQ(r.method, "lm");
  EXPECT_EQ(r.linear_solver, "blas_normal_cholesky");
  // Just past each limit of the middle tier, and s2-100: L-BFGS.
  EXPECT_EQ(resolved(400, 20, kMaxNormalLmParams + 1).method, "lbfgs");
  EXPECT_EQ(resolved(5000, 20, 1001).method, "lbfgs");  // 1.0e8 Jacobian entries
  EXPECT_EQ(resolved(400, 200, 161101).method, "lbfgs");
  // The limits themselves are inside.
  EXPECT_EQ(resolved(1, 1, kMaxLmParams).linear_solver, "dense_qr");
  EXPECT_EQ(resolved(1, 1, kMaxNormalLmParams).linear_solver, "blas_normal_cholesky");
}

TEST(FitDefaults, BootstrapReplicatesInheritTheFitsSolver) {
  const RefineOptions fit = resolved(400, 20, 4201);
  const RefineOptions rep = default_replicate_refine_for(fit);
  EXPECT_EQ(rep.method, "lm");
  EXPECT_EQ(rep.linear_solver, "blas_normal_cholesky");
  EXPECT_EQ(rep.iterations, 10);
  EXPECT_FALSE(rep.keep_best_validation);
  RefineOptions lbfgs;
  lbfgs.method = "lbfgs";
  EXPECT_EQ(default_replicate_refine_for(lbfgs).method, "lbfgs");
}

}  // namespace
}  // namespace csympnet
