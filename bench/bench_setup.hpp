// What every benchmark starts from: a preset's training pairs (seed 42, as `csympnet run`
// draws them) and a model of that preset's architecture at its documented initial θ.
#pragma once

#include <string>

#include "csympnet/data/dataset.hpp"
#include "csympnet/models/model.hpp"

namespace csympnet::bench {

struct Setup {
  Model model;
  Vector theta;
  PairSet train;
  PairSet val;
};

// Training (and validation) pairs of `preset` drawn from the streams `csympnet run --seed
// seed` uses, and `model` initialised from its "init" stream. Besides the presets, the
// workloads P-Nk (e.g. s2-100-4k, s2-100-40k) are preset P with N thousand training pairs from
// the same stream (the GEMM-bound sizes of docs/benchmarks.md); the validation pairs are P's.
Setup make_setup(const std::string& preset, const std::string& model, std::uint64_t seed = 42);

// The analytic FLOP count of one full-batch CSympNet-ID epoch (forward, backward, AdamW) on
// n pairs; the formula is documented in docs/benchmarks.md ("FLOPs per epoch").
double csympnet_epoch_flops(const OneStepMap& map, Index n);

}  // namespace csympnet::bench
