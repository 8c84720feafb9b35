#include "geometry/voxelize.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <optional>
#include <set>
#include <stdexcept>
#include <string>

namespace hexcut::geometry {
namespace {

constexpr double kNoYoungs = std::numeric_limits<double>::quiet_NaN();  // VoxelGrid: material's E

void check_grid(const VoxelGrid& grid) {
  if (grid.spec.h <= 0.0 || !std::isfinite(grid.spec.h)) {
    throw std::invalid_argument("voxel grid: cell size h must be positive");
  }
  if (static_cast<std::int64_t>(grid.material.size()) != grid.spec.num_cells()) {
    throw std::invalid_argument("voxel grid: material has " + std::to_string(grid.material.size()) +
                                " entries for " + std::to_string(grid.spec.num_cells()) +
                                " cells (use make_empty_grid)");
  }
  if (!grid.youngs.empty() && grid.youngs.size() != grid.material.size()) {
    throw std::invalid_argument("voxel grid: youngs must be empty or have one entry per cell");
  }
}

std::int16_t checked_material(int material) {
  if (material < 0 || material > std::numeric_limits<std::int16_t>::max()) {
    throw std::invalid_argument("voxel grid: material id " + std::to_string(material) +
                                " outside [0, 32767]");
  }
  return static_cast<std::int16_t>(material);
}

// Cells whose centre may lie in `box`, as a half-open index box clipped to the lattice.
// Padded by one cell so that round-off in the bounds cannot drop a boundary cell.
void cell_box(const LatticeSpec& spec, const Aabb& box, std::array<int, 3>& lo,
              std::array<int, 3>& hi) {
  for (int a = 0; a < 3; ++a) {
    const double first = std::floor((box.lo[a] - spec.origin[a]) / spec.h - 0.5) - 1.0;
    const double last = std::floor((box.hi[a] - spec.origin[a]) / spec.h - 0.5) + 1.0;
    if (std::isnan(first) || std::isnan(last)) {
      lo[a] = 0;
      hi[a] = spec.dims[a];
      continue;
    }
    // Clamping in double first keeps infinite bounds (half-spaces) from overflowing int.
    lo[a] = static_cast<int>(std::clamp(first, 0.0, double(spec.dims[a])));
    hi[a] = static_cast<int>(std::clamp(last + 1.0, 0.0, double(spec.dims[a])));
    hi[a] = std::max(hi[a], lo[a]);
  }
}

// The integer label of an image value, or nothing for NaN (outside the image) and values
// too large for an int. Shared by apply_image_labels() and make_image_labels(), so the
// lattice and the boundary's Hermite data agree on membership.
std::optional<int> rounded_label(double v) {
  if (!std::isfinite(v) || std::abs(v) > 2e9) return std::nullopt;
  return static_cast<int>(std::lround(v));
}

class ImageLabels final : public Shape {
 public:
  ImageLabels(std::shared_ptr<const VoxelImage> image, std::set<int> labels)
      : image_(std::move(image)), labels_(std::move(labels)) {}
  bool contains(const Eigen::Vector3d& p) const override {
    const auto label = rounded_label(image_->sample(p));
    return label && labels_.count(*label);
  }
  Aabb bounds() const override { return image_->bounds(); }

