// DICOM series (geometry::load_dicom_series): slices written by GDCM's own writer, read back
// against the same phantom given as a raw file with the spacing, position and rescale the
// slices state, in NIfTI's RAS frame; files in any order, other files in the folder skipped,
// axes reversed where they run along -x, -y, -z; and the refusals (oblique, a missing slice,
// two series, no DICOM files) and the deck's defaults for a folder.
#include <gdcmAttribute.h>
#include <gdcmImageWriter.h>
#include <gdcmMediaStorage.h>
#include <gdcmTrace.h>
#include <gdcmWriter.h>
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <string>
#include <vector>

#include "common/errors.hpp"
#include "deck/deck.hpp"
#include "geometry/voxel_image.hpp"
#include "image_deck.hpp"
#include "test_util.hpp"

namespace hg = hexcut::geometry;
using Eigen::Vector3d;
using hg::test::TempDir;

namespace {

constexpr int kNx = 5, kNy = 4, kNz = 6;

std::int16_t value_at(int i, int j, int k) {
  return std::int16_t(i + 10 * j + 100 * k);
}

/// A series: pixel spacing (between columns, between rows), slice spacing [mm], the first
/// voxel's position and the row and column directions (LPS), the rescale.
struct Series {
  double dx = 0.5, dy = 0.7, dz = 1.2;
  Vector3d first{10.0, -20.0, 30.0};
  Vector3d row{1, 0, 0}, column{0, 1, 0};
  double slope = 2.0, intercept = -1024.0;
  std::string uid = "1.2.826.0.1.3680043.2.1125.1";
  std::vector<int> skip;  // slice numbers not written
};

/// Voxel centre (i, j, k) of the series in LPS mm.
Vector3d lps(const Series& s, int i, int j, int k) {
  return s.first + i * s.dx * s.row + j * s.dy * s.column + k * s.dz * s.row.cross(s.column);
}

/// Writes slice k of the phantom value_at as a CT image with GDCM.
void write_slice(const std::string& path, const Series& s, int k) {
  gdcm::Trace::WarningOff();  // the writer warns about tags the test does not need
  gdcm::ImageWriter w;
  gdcm::Image& im = w.GetImage();
  im.SetNumberOfDimensions(2);
  im.SetDimension(0, kNx);
  im.SetDimension(1, kNy);
  im.SetPixelFormat(gdcm::PixelFormat(gdcm::PixelFormat::INT16));
  im.SetPhotometricInterpretation(gdcm::PhotometricInterpretation::MONOCHROME2);
  im.SetTransferSyntax(gdcm::TransferSyntax::ExplicitVRLittleEndian);
  im.SetSpacing(0, s.dx);
  im.SetSpacing(1, s.dy);
  im.SetSpacing(2, s.dz);
  const Vector3d p = lps(s, 0, 0, k);
  const double origin[3] = {p[0], p[1], p[2]};
  im.SetOrigin(origin);
  im.SetOrigin(2, p[2]);  // a 2-D image keeps 2 components of a whole origin
  const double cosines[6] = {s.row[0], s.row[1], s.row[2], s.column[0], s.column[1], s.column[2]};
  im.SetDirectionCosines(cosines);
  im.SetSlope(s.slope);
  im.SetIntercept(s.intercept);
  std::vector<std::int16_t> pixels;
  for (int j = 0; j < kNy; ++j)
    for (int i = 0; i < kNx; ++i) pixels.push_back(value_at(i, j, k));
  gdcm::DataElement data(gdcm::Tag(0x7fe0, 0x0010));
  data.SetByteValue(reinterpret_cast<const char*>(pixels.data()),
                    std::uint32_t(pixels.size() * sizeof(std::int16_t)));
  im.SetDataElement(data);
  gdcm::DataSet& ds = w.GetFile().GetDataSet();
  const char* sop = gdcm::MediaStorage::GetMSString(gdcm::MediaStorage::CTImageStorage);
  gdcm::DataElement klass(gdcm::Tag(0x0008, 0x0016));
  klass.SetByteValue(sop, std::uint32_t(std::strlen(sop)));
  klass.SetVR(gdcm::Attribute<0x0008, 0x0016>::GetVR());
  ds.Replace(klass);
  gdcm::Attribute<0x0020, 0x000e> series;
  series.SetValue(s.uid.c_str());
  ds.Replace(series.GetAsDataElement());
  w.SetFileName(path.c_str());
  ASSERT_TRUE(w.Write()) << path;
}

/// The series in a folder of its own, slice k in a file whose name does not sort by k.
std::string write_series(const TempDir& dir, const std::string& name, const Series& s) {
  const std::string folder = dir.file(name);
  std::filesystem::create_directories(folder);
  for (int k = 0; k < kNz; ++k) {
    if (std::find(s.skip.begin(), s.skip.end(), k) != s.skip.end()) continue;
    write_slice(folder + "/IM" + std::to_string((7 * k + 3) % kNz), s, k);
  }
  return folder;
}

std::string error_of(const std::string& folder) {
  return hg::test::thrown<hexcut::InputError>([&] { hg::load_dicom_series(folder); });
}

}  // namespace

