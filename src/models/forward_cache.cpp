#include "csympnet/core/error.hpp"
#include "csympnet/models/one_step_map.hpp"

namespace csympnet {

void ForwardCache::refuse(const char* reader) const {
  if (context_ == nullptr) {
    throw Error(std::string(reader) +
                ": the cache holds no forward pass (run forward() with it first)");
  }
  throw Error(std::string(reader) + ": the cache holds what a " + context_->owner() +
              " forward pass recorded, not a forward pass of this model");
}

}  // namespace csympnet
