#include <algorithm>
#include <map>

#include "backend/loop.hpp"
#include "element/trilinear.hpp"

namespace hexcut::backend {

CellColours colour_cells(const std::vector<std::array<int, 3>>& position) {
  const std::size_t n = position.size();
  std::vector<int> colour(n);
  std::map<std::array<int, 3>, int> seen;  // cells met so far at each position
  int num = 0;
  for (std::size_t e = 0; e < n; ++e) {
    const auto& p = position[e];
    const int k = seen[p]++;
    colour[e] = element::parity_octant(p[0], p[1], p[2]) + 8 * k;
    num = std::max(num, colour[e] + 1);
  }
  CellColours c;
  c.offset.assign(num + 1, 0);
  for (int k : colour) ++c.offset[k + 1];
  for (int k = 0; k < num; ++k) c.offset[k + 1] += c.offset[k];
  c.cell.resize(n);
  std::vector<std::int32_t> next(c.offset.begin(), c.offset.end() - 1);
  for (std::size_t e = 0; e < n; ++e) c.cell[next[colour[e]]++] = std::int32_t(e);
  return c;
}

}  // namespace hexcut::backend
