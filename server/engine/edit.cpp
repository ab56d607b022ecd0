#include "edit.hpp"

#include <map>
#include <tuple>

namespace marzipan {

void Edit::append(const std::vector<BrickChange>& later, const Box& laterRegion) {
  if (region.empty()) {
    region = laterRegion;
  } else if (!laterRegion.empty()) {
    for (int a = 0; a < 3; ++a) {
      region.lo[a] = std::min(region.lo[a], laterRegion.lo[a]);
      region.hi[a] = std::max(region.hi[a], laterRegion.hi[a]);
    }
  }
  if (later.empty()) return;
  if (changes.empty()) {
    changes = later;
    return;
  }
  auto key = [](Int3 b) { return std::make_tuple(b.z, b.y, b.x); };
  std::map<std::tuple<int, int, int>, std::size_t> at;
  for (std::size_t i = 0; i < changes.size(); ++i) at[key(changes[i].brick)] = i;
  for (const auto& c : later) {
    auto it = at.find(key(c.brick));
    if (it == at.end()) {
      at[key(c.brick)] = changes.size();
      changes.push_back(c);
    } else {
      changes[it->second].after = c.after;
    }
  }
  std::erase_if(changes, [](const BrickChange& c) { return c.before == c.after; });
}

}  // namespace marzipan
