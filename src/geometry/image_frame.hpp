// The placement of a scanner image on hexcut's axis-aligned voxel grid, shared by the NIfTI and
// DICOM readers (doc/user-guide.md, "Images"): the file gives where each voxel centre lies
// (an affine map), hexcut needs the voxels along +x, +y, +z.
#pragma once

#include <Eigen/Core>
#include <array>
#include <cstdint>
#include <string>

#include "geometry/voxel_image.hpp"

namespace hexcut::geometry {

/// Where an image's voxels go: VoxelImage's dims, origin (minimum corner) and spacing [m],
/// and which file axes run along -x, -y, -z (their voxels are to be reversed).
struct ImageFrame {
  std::array<int, 3> dims{0, 0, 0};
  Eigen::Vector3d origin{0, 0, 0}, spacing{1, 1, 1};
  std::array<bool, 3> flipped{false, false, false};

  /// Position in VoxelImage::values (x fastest) of the file's voxel (i, j, k): reversed
  /// along the flipped axes.
  std::size_t index(std::int64_t i, std::int64_t j, std::int64_t k) const {
    const std::int64_t n[3] = {dims[0], dims[1], dims[2]};
    const std::int64_t a = flipped[0] ? n[0] - 1 - i : i, b = flipped[1] ? n[1] - 1 - j : j,
                       c = flipped[2] ? n[2] - 1 - k : k;
    return std::size_t(a + n[0] * (b + n[1] * c));
  }
  /// An image of this frame's dims, origin and spacing, its values allocated (0).
  VoxelImage image() const {
    VoxelImage v;
    v.dims = dims;
    v.origin = origin;
    v.spacing = spacing;
    v.values.resize(std::size_t(dims[0]) * std::size_t(dims[1]) * std::size_t(dims[2]));
    return v;
  }
};

/// The frame of an image whose voxel centre (i, j, k) lies at world M (i, j, k)^T + t, in
/// file units of `unit` m each (mm: 1e-3); n: voxels per file axis. M must be diagonal
/// up to 1e-6 of each column's length (the image axes along x, y, z, in order, either
/// direction). Throws InputError "`what` is oblique or permutes the axes ..." otherwise,
/// and for a zero or non-finite voxel size or offset; `what` names the file and the
/// transform ("scan.nii: NIfTI sform").
ImageFrame axis_aligned_frame(const double M[3][3], const double t[3], const std::int64_t n[3],
                              double unit, const std::string& what);

}  // namespace hexcut::geometry
