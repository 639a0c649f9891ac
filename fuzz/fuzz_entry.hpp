// The fuzz entry points, shared by the libFuzzer targets (fuzz_*.cpp, clang) and the replay
// test of the normal suite (tests/io/fuzz_replay_test.cpp, any compiler).
//
// Each one feeds arbitrary bytes to a parser. A csympnet::Error is the expected answer to bad
// input and is swallowed; anything else escapes and is a finding: another exception type, a
// sanitizer report, or an accepted input that breaks the reader's contract (checked below and
// reported through std::abort so libFuzzer records it as a crash).
#pragma once

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>
#include <vector>

#include "csympnet/core/error.hpp"
#include "csympnet/data/csv.hpp"
#include "csympnet/models/model_file.hpp"

namespace csympnet::fuzz {

[[noreturn]] inline void contract_broken(const char* what) {
  std::fprintf(stderr, "fuzz: contract broken: %s\n", what);
  std::abort();
}

inline bool same_bits(const Matrix& a, const Matrix& b) {
  return a.rows() == b.rows() && a.cols() == b.cols() &&
         (a.size() == 0 || std::memcmp(a.data(), b.data(),
                                       sizeof(double) * static_cast<std::size_t>(a.size())) == 0);
}

// An accepted pairs file is valid data, and writing it and reading it back is exact.
inline int csv_pairs(const std::uint8_t* data, std::size_t size) {
  PairSet p;
  try {
    p = parse_pairs_csv(std::string(reinterpret_cast<const char*>(data), size), "fuzz.csv");
  } catch (const Error&) {
    return 0;
  }
  if (p.size() < 1 || p.d() < 1 || p.dim() != 2 * p.d()) contract_broken("pairs shape");
  try {
    p.validate("fuzz");
  } catch (const Error&) {
    contract_broken("accepted pairs fail validate()");
  }
  const PairSet q = parse_pairs_csv(pairs_csv_text(p), "roundtrip.csv");
  if (!same_bits(p.z0, q.z0) || !same_bits(p.z1, q.z1) || !same_bits(p.h, q.h))
    contract_broken("pairs do not round-trip bit-exactly");
  return 0;
}

// An accepted trajectories file is valid data and round-trips exactly; converting it to pairs
// either works or fails with Error.
inline int csv_trajectories(const std::uint8_t* data, std::size_t size) {
  const std::string text(reinterpret_cast<const char*>(data), size);
  std::vector<Trajectory> trajs;
  try {
    trajs = parse_trajectories_csv(text, "fuzz.csv");
  } catch (const Error&) {
    return 0;
  }
  if (trajs.empty()) contract_broken("no trajectories returned");
  for (const Trajectory& tr : trajs) {
    try {
      tr.validate("fuzz");
    } catch (const Error&) {
      contract_broken("accepted trajectory fails validate()");
    }
    if (tr.z.rows() != trajs.front().z.rows()) contract_broken("trajectory dimensions differ");
  }
  const std::vector<Trajectory> back =
      parse_trajectories_csv(trajectories_csv_text(trajs), "roundtrip.csv");
  if (back.size() != trajs.size()) contract_broken("trajectory count changed on round trip");
  for (std::size_t k = 0; k < trajs.size(); ++k)
    if (!same_bits(trajs[k].t, back[k].t) || !same_bits(trajs[k].z, back[k].z))
      contract_broken("trajectories do not round-trip bit-exactly");
  try {
    const PairSet p = parse_any_as_pairs(text, "fuzz.csv");
    p.validate("fuzz");
  } catch (const Error&) {
  }
  return 0;
}

// An accepted model file has finite parameters of the architecture's length, and saving it
// again gives a document that loads to the same bits.
inline int model_file(const std::uint8_t* data, std::size_t size) {
  SavedModel m;
  try {
    m = model_from_text(std::string(reinterpret_cast<const char*>(data), size), "fuzz.json");
  } catch (const Error&) {
    return 0;
  }
  if (m.theta.size() != m.model.n_params() || !m.theta.allFinite())
    contract_broken("accepted model has bad parameters");
  const SavedModel again = model_from_json(model_to_json(m.model, m.theta, m.meta), "again");
  if (!same_bits(m.theta, again.theta)) contract_broken("model does not round-trip");
  return 0;
}

}  // namespace csympnet::fuzz
