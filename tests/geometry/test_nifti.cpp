// NIfTI images (geometry::load_nifti_image): files written by the NIfTI reference library
// itself, read back against the same phantom given as a raw file with the spacing, origin
// and rescale the header states; axes along -x reversed; qform, sform and pixdim-only
// headers; units; and the refusals (oblique, 4-D, complex).
#include <gtest/gtest.h>
#include <nifti2_io.h>

#include <cmath>
#include <cstdint>
#include <cstring>
#include <string>

#include "common/errors.hpp"
#include "deck/deck.hpp"
#include "geometry/voxel_image.hpp"
#include "image_deck.hpp"
#include "test_util.hpp"

namespace hg = hexcut::geometry;
using Eigen::Vector3d;
using hg::test::TempDir;

namespace {

constexpr int kNx = 5, kNy = 4, kNz = 3;

std::int16_t value_at(int i, int j, int k) {
  return std::int16_t(i + 10 * j + 100 * k);
}

/// Header settings of a test file; M and t: voxel index -> world (file units).
struct Header {
  double M[3][3] = {{0.5, 0, 0}, {0, 0.25, 0}, {0, 0, 2.0}};
  double t[3] = {1.0, -2.0, 0.5};
  int sform = 1, qform = 0, units = NIFTI_UNITS_MM, datatype = DT_INT16;
  double slope = 2.0, intercept = -1024.0;
  std::int64_t nt = 1;
};

/// Writes the phantom value_at(i, j, k) with header h to `path` (.nii or .nii.gz).
void write_nifti(const std::string& path, const Header& h) {
  const std::int64_t dims[8] = {h.nt > 1 ? 4 : 3, kNx, kNy, kNz, h.nt, 1, 1, 1};
  nifti_image* nim = nifti_make_new_nim(dims, h.datatype, 1);
  ASSERT_NE(nim, nullptr);
  if (h.datatype == DT_INT16) {
    auto* d = static_cast<std::int16_t*>(nim->data);
    for (std::int64_t v = 0; v < h.nt; ++v)
      for (int k = 0; k < kNz; ++k)
        for (int j = 0; j < kNy; ++j)
          for (int i = 0; i < kNx; ++i) d[i + kNx * (j + kNy * (k + kNz * v))] = value_at(i, j, k);
  }
  for (int a = 0; a < 3; ++a) {
    const double len =
        std::sqrt(h.M[0][a] * h.M[0][a] + h.M[1][a] * h.M[1][a] + h.M[2][a] * h.M[2][a]);
    nim->pixdim[a + 1] = len;
  }
  nim->dx = nim->pixdim[1], nim->dy = nim->pixdim[2], nim->dz = nim->pixdim[3];
  nim->sform_code = h.sform;
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) nim->sto_xyz.m[r][c] = h.M[r][c];
    nim->sto_xyz.m[r][3] = h.t[r];
  }
  nim->qform_code = h.qform;
  nim->quatern_b = nim->quatern_c = nim->quatern_d = 0.0;
  nim->qfac = 1.0;
  nim->qoffset_x = h.t[0], nim->qoffset_y = h.t[1], nim->qoffset_z = h.t[2];
  nim->scl_slope = h.slope;
  nim->scl_inter = h.intercept;
  nim->xyz_units = h.units;
  ASSERT_EQ(nifti_set_filenames(nim, path.c_str(), 0, 1), 0);
  nifti_image_write(nim);
  nifti_image_free(nim);
}

/// The world position [file units] of the centre of voxel (i, j, k) under h.
Vector3d centre(const Header& h, int i, int j, int k) {
  Vector3d x;
  for (int r = 0; r < 3; ++r) x[r] = h.M[r][0] * i + h.M[r][1] * j + h.M[r][2] * k + h.t[r];
  return x;
}

}  // namespace

TEST(GeometryNifti, MatchesTheSamePhantomGivenAsRaw) {
  TempDir dir("nifti");
  const Header h;
  const std::string nii = dir.file("phantom.nii.gz");
  write_nifti(nii, h);
  hg::NiftiInfo info;
  const auto img = hg::load_nifti_image(nii, &info);
  EXPECT_EQ(info.transform, "sform");
  EXPECT_EQ(info.units, "mm");
  EXPECT_EQ(info.slope, 2.0);
  EXPECT_EQ(info.intercept, -1024.0);
  // The raw phantom with what the header states, in m: voxel (0,0,0) centred at t.
  const std::string bytes = hg::test::int16_raw({kNx, kNy, kNz}, value_at);
  const Vector3d spacing = 1e-3 * Vector3d(0.5, 0.25, 2.0);
  const Vector3d origin = 1e-3 * Vector3d(1.0, -2.0, 0.5) - 0.5 * spacing;
  const auto raw = hg::load_raw_image(dir.write("phantom.raw", bytes), {kNx, kNy, kNz}, "int16",
                                      true, origin, spacing);
  hg::test::expect_rescaled_copy(img, raw, 2.0f, -1024.0f);
}

