// Voxelization: builds the per-cell material table of the lattice from a sequence of CSG-like
// operations (doc/theory.md, "Voxelization").
#pragma once

#include <cstdint>
#include <map>
#include <memory>
#include <set>
#include <vector>

#include "common/lattice_spec.hpp"
#include "geometry/shape.hpp"
#include "geometry/voxel_image.hpp"

namespace hexcut::geometry {

struct VoxelGrid {
  LatticeSpec spec;
  std::vector<std::int16_t> material;  // dense, x fastest (LatticeSpec::cell_index), -1 = empty
  std::vector<double> youngs;  // empty, or dense per-cell Young's modulus; NaN = use material
};

/// A grid of spec.num_cells() empty cells and no Young's modulus override.
VoxelGrid make_empty_grid(const LatticeSpec& spec);

enum class OpMode {
  add,       // inside cells get `material` (filled or not)
  subtract,  // inside cells become empty
  assign,    // inside cells that are already filled get `material`; empty ones stay empty
};

struct GeometryOp {
  OpMode mode = OpMode::add;
  std::shared_ptr<const Shape> shape;
  int material = 0;
};

/// Applies one operation to the cells whose centre is inside op.shape. Only the cells
/// within the shape's bounds (clipped to the lattice) are visited. A cell the operation
/// changes loses any Young's modulus an earlier image gave it (grid.youngs: NaN, its
/// material's E): the last operation on a cell decides. Throws
/// std::invalid_argument for a null shape, a material outside [0, 32767], or a grid
/// whose material array does not match its spec.
/// `touched` (optional, dense like grid.material): set to `tag` in every cell changed.
void apply(VoxelGrid& grid, const GeometryOp& op, std::vector<std::int32_t>* touched = nullptr,
           std::int32_t tag = 0);

/// Label map: every cell whose centre samples a label listed in label_to_material gets
/// that material (an add); other cells are untouched. Labels are rounded to integers.
void apply_image_labels(VoxelGrid& grid, const VoxelImage& image,
                        const std::map<int, int>& label_to_material);

/// Solid where the image's rounded label is in `labels` (never outside the image): the
/// cells apply_image_labels() fills, as a shape (membership of the boundary's Hermite
/// data, geometry/crossing.hpp). Throws std::invalid_argument for a null image.
ShapePtr make_image_labels(std::shared_ptr<const VoxelImage> image, std::set<int> labels);

/// Stiffness map: every filled cell gets youngs = scale * sample(cell centre); cells
/// outside the image keep their value (NaN = use material). Allocates youngs (all NaN)
/// on first use.
void apply_image_youngs(VoxelGrid& grid, const VoxelImage& image, double scale);

/// The CT calibration of an image (doc/user-guide.md, "Images"; Dick 2012, ch. 5): a
/// voxel value v (e.g. Hounsfield units) has density rho = density_slope v +
/// density_intercept (in the unit the deck's numbers give, e.g. g/cm^3) and Young's modulus
/// E = max(a max(rho, 0)^b, E_min) [Pa], with (a, b) of the cell's material when
/// `by_material` lists it.
struct YoungsCalibration {
  double density_slope = 1.0, density_intercept = 0.0;
  double a = 1.0, b = 1.0;                           // E = a rho^b [Pa]
  double E_min = 0.0;                                // [Pa]
  std::map<int, std::array<double, 2>> by_material;  // material index -> (a, b)
  /// E [Pa] of a voxel value in a cell of `material`.
  double youngs(double value, int material) const;
};

/// Calibrated stiffness map: every filled cell that holds voxel centres gets the mean of
/// their E (Dick's rule; NaN voxels are skipped, voxels below E_min count as E_min); a
/// cell smaller than a voxel, holding no centre, takes the E of the voxel at its centre.
/// Cells outside the image, or whose voxels are all NaN, keep their value (NaN = use the
/// material). Allocates youngs (all NaN) on first use.
void apply_image_calibrated_youngs(VoxelGrid& grid, const VoxelImage& image,
                                   const YoungsCalibration& calibration);

/// Number of filled cells (material >= 0).
std::int64_t count_filled(const VoxelGrid& grid);

}  // namespace hexcut::geometry
