// NIfTI images through the NIfTI reference library (nifti2_io, Debian libnifti2-dev and
// libniftiio-dev): the library reads the header and voxels (either NIfTI version, gzipped
// or not, byte-swapped as needed); this file maps the voxel-to-world transform onto
// VoxelImage's axis-aligned grid (doc/user-guide.md, "Images").
#include <nifti2_io.h>

#include <cmath>
#include <cstdint>
#include <memory>
#include <string>

#include "common/errors.hpp"
#include "geometry/image_frame.hpp"
#include "geometry/voxel_image.hpp"

namespace hexcut::geometry {
namespace {

using NiftiPtr = std::unique_ptr<nifti_image, void (*)(nifti_image*)>;

template <class T>
void convert(const nifti_image& nim, const ImageFrame& frame, double slope, double intercept,
             std::vector<float>& out) {
  const auto* in = static_cast<const T*>(nim.data);
  const std::int64_t n[3] = {nim.nx, nim.ny, nim.nz};
  for (std::int64_t k = 0; k < n[2]; ++k)
    for (std::int64_t j = 0; j < n[1]; ++j)
      for (std::int64_t i = 0; i < n[0]; ++i)
        out[frame.index(i, j, k)] =
            float(slope * double(in[i + n[0] * (j + n[1] * k)]) + intercept);
}

}  // namespace

VoxelImage load_nifti_image(const std::string& path, NiftiInfo* info) {
  nifti_set_debug_level(0);  // the library prints to stderr; hexcut reports its own errors
  NiftiPtr nim(nifti_image_read(path.c_str(), 1), nifti_image_free);
  if (!nim) throw InputError(path + ": cannot read as a NIfTI image");
  if (!nim->data) throw InputError(path + ": NIfTI image without voxel data");
  for (int d = 4; d <= 7; ++d)
    if (nim->dim[0] >= d && nim->dim[d] > 1)
      throw InputError(path + ": NIfTI image has " +
                       std::to_string(nim->nvox / (nim->nx * nim->ny * nim->nz)) +
                       " volumes (dimension " + std::to_string(d) + " is " +
                       std::to_string(nim->dim[d]) + "); hexcut reads one 3-D volume");
  const std::int64_t n[3] = {nim->nx, nim->ny, std::max<std::int64_t>(nim->nz, 1)};
  for (auto m : n)
    if (m <= 0 || m > std::numeric_limits<int>::max())
      throw InputError(path + ": NIfTI image has an empty or huge dimension");
  NiftiInfo I;
  // Voxel centre (i, j, k) -> world: x = M (i, j, k)^T + t.
  double M[3][3] = {{nim->dx, 0, 0}, {0, nim->dy, 0}, {0, 0, nim->dz}}, t[3] = {0, 0, 0};
  const nifti_dmat44* A = nim->sform_code > 0   ? &nim->sto_xyz
                          : nim->qform_code > 0 ? &nim->qto_xyz
                                                : nullptr;
  I.transform = nim->sform_code > 0 ? "sform" : nim->qform_code > 0 ? "qform" : "pixdim";
  if (A) {
    for (int r = 0; r < 3; ++r) {
      for (int c = 0; c < 3; ++c) M[r][c] = A->m[r][c];
      t[r] = A->m[r][3];
    }
  }
  double unit = 1e-3;
  switch (XYZT_TO_SPACE(nim->xyz_units)) {
    case NIFTI_UNITS_METER:
      unit = 1.0, I.units = "m";
      break;
    case NIFTI_UNITS_MM:
      unit = 1e-3, I.units = "mm";
      break;
    case NIFTI_UNITS_MICRON:
      unit = 1e-6, I.units = "um";
      break;
    default:
      I.units = "unknown (mm)";
  }
  const auto frame = axis_aligned_frame(M, t, n, unit, path + ": NIfTI " + I.transform);
  VoxelImage image = frame.image();
  I.flipped = frame.flipped;
  if (nim->scl_slope != 0.0 && std::isfinite(nim->scl_slope)) {
    I.slope = nim->scl_slope;
    I.intercept = std::isfinite(nim->scl_inter) ? nim->scl_inter : 0.0;
  }
  auto& v = image.values;
  switch (nim->datatype) {
    case DT_UINT8:
      convert<std::uint8_t>(*nim, frame, I.slope, I.intercept, v);
      break;
    case DT_INT8:
      convert<std::int8_t>(*nim, frame, I.slope, I.intercept, v);
      break;
    case DT_INT16:
      convert<std::int16_t>(*nim, frame, I.slope, I.intercept, v);
      break;
    case DT_UINT16:
      convert<std::uint16_t>(*nim, frame, I.slope, I.intercept, v);
      break;
    case DT_INT32:
      convert<std::int32_t>(*nim, frame, I.slope, I.intercept, v);
      break;
    case DT_UINT32:
      convert<std::uint32_t>(*nim, frame, I.slope, I.intercept, v);
      break;
    case DT_INT64:
      convert<std::int64_t>(*nim, frame, I.slope, I.intercept, v);
      break;
    case DT_UINT64:
      convert<std::uint64_t>(*nim, frame, I.slope, I.intercept, v);
      break;
    case DT_FLOAT32:
      convert<float>(*nim, frame, I.slope, I.intercept, v);
      break;
    case DT_FLOAT64:
      convert<double>(*nim, frame, I.slope, I.intercept, v);
      break;
    default:
      throw InputError(path + ": NIfTI data type " +
                       std::string(nifti_datatype_string(nim->datatype)) +
                       " is not a real scalar (hexcut reads integer and float images)");
  }
  if (info) *info = I;
  return image;
}

}  // namespace hexcut::geometry