TEST(GeometryDicom, MatchesTheSamePhantomGivenAsRaw) {
  TempDir dir("dicom");
  const Series s;
  const std::string folder = write_series(dir, "ct", s);
  dir.write("ct/README.txt", "not a DICOM file\n");  // skipped
  {  // a DICOM file of no series (as a DICOMDIR is): skipped
    gdcm::Writer w;
    gdcm::DataSet& ds = w.GetFile().GetDataSet();
    const char* sop = "1.2.840.10008.1.3.10";  // Media Storage Directory Storage
    gdcm::DataElement klass(gdcm::Tag(0x0008, 0x0016));
    klass.SetByteValue(sop, std::uint32_t(std::strlen(sop)));
    klass.SetVR(gdcm::Attribute<0x0008, 0x0016>::GetVR());
    ds.Replace(klass);
    gdcm::Attribute<0x0004, 0x1130> fileset;
    fileset.SetValue("HEXCUT");
    ds.Replace(fileset.GetAsDataElement());
    gdcm::Attribute<0x0008, 0x0018> instance;  // SOP Instance UID, for the file meta header
    instance.SetValue("1.2.826.0.1.3680043.2.1125.9");
    ds.Replace(instance.GetAsDataElement());
    w.GetFile().GetHeader().SetDataSetTransferSyntax(gdcm::TransferSyntax::ExplicitVRLittleEndian);
    w.SetFileName(dir.file("ct/DICOMDIR").c_str());
    ASSERT_TRUE(w.Write());
  }
  hg::DicomInfo info;
  const auto img = hg::load_dicom_series(folder, &info);
  EXPECT_EQ(info.slices, kNz);
  EXPECT_EQ(info.slope, 2.0);
  EXPECT_EQ(info.intercept, -1024.0);
  EXPECT_EQ(info.series_uid, s.uid);
  // Rows along LPS +x and columns along +y run along RAS -x and -y: both reversed.
  EXPECT_TRUE(info.flipped[0] && info.flipped[1] && !info.flipped[2]);
  // The raw phantom in RAS order: raw voxel (a, b, c) is the series' (nx-1-a, ny-1-b, c),
  // its minimum corner the RAS position of voxel (nx-1, ny-1, 0) less half a voxel, in m.
  const std::string bytes = hg::test::int16_raw(
      {kNx, kNy, kNz}, [](int a, int b, int c) { return value_at(kNx - 1 - a, kNy - 1 - b, c); });
  const Vector3d spacing = 1e-3 * Vector3d(s.dx, s.dy, s.dz);
  const Vector3d corner = lps(s, kNx - 1, kNy - 1, 0);
  const Vector3d origin = 1e-3 * Vector3d(-corner[0], -corner[1], corner[2]) - 0.5 * spacing;
  const auto raw = hg::load_raw_image(dir.write("phantom.raw", bytes), {kNx, kNy, kNz}, "int16",
                                      true, origin, spacing);
  hg::test::expect_rescaled_copy(img, raw, 2.0f, -1024.0f);
}