TEST(GeometryNifti, AxesAlongMinusXAreReversedAndEveryVoxelStaysWhereTheHeaderPutsIt) {
  TempDir dir("nifti_flip");
  for (int variant = 0; variant < 3; ++variant) {
    Header h;
    if (variant == 0) h.M[0][0] = -0.5, h.M[2][2] = -2.0;  // radiological x, and z down
    if (variant == 1) h.sform = 0, h.qform = 1;            // qform only (identity rotation)
    if (variant == 2) h.sform = 0, h.units = NIFTI_UNITS_METER, h.slope = 0;  // pixdim only
    const std::string nii = dir.file("p" + std::to_string(variant) + ".nii");
    write_nifti(nii, h);
    hg::NiftiInfo info;
    const auto img = hg::load_nifti_image(nii, &info);
    const double unit = h.units == NIFTI_UNITS_METER ? 1.0 : 1e-3;
    const char* expected[] = {"sform", "qform", "pixdim"};
    EXPECT_EQ(info.transform, expected[variant]);
    EXPECT_EQ(info.flipped[0], variant == 0);
    EXPECT_EQ(info.flipped[2], variant == 0);
    const double slope = h.slope == 0 ? 1.0 : h.slope, inter = h.slope == 0 ? 0.0 : h.intercept;
    for (int k = 0; k < kNz; ++k)
      for (int j = 0; j < kNy; ++j)
        for (int i = 0; i < kNx; ++i) {
          // pixdim only: voxel (0,0,0) is centred at the world origin.
          const Vector3d x =
              variant == 2 ? Vector3d(0.5 * i, 0.25 * j, 2.0 * k) : centre(h, i, j, k);
          EXPECT_EQ(img.sample(unit * x), slope * value_at(i, j, k) + inter)
              << "variant " << variant << " voxel " << i << " " << j << " " << k;
        }
  }
}

TEST(GeometryNifti, RefusesWhatHexcutCannotRepresent) {
  TempDir dir("nifti_bad");
  auto message = [&](const Header& h, const std::string& name) {
    const std::string path = dir.file(name);
    write_nifti(path, h);
    return hg::test::thrown<hexcut::InputError>([&] { hg::load_nifti_image(path); });
  };
  Header oblique;  // 30 degrees about z
  const double c = std::cos(0.5236), s = std::sin(0.5236);
  oblique.M[0][0] = 0.5 * c, oblique.M[0][1] = -0.25 * s;
  oblique.M[1][0] = 0.5 * s, oblique.M[1][1] = 0.25 * c;
  EXPECT_NE(message(oblique, "oblique.nii").find("oblique"), std::string::npos);
  Header permuted;  // voxel x along world y
  permuted.M[0][0] = 0, permuted.M[1][0] = 0.5, permuted.M[1][1] = 0, permuted.M[0][1] = 0.25;
  EXPECT_NE(message(permuted, "permuted.nii").find("permutes"), std::string::npos);
  Header series;
  series.nt = 2;
  EXPECT_NE(message(series, "series.nii").find("2 volumes"), std::string::npos);
  Header complex;
  complex.datatype = DT_COMPLEX64;
  EXPECT_NE(message(complex, "complex.nii").find("not a real scalar"), std::string::npos);
  EXPECT_THROW(hg::load_nifti_image(dir.write("junk.nii", "not a nifti file")), hexcut::InputError);
}

TEST(GeometryNifti, DeckTakesTheVoxelsFromTheHeader) {
  // image: {file: X.nii.gz} is a NIfTI image without a format key; spacing, origin, dims
  // and dtype come from the header, so giving them is an error at their deck line.
  TempDir dir("nifti_deck");
  const std::string nii = dir.file("ct.nii.gz");
  write_nifti(nii, Header{});
  hg::test::expect_image_deck("[[0, -0.003, -0.001], [0.004, 0.0, 0.006]]", nii,
                              1e-3 * Vector3d(0.5, 0.25, 2.0), "not used for a NIfTI image");
}
