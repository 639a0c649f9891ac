#include "csympnet/data/dataset.hpp"

#include <cmath>
#include <sstream>

#include "csympnet/core/error.hpp"

namespace csympnet {

namespace {

std::string num(double v) {
  return round_trip_text(v);
}

std::string shape(const Matrix& m) {
  return std::to_string(m.rows()) + "x" + std::to_string(m.cols());
}

// Names the first non-finite entry, so a user can find it in their data.
void require_finite(const Matrix& m, const std::string& where, const std::string& name) {
  for (Index j = 0; j < m.cols(); ++j)
    for (Index i = 0; i < m.rows(); ++i)
      if (!std::isfinite(m(i, j)))
        throw Error(where + ": " + name + "(" + std::to_string(i) + ", " + std::to_string(j) +
                    ") = " + num(m(i, j)) + "; expected a finite value");
}

void require_state_rows(Index rows, const std::string& where, const std::string& name) {
  require(rows > 0 && rows % 2 == 0, [&] {
    return where + ": " + name + " has " + std::to_string(rows) +
           " rows; expected an even number 2d > 0 (q then p)";
  });
}

// `n` pairs of dimension `dim`, to be filled by the caller.
PairSet uninitialized_pairs(Index dim, Index n) {
  PairSet out;
  out.z0.resize(dim, n);
  out.z1.resize(dim, n);
  out.h.resize(n);
  return out;
}

}  // namespace

void PairSet::validate(const std::string& where) const {
  require(z0.rows() == z1.rows() && z0.cols() == z1.cols(), [&] {
    return where + ": z0 is " + shape(z0) + " but z1 is " + shape(z1) + "; expected the same shape";
  });
  require_state_rows(z0.rows(), where, "z0");
  require(z0.cols() >= 1, [&] { return where + ": no pairs (N = 0); expected at least one"; });
  require(h.size() == z0.cols(), [&] {
    return where + ": h has length " + std::to_string(h.size()) +
           "; expected N = " + std::to_string(z0.cols());
  });
  require_finite(z0, where, "z0");
  require_finite(z1, where, "z1");
  for (Index n = 0; n < h.size(); ++n) {
    const auto at = [&] { return where + ": h[" + std::to_string(n) + "] = " + num(h(n)); };
    require(std::isfinite(h(n)), [&] { return at() + "; expected a finite value"; });
    require(h(n) > 0, [&] { return at() + " must be > 0"; });
  }
}

PairSet select_pairs(const PairSet& pairs, const std::vector<Index>& idx) {
  const Index n = pairs.size();
  require(pairs.z1.cols() == n && pairs.h.size() == n && pairs.z1.rows() == pairs.dim(), [&] {
    return "select_pairs: inconsistent pair set (z0 " + shape(pairs.z0) + ", z1 " +
           shape(pairs.z1) + ", h " + std::to_string(pairs.h.size()) +
           "); expected matching shapes";
  });
  const Index m = static_cast<Index>(idx.size());
  PairSet out = uninitialized_pairs(pairs.dim(), m);
  for (Index k = 0; k < m; ++k) {
    const Index j = idx[static_cast<std::size_t>(k)];
    require(j >= 0 && j < n, [&] {
      return "select_pairs: index " + std::to_string(j) + " at position " + std::to_string(k) +
             "; expected an index in [0, " + std::to_string(n) + ")";
    });
    out.z0.col(k) = pairs.z0.col(j);
    out.z1.col(k) = pairs.z1.col(j);
    out.h(k) = pairs.h(j);
  }
  return out;
}

PairSet concat_pairs(const std::vector<PairSet>& parts) {
  require(!parts.empty(), "concat_pairs: no parts; expected at least one pair set");
  const Index dim = parts.front().dim();
  Index total = 0;
  for (std::size_t k = 0; k < parts.size(); ++k) {
    const PairSet& p = parts[k];
    const std::string part = "concat_pairs: part " + std::to_string(k);
    require(p.dim() == dim, [&] {
      return part + " has dimension " + std::to_string(p.dim()) + "; expected " +
             std::to_string(dim) + " like part 0";
    });
    require(p.z1.rows() == dim && p.z1.cols() == p.size() && p.h.size() == p.size(), [&] {
      return part + " is inconsistent (z0 " + shape(p.z0) + ", z1 " + shape(p.z1) + ", h " +
             std::to_string(p.h.size()) + "); expected matching shapes";
    });
    total += p.size();
  }
  PairSet out = uninitialized_pairs(dim, total);
  Index at = 0;
  for (const PairSet& p : parts) {
    out.z0.middleCols(at, p.size()) = p.z0;
    out.z1.middleCols(at, p.size()) = p.z1;
    out.h.segment(at, p.size()) = p.h;
    at += p.size();
  }
  return out;
}

void Trajectory::validate(const std::string& where) const {
  require(t.size() >= 1,
          [&] { return where + ": no points; expected at least one time and state"; });
  require_state_rows(z.rows(), where, "z");
  require(z.cols() == t.size(), [&] {
    return where + ": z has " + std::to_string(z.cols()) + " columns but t has " +
           std::to_string(t.size()) + " entries; expected one state per time";
  });
  require_finite(z, where, "z");
  if (u.size() > 0) {
    require(u.cols() == t.size(), [&] {
      return where + ": u has " + std::to_string(u.cols()) + " columns but t has " +
             std::to_string(t.size()) + " entries; expected the inputs at every time";
    });
    require_finite(u, where, "u");
  }
  for (Index n = 0; n < t.size(); ++n) {
    require(std::isfinite(t(n)), [&] {
      return where + ": t[" + std::to_string(n) + "] = " + num(t(n)) + "; expected a finite value";
    });
    if (n > 0)
      require(t(n) > t(n - 1), [&] {
        return where + ": t[" + std::to_string(n) + "] = " + num(t(n)) + " is not greater than t[" +
               std::to_string(n - 1) + "] = " + num(t(n - 1)) +
               "; expected strictly increasing times";
      });
  }
}

PairSet pairs_from_trajectories(const std::vector<Trajectory>& trajs) {
  const std::string where = "pairs_from_trajectories";
  require(!trajs.empty(), [&] { return where + ": no trajectories; expected at least one"; });
  const Index dim = trajs.front().z.rows();
  Index total = 0;
  for (std::size_t k = 0; k < trajs.size(); ++k) {
    trajs[k].validate(where + ": trajectory " + std::to_string(k));
    require(trajs[k].z.rows() == dim, [&] {
      return where + ": trajectory " + std::to_string(k) + " has dimension " +
             std::to_string(trajs[k].z.rows()) + "; expected " + std::to_string(dim) +
             " like trajectory 0";
    });
    // A pair carries no inputs: dropping them would fit a driven record as a free one.
    require(trajs[k].u.size() == 0, [&] {
      return where + ": trajectory " + std::to_string(k) + " has " +
             std::to_string(trajs[k].u.rows()) +
             " inputs; pairs carry none (a driven record is fitted as trajectories)";
    });
    total += trajs[k].steps();
  }
  require(total > 0, [&] {
    return where + ": all " + std::to_string(trajs.size()) +
           " trajectories have a single point, so there are no pairs; expected "
           "at least one trajectory with two or more points";
  });
  PairSet out = uninitialized_pairs(dim, total);
  Index at = 0;
  for (const Trajectory& tr : trajs) {
    const Index s = tr.steps();
    out.z0.middleCols(at, s) = tr.z.leftCols(s);
    out.z1.middleCols(at, s) = tr.z.rightCols(s);
    out.h.segment(at, s) = tr.t.tail(s) - tr.t.head(s);
    at += s;
  }
  // Differences of huge finite times can overflow; validate catches that.
  out.validate(where);
  return out;
}

}  // namespace csympnet
