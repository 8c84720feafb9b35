// 3D voxel images (CT scans, label maps, stiffness maps) read from raw, HDF5 or NIfTI files.
#pragma once

#include <Eigen/Core>
#include <array>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "geometry/shape.hpp"

namespace hexcut::geometry {

/// A scalar field on a regular grid. Voxel (i,j,k) covers the box
/// origin + spacing∘[i,i+1]x[j,j+1]x[k,k+1] (origin is a corner, as for LatticeSpec).
struct VoxelImage {
  std::array<int, 3> dims{0, 0, 0};
  Eigen::Vector3d origin{0.0, 0.0, 0.0};
  Eigen::Vector3d spacing{1.0, 1.0, 1.0};
  std::vector<float> values;  // x fastest: i + dims[0]*(j + dims[1]*k)

  /// Value of the voxel containing p (nearest-voxel sampling); NaN outside the image.
  double sample(const Eigen::Vector3d& p) const;

  /// Extent of the image, origin to origin + spacing∘dims.
  Aabb bounds() const;
};

/// Reads a headerless raw file of dims[0]*dims[1]*dims[2] values, x fastest. dtype is one
/// of "uint8", "uint16", "int16", "int32", "float32", "float64". Throws hexcut::InputError
/// for a missing file or a size that does not match, std::invalid_argument for a bad
/// dtype, dims or spacing.
VoxelImage load_raw_image(const std::string& path, const std::array<int, 3>& dims,
                          const std::string& dtype, bool little_endian = true,
                          const Eigen::Vector3d& origin = Eigen::Vector3d::Zero(),
                          const Eigen::Vector3d& spacing = Eigen::Vector3d::Ones());

/// A whole HDF5 dataset: its shape (slowest axis first, as h5py reports it) and its values in
/// C order, converted to T (float or double) by HDF5.
template <typename T>
struct Hdf5Array {
  std::vector<std::uint64_t> shape;
  std::vector<T> values;
};

/// Reads a numeric dataset (any integer or float type, any rank) from an HDF5 file; T is
/// float or double. Throws hexcut::InputError for a missing file or dataset, a file that
/// is not HDF5 or a dataset that is not numeric.
template <typename T>
Hdf5Array<T> load_hdf5_array(const std::string& path, const std::string& dataset);

/// Reads a 3D dataset of any numeric type from an HDF5 file. The dataset is stored in C
/// order with shape [nz][ny][nx] (x fastest in memory, as numpy/h5py write a
/// z,y,x-indexed array), so it maps onto VoxelImage::values without reordering.
/// Throws hexcut::InputError for a missing file or dataset or a rank other than 3.
VoxelImage load_hdf5_image(const std::string& path, const std::string& dataset,
                           const Eigen::Vector3d& origin = Eigen::Vector3d::Zero(),
                           const Eigen::Vector3d& spacing = Eigen::Vector3d::Ones());

/// What load_nifti_image found in the file's header besides the voxels.
struct NiftiInfo {
  std::string transform;  ///< "sform", "qform" or "pixdim" (no transform in the file)
  std::string units;      ///< the file's spatial unit: "m", "mm", "um" or "unknown (mm)"
  double slope = 1.0, intercept = 0.0;  ///< rescale applied: value = slope * stored + intercept
  std::array<bool, 3> flipped{false, false, false};  ///< axes reversed to run along +x, +y, +z
};

/// Reads a NIfTI-1 or NIfTI-2 image (.nii, .nii.gz, .hdr/.img) with the NIfTI reference
/// library (nifti2_io). The voxel spacing and position come from the file's sform (if its
/// code is set), else its qform, else pixdim with the origin at 0, in the file's spatial unit
/// converted to m (unknown: mm, the NIfTI convention); voxel values are rescaled by
/// scl_slope and scl_inter when the slope is non-zero. Axes along -x, -y or -z are reversed
/// (origin is then the minimum corner as always); an orientation that is oblique or permutes
/// the axes is refused, as is an image with more than one volume (4-D) or a complex or RGB
/// type. Throws hexcut::InputError naming the file and the reason.
VoxelImage load_nifti_image(const std::string& path, NiftiInfo* info = nullptr);

/// What load_dicom_series found besides the voxels.
struct DicomInfo {
  int slices = 0;
  double slope = 1.0, intercept = 0.0;  ///< the first slice's rescale (each slice uses its own)
  std::array<bool, 3> flipped{false, false, false};  ///< axes reversed to run along +x, +y, +z
  std::string series_uid;
};

/// Reads a DICOM series, a folder of single-frame grey-scale slices, with GDCM. Files that
/// are not DICOM are skipped; the folder must hold one series. The slices are sorted by
/// their position along the normal of their plane and must form one regular volume: the
/// same size, pixel spacing and orientation, evenly spaced (to 0.1 %), not offset across
/// their plane (gantry tilt). Each slice's values are rescaled by its RescaleSlope and
/// RescaleIntercept (CT: Hounsfield units), Bits Stored respected. Positions are DICOM's
/// patient coordinates (LPS, mm) turned into NIfTI's RAS frame (x and y negated) and m, so
/// that a series and its NIfTI conversion (dcm2niix) lie at the same place; image axes
/// along -x, -y or -z are reversed as for NIfTI, and an oblique orientation is refused.
/// Throws hexcut::InputError naming the folder or file and the reason.
VoxelImage load_dicom_series(const std::string& directory, DicomInfo* info = nullptr);

/// Solid where image->sample(p) >= threshold (never outside the image).
ShapePtr make_image_threshold(std::shared_ptr<const VoxelImage> image, double threshold);

}  // namespace hexcut::geometry
