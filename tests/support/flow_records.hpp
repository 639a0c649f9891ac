// What a symplectic core's flow recorded, as one list in application order, so that tests can
// compare two flows (or a flow with a reference implementation's list) whatever the core type.
#pragma once

#include <stdexcept>
#include <vector>

#include "../src/models/csympnet_id.hpp"
#include "../src/models/g_sympnet.hpp"
#include "../src/models/la_sympnet.hpp"

namespace csympnet::testing {

// G-SympNet: per module its input, then σ; LA-SympNet: its recorded steps.
inline std::vector<const Matrix*> flow_records(const SymplecticCore& core,
                                               const ForwardCache& flow_cache) {
  std::vector<const Matrix*> out;
  if (dynamic_cast<const GSympNet*>(&core) != nullptr) {
    for (const auto& m : flow_cache.context<GSympNet::FlowContext>("test").modules) {
      out.push_back(&m.input);
      out.push_back(&m.sigma);
    }
  } else if (dynamic_cast<const LaSympNet*>(&core) != nullptr) {
    for (const Matrix& s : flow_cache.context<LaSympNet::FlowContext>("test").steps) {
      out.push_back(&s);
    }
  } else {
    throw std::logic_error("flow_records: unknown core type");
  }
  return out;
}

// Everything a CSympNet-ID forward pass recorded: h, a (as 1 x N), p_in, p_core, then the
// core's flow records.
inline std::vector<Matrix> csympnet_records(const CSympNetId& model, const ForwardCache& cache) {
  const auto& ctx = cache.context<CSympNetId::Context>("test");
  std::vector<Matrix> out = {ctx.h.transpose(), ctx.a.transpose(), ctx.p_in, ctx.p_core};
  for (const Matrix* m : flow_records(model.core(), ctx.core)) out.push_back(*m);
  return out;
}

}  // namespace csympnet::testing
