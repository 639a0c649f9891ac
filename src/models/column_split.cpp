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

bool ranges_tile(Index n, const std::vector<Columns>& ranges) {
  if (ranges.empty() || ranges.front().begin != 0 || ranges.back().end != n) return false;
  for (std::size_t r = 0; r < ranges.size(); ++r) {
    const Columns c = ranges[r];
    if (c.begin % kColumnAlign != 0 || c.size() < 1 || (r > 0 && c.begin != ranges[r - 1].end)) {
      return false;
    }
  }
  return true;
}

}  // namespace csympnet