 private:
  std::shared_ptr<const VoxelImage> image_;
  std::set<int> labels_;
};

}  // namespace

ShapePtr make_image_labels(std::shared_ptr<const VoxelImage> image, std::set<int> labels) {
  if (!image) throw std::invalid_argument("image labels: null image");
  return std::make_shared<ImageLabels>(std::move(image), std::move(labels));
}

VoxelGrid make_empty_grid(const LatticeSpec& spec) {
  for (int d : spec.dims) {
    if (d < 0) throw std::invalid_argument("voxel grid: negative lattice dimension");
  }
  VoxelGrid grid;
  grid.spec = spec;
  grid.material.assign(spec.num_cells(), -1);
  return grid;
}

void apply(VoxelGrid& grid, const GeometryOp& op, std::vector<std::int32_t>* touched,
           std::int32_t tag) {
  check_grid(grid);
  if (!op.shape) throw std::invalid_argument("geometry op: null shape");
  const std::int16_t mat =
      op.mode == OpMode::subtract ? std::int16_t(-1) : checked_material(op.material);
  std::array<int, 3> lo, hi;
  cell_box(grid.spec, op.shape->bounds(), lo, hi);
  std::vector<std::uint8_t> inside;
  op.shape->classify_cells(grid.spec, lo, hi, inside);
  std::int64_t c = 0;
  for (int k = lo[2]; k < hi[2]; ++k) {
    for (int j = lo[1]; j < hi[1]; ++j) {
      for (int i = lo[0]; i < hi[0]; ++i, ++c) {
        if (!inside[c]) continue;
        std::int16_t& m = grid.material[grid.spec.cell_index(i, j, k)];
        if (op.mode == OpMode::assign && m < 0) continue;
        m = mat;
        // The last operation on a cell decides its E: a cell this one fills, re-assigns or
        // empties takes its material's E again, not one an earlier image gave it (an
        // implant added after a calibrated CT image is titanium, not bone).
        const auto idx = grid.spec.cell_index(i, j, k);
        if (!grid.youngs.empty()) grid.youngs[idx] = kNoYoungs;
        if (touched) (*touched)[idx] = tag;
      }
    }
  }
}

void apply_image_labels(VoxelGrid& grid, const VoxelImage& image,
                        const std::map<int, int>& label_to_material) {
  check_grid(grid);
  std::map<int, std::int16_t> table;
  for (const auto& [label, material] : label_to_material) table[label] = checked_material(material);
  std::array<int, 3> lo, hi;
  cell_box(grid.spec, image.bounds(), lo, hi);
  for (int k = lo[2]; k < hi[2]; ++k) {
    for (int j = lo[1]; j < hi[1]; ++j) {
      for (int i = lo[0]; i < hi[0]; ++i) {
        const auto label = rounded_label(image.sample(grid.spec.cell_centre(i, j, k)));
        if (!label) continue;
        const auto it = table.find(*label);
        if (it != table.end()) grid.material[grid.spec.cell_index(i, j, k)] = it->second;
      }
    }
  }
}

void apply_image_youngs(VoxelGrid& grid, const VoxelImage& image, double scale) {
  check_grid(grid);
  if (!std::isfinite(scale)) throw std::invalid_argument("image youngs: scale is not finite");
  if (grid.youngs.empty()) {
    grid.youngs.assign(grid.material.size(), std::numeric_limits<double>::quiet_NaN());
  }
  std::array<int, 3> lo, hi;
  cell_box(grid.spec, image.bounds(), lo, hi);
  for (int k = lo[2]; k < hi[2]; ++k) {
    for (int j = lo[1]; j < hi[1]; ++j) {
      for (int i = lo[0]; i < hi[0]; ++i) {
        const std::int64_t c = grid.spec.cell_index(i, j, k);
        if (grid.material[c] < 0) continue;
        const double v = image.sample(grid.spec.cell_centre(i, j, k));
        if (std::isnan(v)) continue;
        grid.youngs[c] = scale * v;
      }
    }
  }
}

double YoungsCalibration::youngs(double value, int material) const {
  const auto it = by_material.find(material);
  const double A = it == by_material.end() ? a : it->second[0];
  const double B = it == by_material.end() ? b : it->second[1];
  const double rho = std::max(density_slope * value + density_intercept, 0.0);
  return std::max(A * std::pow(rho, B), E_min);
}

void apply_image_calibrated_youngs(VoxelGrid& grid, const VoxelImage& image,
                                   const YoungsCalibration& calibration) {
  check_grid(grid);
  if (grid.youngs.empty()) {
    grid.youngs.assign(grid.material.size(), std::numeric_limits<double>::quiet_NaN());
  }
  const auto& spec = grid.spec;
  // Voxels [first, last) along axis a whose centres lie in [lo, hi).
  auto centres_in = [&](int a, double lo, double hi, int* first, int* last) {
    const double o = image.origin[a], s = image.spacing[a];
    *first = std::max(0, int(std::ceil((lo - o) / s - 0.5)));
    *last = std::min(image.dims[a], int(std::ceil((hi - o) / s - 0.5)));
  };
  std::array<int, 3> lo, hi;
  cell_box(spec, image.bounds(), lo, hi);
  for (int k = lo[2]; k < hi[2]; ++k) {
    for (int j = lo[1]; j < hi[1]; ++j) {
      for (int i = lo[0]; i < hi[0]; ++i) {
        const std::int64_t c = spec.cell_index(i, j, k);
        const int m = grid.material[c];
        if (m < 0) continue;
        const Eigen::Vector3d x = spec.cell_centre(i, j, k);
        // The cell's faces from the lattice, not centre +- h/2: neighbours share them
        // exactly, so a voxel centre on a face counts in one cell.
        const int ijk[3] = {i, j, k};
        int f[3], l[3];
        for (int a = 0; a < 3; ++a)
          centres_in(a, spec.origin[a] + spec.h * ijk[a], spec.origin[a] + spec.h * (ijk[a] + 1),
                     &f[a], &l[a]);
        double sum = 0.0;
        std::int64_t count = 0;
        for (int vk = f[2]; vk < l[2]; ++vk)
          for (int vj = f[1]; vj < l[1]; ++vj)
            for (int vi = f[0]; vi < l[0]; ++vi) {
              const double v =
                  image.values[std::size_t(vi) + std::size_t(image.dims[0]) *
                                                     (std::size_t(vj) + std::size_t(image.dims[1]) *
                                                                            std::size_t(vk))];
              if (std::isnan(v)) continue;
              sum += calibration.youngs(v, m);
              ++count;
            }
        if (count == 0 && (f[0] >= l[0] || f[1] >= l[1] || f[2] >= l[2])) {
          const double v = image.sample(x);  // a cell smaller than a voxel
          if (!std::isnan(v)) sum = calibration.youngs(v, m), count = 1;
        }
        if (count > 0) grid.youngs[c] = sum / double(count);
      }
    }
  }
}

std::int64_t count_filled(const VoxelGrid& grid) {
  return std::count_if(grid.material.begin(), grid.material.end(),
                       [](std::int16_t m) { return m >= 0; });
}

}  // namespace hexcut::geometry
