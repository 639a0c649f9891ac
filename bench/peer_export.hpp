// The inputs of the PyTorch peer (bench/torch_peer.py): per preset, its training pairs, the
// architecture, csympnet's initial θ and csympnet's training losses over a few epochs from it.
#pragma once

#include <string>
#include <vector>

namespace csympnet::bench {

// Writes DIR/P-train.csv, DIR/P-spec.json, DIR/P-theta0.txt and DIR/P-losses.txt for each
// preset P (CSympNet-ID, seed 42), the losses of `epochs` full-batch AdamW epochs.
void export_peer_inputs(const std::string& dir, const std::vector<std::string>& presets,
                        int epochs);

}  // namespace csympnet::bench
