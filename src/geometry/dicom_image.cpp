// DICOM series through GDCM (Debian libgdcm-dev): GDCM reads and decodes each slice (any
// transfer syntax it has a codec for) and gives its position, orientation, pixel spacing and
// rescale; this file checks that the slices form one axis-aligned, evenly spaced volume and
// places it on VoxelImage's grid in the RAS frame NIfTI uses (doc/user-guide.md, "Images").
#include <gdcmDirectory.h>
#include <gdcmImage.h>
#include <gdcmImageHelper.h>
#include <gdcmImageReader.h>
#include <gdcmScanner.h>
#include <gdcmTrace.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <limits>
#include <map>
#include <string>
#include <vector>

#include "common/errors.hpp"
#include "geometry/image_frame.hpp"
#include "geometry/voxel_image.hpp"

namespace hexcut::geometry {
namespace {

const gdcm::Tag kSeriesUid(0x0020, 0x000e);

/// One slice as read: where it is and its values after the rescale, in file order
/// (column index fastest).
struct Slice {
  std::string file;
  Eigen::Vector3d position;     // ImagePositionPatient: centre of the first voxel [mm], LPS
  Eigen::Vector3d row, column;  // ImageOrientationPatient: directions of i and j, LPS
  double spacing[2] = {1, 1};   // between columns (along row), between rows (along column) [mm]
  unsigned dims[2] = {0, 0};    // columns, rows
  double slope = 1, intercept = 0;
  std::vector<float> values;
};

template <class T>
void rescale(const char* buffer, std::size_t n, const gdcm::PixelFormat& pf, double slope,
             double intercept, std::vector<float>& out) {
  out.resize(n);
  const int stored = pf.GetBitsStored();
  const int bits = int(8 * sizeof(T));
  for (std::size_t p = 0; p < n; ++p) {
    T v;
    std::memcpy(&v, buffer + p * sizeof(T), sizeof(T));
    double x = double(v);
    if constexpr (std::is_integral_v<T>) {
      // Bits Stored < Bits Allocated (12 of 16 in many CTs): drop the bits above the
      // stored ones, with the sign of the highest stored bit for signed pixels.
      if (stored > 0 && stored < bits) {
        using U = std::make_unsigned_t<T>;
        const U mask = U((U(1) << stored) - 1);
        U u = U(v) & mask;
        if (std::is_signed_v<T> && (u >> (stored - 1)) & 1u) u = U(u | U(~mask));
        x = double(T(u));
      }
    }
    out[p] = float(slope * x + intercept);
  }
}

Slice read_slice(const std::string& file) {
  gdcm::ImageReader reader;
  reader.SetFileName(file.c_str());
  if (!reader.Read()) throw InputError(file + ": GDCM cannot read this file as a DICOM image");
  const gdcm::Image& image = reader.GetImage();
  const unsigned* d = image.GetDimensions();
  if (image.GetNumberOfDimensions() == 3 && d[2] > 1)
    throw InputError(file + ": a multi-frame DICOM file (" + std::to_string(d[2]) +
                     " frames); hexcut reads a series of single-frame slices (convert it, e.g. "
                     "with dcm2niix, and read the NIfTI)");
  const gdcm::PixelFormat pf = image.GetPixelFormat();
  if (pf.GetSamplesPerPixel() != 1 ||
      image.GetPhotometricInterpretation() != gdcm::PhotometricInterpretation::MONOCHROME2)
    throw InputError(file + ": DICOM photometric interpretation " +
                     std::string(gdcm::PhotometricInterpretation::GetPIString(
                         image.GetPhotometricInterpretation())) +
                     "; hexcut reads grey-scale MONOCHROME2 slices (CT, MR)");
  Slice s;
  s.file = file;
  // Position and orientation from the tags themselves: gdcm::Image keeps only as many
  // origin components as the image has dimensions (2 for a slice).
  const std::vector<double> o = gdcm::ImageHelper::GetOriginValue(reader.GetFile());
  const std::vector<double> c = gdcm::ImageHelper::GetDirectionCosinesValue(reader.GetFile());
  const double* h = image.GetSpacing();
  if (o.size() < 3 || c.size() < 6)
    throw InputError(file + ": DICOM image position or orientation is missing");
  s.position = Eigen::Vector3d(o[0], o[1], o[2]);
  s.row = Eigen::Vector3d(c[0], c[1], c[2]);
  s.column = Eigen::Vector3d(c[3], c[4], c[5]);
  s.spacing[0] = h[0];
  s.spacing[1] = h[1];
  s.dims[0] = d[0];
  s.dims[1] = d[1];
  s.slope = image.GetSlope();
  s.intercept = image.GetIntercept();
  if (!s.position.allFinite() || !s.row.allFinite() || !s.column.allFinite() ||
      std::abs(s.row.norm() - 1) > 1e-3 || std::abs(s.column.norm() - 1) > 1e-3 ||
      std::abs(s.row.dot(s.column)) > 1e-3)
    throw InputError(file + ": DICOM image position or orientation is missing or invalid");
  std::vector<char> buffer(image.GetBufferLength());
  if (!image.GetBuffer(buffer.data()))
    throw InputError(file + ": GDCM cannot decode the pixel data");
  const std::size_t n = std::size_t(d[0]) * d[1];
  const auto type = pf.GetScalarType();
  auto need = [&](std::size_t bytes) {
    if (buffer.size() < n * bytes) throw InputError(file + ": DICOM pixel data is too short");
  };
  switch (type) {
#define HEXCUT_DICOM_TYPE(ENUM, T)                                    \
  case gdcm::PixelFormat::ENUM:                                       \
    need(sizeof(T));                                                  \
    rescale<T>(buffer.data(), n, pf, s.slope, s.intercept, s.values); \
    break;
    HEXCUT_DICOM_TYPE(UINT8, std::uint8_t)
    HEXCUT_DICOM_TYPE(INT8, std::int8_t)
    HEXCUT_DICOM_TYPE(UINT16, std::uint16_t)
    HEXCUT_DICOM_TYPE(INT16, std::int16_t)
    HEXCUT_DICOM_TYPE(UINT32, std::uint32_t)
    HEXCUT_DICOM_TYPE(INT32, std::int32_t)
    HEXCUT_DICOM_TYPE(FLOAT32, float)
    HEXCUT_DICOM_TYPE(FLOAT64, double)
#undef HEXCUT_DICOM_TYPE
    default:
      throw InputError(file + ": DICOM pixel type " + std::string(pf.GetScalarTypeAsString()) +
                       " is not read (hexcut reads 8-, 16- and 32-bit integers and floats)");
  }
  return s;
}

}  // namespace

VoxelImage load_dicom_series(const std::string& directory, DicomInfo* info) {
  namespace fs = std::filesystem;
  if (!fs::is_directory(directory))
    throw InputError(directory + ": a DICOM series is read from a folder of slices");
  gdcm::Trace::WarningOff();  // GDCM's warnings go to stderr; hexcut reports its own errors
  gdcm::Directory dir;
  dir.Load(directory, false);
  const auto& files = dir.GetFilenames();
  // The DICOM files of the folder (others, a README or a DICOMDIR, are skipped) by series.
  gdcm::Scanner scanner;
  scanner.AddTag(kSeriesUid);
  if (files.empty() || !scanner.Scan(files))
    throw InputError(directory + ": the folder holds no files GDCM can scan");
  std::map<std::string, std::vector<std::string>> series;
  for (const auto& f : files)
    if (scanner.IsKey(f.c_str())) {
      const char* uid = scanner.GetValue(f.c_str(), kSeriesUid);
      series[uid ? uid : ""].push_back(f);
    }
  // DICOM files without a series UID (a DICOMDIR, a structured report) are no slices of one.
  if (series.size() > 1) series.erase("");
  if (series.empty()) throw InputError(directory + ": the folder holds no DICOM files");
  if (series.size() > 1) {
    std::string list;
    for (const auto& [uid, f] : series)
      list += "\n  " + (uid.empty() ? std::string("(no series UID)") : uid) + ": " +
              std::to_string(f.size()) + " file(s)";
    throw InputError(directory + ": the folder holds " + std::to_string(series.size()) +
                     " DICOM series; put each series in a folder of its own:" + list);
  }
  std::vector<Slice> slices;
  for (const auto& f : series.begin()->second) slices.push_back(read_slice(f));

  // One volume: the same grid in every slice, positions along the normal, evenly spaced.
  const Slice& first = slices.front();
  const Eigen::Vector3d normal = first.row.cross(first.column);
  for (const auto& s : slices) {
    if (s.dims[0] != first.dims[0] || s.dims[1] != first.dims[1] ||
        std::abs(s.spacing[0] - first.spacing[0]) > 1e-6 * first.spacing[0] ||
        std::abs(s.spacing[1] - first.spacing[1]) > 1e-6 * first.spacing[1] ||
        (s.row - first.row).norm() > 1e-6 || (s.column - first.column).norm() > 1e-6)
      throw InputError(s.file + ": this slice's size, pixel spacing or orientation differs from " +
                       first.file + "'s; a series must be one volume");
  }
  std::sort(slices.begin(), slices.end(), [&](const Slice& a, const Slice& b) {
    return a.position.dot(normal) < b.position.dot(normal);
  });
  // The slice spacing is the smallest step: a missing slice makes one step larger, wherever
  // it is, and the error names the pair around it.
  double dz = std::numeric_limits<double>::infinity();
  for (std::size_t k = 1; k < slices.size(); ++k) {
    const double along = (slices[k].position - slices[k - 1].position).dot(normal);
    if (!(along > 0))
      throw InputError(slices[k].file + ": two slices of the series lie at the same position (" +
                       slices[k - 1].file + ")");
    dz = std::min(dz, along);
  }
  for (std::size_t k = 1; k < slices.size(); ++k) {
    const Eigen::Vector3d step = slices[k].position - slices[k - 1].position;
    const double along = step.dot(normal);
    if (std::abs(along - dz) > 1e-3 * dz)
      throw InputError(directory + ": the slices are not evenly spaced (" + std::to_string(dz) +
                       " mm, then " + std::to_string(along) + " mm between " + slices[k - 1].file +
                       " and " + slices[k].file +
                       "); a missing slice? hexcut needs a regular grid");
    if ((step - along * normal).norm() > 1e-3 * dz)
      throw InputError(directory +
                       ": the slices are offset across their plane (gantry tilt or "
                       "a sheared stack, at " +
                       slices[k].file + "); resample to a regular grid first");
  }
  if (slices.size() == 1) dz = first.spacing[0];  // one slice: a layer as thick as it is wide

  // Voxel centre (i, j, k) in DICOM's patient frame (LPS, mm): P0 + i dx r + j dy c + k dz n.
  // NIfTI's RAS frame (+x towards the patient's right, +y anterior) negates LPS's x and y.
  const double ras[3] = {-1.0, -1.0, 1.0};
  double M[3][3], t[3];
  for (int r = 0; r < 3; ++r) {
    M[r][0] = ras[r] * first.spacing[0] * first.row[r];
    M[r][1] = ras[r] * first.spacing[1] * first.column[r];
    M[r][2] = ras[r] * dz * normal[r];
    t[r] = ras[r] * slices.front().position[r];
  }
  const std::int64_t n[3] = {first.dims[0], first.dims[1], std::int64_t(slices.size())};
  const auto frame = axis_aligned_frame(M, t, n, 1e-3, directory + ": DICOM orientation");
  VoxelImage image = frame.image();
  for (std::int64_t k = 0; k < n[2]; ++k) {
    const auto& v = slices[std::size_t(k)].values;
    for (std::int64_t j = 0; j < n[1]; ++j)
      for (std::int64_t i = 0; i < n[0]; ++i)
        image.values[frame.index(i, j, k)] = v[std::size_t(i + n[0] * j)];
  }
  if (info) {
    info->slices = int(slices.size());
    info->slope = first.slope;
    info->intercept = first.intercept;
    info->flipped = frame.flipped;
    info->series_uid = series.begin()->first;
  }
  return image;
}

}  // namespace hexcut::geometry
