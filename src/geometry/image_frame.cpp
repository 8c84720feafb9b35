#include "geometry/image_frame.hpp"

#include <cmath>
#include <limits>

#include "common/errors.hpp"

namespace hexcut::geometry {

ImageFrame axis_aligned_frame(const double M[3][3], const double t[3], const std::int64_t n[3],
                              double unit, const std::string& what) {
  for (int c = 0; c < 3; ++c) {
    const double len = std::sqrt(M[0][c] * M[0][c] + M[1][c] * M[1][c] + M[2][c] * M[2][c]);
    if (!(len > 0) || !std::isfinite(len))
      throw InputError(what + " has a zero or non-finite voxel size");
    for (int r = 0; r < 3; ++r)
      if (r != c && std::abs(M[r][c]) > 1e-6 * len)
        throw InputError(what + " is oblique or permutes the axes (voxel axis " +
                         std::to_string(c) + " has a world " + "xyz"[r] +
                         " component); hexcut needs the image axes along x, y, z: resample it "
                         "first (e.g. with a tool's reslice to the scanner axes)");
  }
  ImageFrame f;
  for (int a = 0; a < 3; ++a) {
    if (n[a] <= 0 || n[a] > std::numeric_limits<int>::max())
      throw InputError(what + ": the image has an empty or huge dimension");
    const double m = M[a][a];
    f.flipped[a] = m < 0;
    f.dims[a] = int(n[a]);
    f.spacing[a] = std::abs(m) * unit;
    // The centre of the voxel nearest -infinity along a, less half a voxel: its corner.
    const double first_centre = m > 0 ? t[a] : t[a] + m * double(n[a] - 1);
    f.origin[a] = (first_centre - 0.5 * std::abs(m)) * unit;
  }
  if (!f.origin.allFinite()) throw InputError(what + " has a non-finite offset");
  return f;
}

}  // namespace hexcut::geometry