TEST(GeometryDicom, EveryVoxelStaysWhereTheSlicesPutIt) {
  // Rows along LPS -x and columns along -y (RAS +x, +y: nothing reversed), and slices whose
  // normal points down (RAS -z: reversed): each voxel's value is found at its RAS position.
  TempDir dir("dicom_flip");
  Series s;
  s.row = Vector3d(-1, 0, 0);
  s.column = Vector3d(0, -1, 0);  // normal row x column = +z ...
  for (int variant = 0; variant < 2; ++variant) {
    if (variant == 1) s.column = Vector3d(0, 1, 0);  // ... normal -z
    const auto img = hg::load_dicom_series(write_series(dir, "v" + std::to_string(variant), s));
    for (int k = 0; k < kNz; ++k)
      for (int j = 0; j < kNy; ++j)
        for (int i = 0; i < kNx; ++i) {
          const Vector3d x = lps(s, i, j, k);
          EXPECT_EQ(img.sample(1e-3 * Vector3d(-x[0], -x[1], x[2])), 2.0 * value_at(i, j, k) - 1024)
              << "variant " << variant << " voxel " << i << " " << j << " " << k;
        }
  }
}

TEST(GeometryDicom, RefusesWhatIsNotOneRegularAxisAlignedVolume) {
  TempDir dir("dicom_bad");
  Series oblique;  // 30 degrees about z
  const double c = std::cos(0.5236), s = std::sin(0.5236);
  oblique.row = Vector3d(c, s, 0);
  oblique.column = Vector3d(-s, c, 0);
  EXPECT_NE(error_of(write_series(dir, "oblique", oblique)).find("oblique"), std::string::npos);
  for (int missing : {1, 2}) {  // a missing slice anywhere, also right after the first
    Series gap;
    gap.skip = {missing};
    const std::string g = error_of(write_series(dir, "gap" + std::to_string(missing), gap));
    EXPECT_NE(g.find("not evenly spaced"), std::string::npos) << g;
    // The pair around the gap: slices missing - 1 and missing + 1 (files IM((7k + 3) % 6)).
    for (int k : {missing - 1, missing + 1})
      EXPECT_NE(g.find("IM" + std::to_string((7 * k + 3) % kNz)), std::string::npos) << g;
  }
  const std::string two = write_series(dir, "two", Series{});
  Series other;
  other.uid = "1.2.826.0.1.3680043.2.1125.2";
  other.first[2] += 100;
  write_slice(two + "/OTHER", other, 0);
  const std::string t = error_of(two);
  EXPECT_NE(t.find("2 DICOM series"), std::string::npos) << t;
  std::filesystem::create_directories(dir.file("none"));
  dir.write("none/notes.txt", "no DICOM here\n");
  EXPECT_NE(error_of(dir.file("none")).find("no"), std::string::npos);
  EXPECT_NE(error_of(dir.file("missing")).find("folder"), std::string::npos);
}

TEST(GeometryDicom, DeckReadsAFolderAsADicomSeries) {
  // image: {file: FOLDER} is a DICOM series without a format key; its spacing comes from the
  // slices, so giving one is an error at its deck line.
  TempDir dir("dicom_deck");
  const Series s;
  hg::test::expect_image_deck("[[-0.013, 0.017, 0.029], [-0.010, 0.020, 0.037]]",
                              write_series(dir, "ct", s), 1e-3 * Vector3d(s.dx, s.dy, s.dz),
                              "not used for a DICOM series");
}
