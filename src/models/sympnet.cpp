#include "sympnet.hpp"

#include "csympnet/core/error.hpp"

namespace csympnet {

SympNet::SympNet(std::unique_ptr<SymplecticCore> core) : core_(std::move(core)) {
  require(core_ != nullptr, "sympnet: the symplectic core must not be null");
}

nlohmann::json SympNet::hyperparams() const {
  return {{"type", "sympnet"}, {"d", core_->d()}, {"core", core_->core_spec()}};
}

}  // namespace csympnet
