#include "csympnet/models/column_split.hpp"

#include <algorithm>

namespace csympnet {

std::vector<Columns> column_ranges(Index n, int parts) {
  const Index blocks = (std::max<Index>(n, 0) + kColumnAlign - 1) / kColumnAlign;
  const Index count = std::max<Index>(1, std::min<Index>(parts, blocks));
  std::vector<Columns> ranges;
  ranges.reserve(static_cast<std::size_t>(count));
  Index begin = 0;
  for (Index r = 0; r < count; ++r) {
    // Range r ends at block ⌊blocks (r + 1) / count⌋: consecutive, none empty, sizes within one
    // block of each other.
    const Index end =
        r + 1 == count ? std::max<Index>(n, 0) : blocks * (r + 1) / count * kColumnAlign;
    ranges.push_back({begin, end});
    begin = end;
  }
  return ranges;
}

}  // namespace csympnet
