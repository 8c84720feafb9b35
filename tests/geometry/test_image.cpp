// Voxel images: raw and HDF5 round trips, sampling, and their use in voxelization.
#include <gtest/gtest.h>
#include <hdf5.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <fstream>
#include <limits>

#include "common/errors.hpp"
#include "geometry/voxel_image.hpp"
#include "geometry/voxelize.hpp"
#include "test_util.hpp"

namespace hg = hexcut::geometry;
using Eigen::Vector3d;
using hg::test::TempDir;

namespace {

constexpr int kNx = 5, kNy = 4, kNz = 3;

// A label-like value that differs in every voxel and in every axis.
int value_at(int i, int j, int k) {
  return i + 10 * j + 100 * k;
}

}  // namespace

TEST(GeometryImage, RawUint8RoundTripAndSampling) {
  TempDir dir("raw");
  std::string bytes;
  for (int k = 0; k < kNz; ++k) {
    for (int j = 0; j < kNy; ++j) {
      for (int i = 0; i < kNx; ++i) bytes.push_back(static_cast<char>(value_at(i, j, k) % 256));
    }
  }
  const std::string path = dir.write("img.raw", bytes);
  const Vector3d origin(1.0, -2.0, 0.5), spacing(0.5, 0.25, 2.0);
  const auto img = hg::load_raw_image(path, {kNx, kNy, kNz}, "uint8", true, origin, spacing);
  ASSERT_EQ(img.values.size(), std::size_t(kNx * kNy * kNz));
  for (int k = 0; k < kNz; ++k) {
    for (int j = 0; j < kNy; ++j) {
      for (int i = 0; i < kNx; ++i) {
        // Anywhere inside voxel (i,j,k) samples its value.
        const Vector3d p = origin + spacing.cwiseProduct(Vector3d(i + 0.3, j + 0.9, k + 0.01));
        EXPECT_EQ(img.sample(p), value_at(i, j, k) % 256);
      }
    }
  }
  EXPECT_TRUE(std::isnan(img.sample(origin - Vector3d(0.01, 0, 0))));
  EXPECT_TRUE(std::isnan(img.sample(origin + spacing.cwiseProduct(Vector3d(kNx, 0.5, 0.5)))));
  // Wrong size: the message says what was expected.
  try {
    hg::load_raw_image(path, {kNx, kNy, kNz + 1}, "uint8");
    FAIL() << "no InputError";
  } catch (const hexcut::InputError& e) {
    EXPECT_NE(std::string(e.what()).find("needs 80"), std::string::npos) << e.what();
  }
  EXPECT_THROW(hg::load_raw_image(path, {kNx, kNy, kNz}, "uint16"), hexcut::InputError);
  EXPECT_THROW(hg::load_raw_image(dir.file("none.raw"), {1, 1, 1}, "uint8"), hexcut::InputError);
  EXPECT_THROW(hg::load_raw_image(path, {kNx, kNy, kNz}, "complex64"), std::invalid_argument);
}

TEST(GeometryImage, RawBigEndianInt16AndFloat64) {
  TempDir dir("raw16");
  std::string be16, le64;
  const int n = 2 * 3 * 2;
  for (int c = 0; c < n; ++c) {
    const std::int16_t v = static_cast<std::int16_t>(-300 * c + 7);
    const auto u = static_cast<std::uint16_t>(v);
    be16.push_back(static_cast<char>(u >> 8));
    be16.push_back(static_cast<char>(u & 0xff));
    const double d = 0.125 * c - 1.0;
    char b[8];
    std::memcpy(b, &d, 8);  // the test host is little-endian (x86-64)
    le64.append(b, 8);
  }
  const auto a = hg::load_raw_image(dir.write("a.raw", be16), {2, 3, 2}, "int16", false);
  const auto b = hg::load_raw_image(dir.write("b.raw", le64), {2, 3, 2}, "float64", true);
  for (int c = 0; c < n; ++c) {
    EXPECT_EQ(a.values[c], -300 * c + 7);
    EXPECT_EQ(b.values[c], 0.125 * c - 1.0);
  }
}

TEST(GeometryImage, Hdf5RoundTrip) {
  TempDir dir("h5");
  const std::string path = dir.file("img.h5");
  {
    // Written as numpy would write a z,y,x-indexed array: C order, shape [nz][ny][nx].
    std::vector<std::int32_t> data;
    for (int k = 0; k < kNz; ++k) {
      for (int j = 0; j < kNy; ++j) {
        for (int i = 0; i < kNx; ++i) data.push_back(value_at(i, j, k));
      }
    }
    const hid_t file = H5Fcreate(path.c_str(), H5F_ACC_TRUNC, H5P_DEFAULT, H5P_DEFAULT);
    ASSERT_GE(file, 0);
    const hid_t group = H5Gcreate2(file, "scan", H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT);
    const hsize_t shape[3] = {kNz, kNy, kNx};
    const hid_t space = H5Screate_simple(3, shape, nullptr);
    const hid_t dset =
        H5Dcreate2(group, "labels", H5T_STD_I32LE, space, H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT);
    ASSERT_GE(H5Dwrite(dset, H5T_NATIVE_INT32, H5S_ALL, H5S_ALL, H5P_DEFAULT, data.data()), 0);
    const hsize_t flat_shape[2] = {3, 4};
    const hid_t flat_space = H5Screate_simple(2, flat_shape, nullptr);
    const hid_t flat = H5Dcreate2(file, "flat", H5T_NATIVE_FLOAT, flat_space, H5P_DEFAULT,
                                  H5P_DEFAULT, H5P_DEFAULT);
    H5Dclose(flat);
    H5Sclose(flat_space);
    H5Dclose(dset);
    H5Sclose(space);
    H5Gclose(group);
    H5Fclose(file);
  }
  const Vector3d origin(0, 0, 0), spacing(1, 1, 1);
  const auto img = hg::load_hdf5_image(path, "/scan/labels", origin, spacing);
  EXPECT_EQ(img.dims, (std::array<int, 3>{kNx, kNy, kNz}));
  for (int k = 0; k < kNz; ++k) {
    for (int j = 0; j < kNy; ++j) {
      for (int i = 0; i < kNx; ++i) {
        EXPECT_EQ(img.sample(Vector3d(i + 0.5, j + 0.5, k + 0.5)), value_at(i, j, k));
      }
    }
  }
  EXPECT_THROW(hg::load_hdf5_image(path, "/scan/missing"), hexcut::InputError);
  EXPECT_THROW(hg::load_hdf5_image(path, "/flat"), hexcut::InputError);
  EXPECT_THROW(hg::load_hdf5_image(dir.file("none.h5"), "x"), hexcut::InputError);
  EXPECT_THROW(hg::load_hdf5_image(dir.write("text.h5", "not hdf5"), "x"), hexcut::InputError);
}

TEST(GeometryImage, ThresholdLabelsAndYoungs) {
  // 4x4x4 image of 1 mm voxels: label 1 in the lower half (k < 2), 2 in the upper half.
  auto img = std::make_shared<hg::VoxelImage>();
  img->dims = {4, 4, 4};
  img->spacing = Vector3d::Constant(1.0);
  for (int k = 0; k < 4; ++k) {
    for (int c = 0; c < 16; ++c) img->values.push_back(k < 2 ? 1.0f : 2.0f);
  }
  // Lattice of 0.5 cells over [-1, 5]^3: the image covers the middle 8^3 cells.
  hexcut::LatticeSpec spec;
  spec.origin = Vector3d::Constant(-1.0);
  spec.h = 0.5;
  spec.dims = {12, 12, 12};

  hg::VoxelGrid grid = hg::make_empty_grid(spec);
  hg::apply(grid, {hg::OpMode::add, hg::make_image_threshold(img, 1.5), 3});
  EXPECT_EQ(hg::count_filled(grid), 8 * 8 * 4);

  hg::VoxelGrid labels = hg::make_empty_grid(spec);
  hg::apply_image_labels(labels, *img, {{1, 7}});
  EXPECT_EQ(hg::count_filled(labels), 8 * 8 * 4);
  EXPECT_EQ(labels.material[spec.cell_index(2, 2, 2)], 7);
  EXPECT_EQ(labels.material[spec.cell_index(2, 2, 6)], -1);
  hg::apply_image_labels(labels, *img, {{2, 4}, {9, 1}});
  EXPECT_EQ(hg::count_filled(labels), 8 * 8 * 8);
  EXPECT_EQ(labels.material[spec.cell_index(2, 2, 6)], 4);

  hg::apply(labels,
            {hg::OpMode::add, hg::make_box(Vector3d::Constant(-1), Vector3d::Constant(5)), 0});
  hg::apply_image_youngs(labels, *img, 1e9);
  ASSERT_EQ(labels.youngs.size(), std::size_t(spec.num_cells()));
  EXPECT_EQ(labels.youngs[spec.cell_index(2, 2, 2)], 1e9);
  EXPECT_EQ(labels.youngs[spec.cell_index(2, 2, 6)], 2e9);
  EXPECT_TRUE(std::isnan(labels.youngs[spec.cell_index(0, 5, 5)]));  // outside the image

  // An implant added after the image: its cells take their material's E (NaN), the
  // others keep the image's; an assign or a subtract does the same to the cells it changes.
  hg::apply(labels, {hg::OpMode::add, hg::make_box(Vector3d(0, 0, 0), Vector3d(1, 1, 1)), 5});
  EXPECT_TRUE(std::isnan(labels.youngs[spec.cell_index(2, 2, 2)]));  // centre (0.25, ...)
  EXPECT_EQ(labels.youngs[spec.cell_index(4, 4, 4)], 1e9);           // outside the box
  hg::apply(labels,
            {hg::OpMode::assign, hg::make_box(Vector3d(1.5, 1.5, 2), Vector3d(2.5, 2.5, 3)), 2});
  EXPECT_TRUE(std::isnan(labels.youngs[spec.cell_index(6, 6, 6)]));
  EXPECT_EQ(labels.youngs[spec.cell_index(6, 6, 8)], 2e9);
}

TEST(GeometryImage, CalibrationLawsAndTheMeanPerCell) {
  // HU -> density (g/cm^3) -> E = a rho^b [Pa] with a floor, checked at given values against
  // the formula written out; then the cell E is the mean of its voxels' E (Dick's rule):
  // 2x2x2 voxels per cell, a NaN voxel skipped, a per-material law, and cells smaller than
  // a voxel taking the voxel at their centre.
  hg::YoungsCalibration cal;
  cal.density_slope = 0.0008, cal.density_intercept = 1.0;  // rho = 0.0008 HU + 1
  cal.a = 6.85e9, cal.b = 1.49;                             // Morgan et al. 2003, femoral neck
  cal.E_min = 10e6;
  EXPECT_DOUBLE_EQ(cal.youngs(1000.0, 0), 6.85e9 * std::pow(1.8, 1.49));
  EXPECT_DOUBLE_EQ(cal.youngs(-1000.0, 0), 6.85e9 * std::pow(0.2, 1.49));
  EXPECT_EQ(cal.youngs(-1240.0, 0), 10e6);  // rho = 0.008: 5.3e6 Pa, floored
  EXPECT_EQ(cal.youngs(-3000.0, 0), 10e6);  // rho < 0 counts as 0
  cal.by_material[1] = {1.0e9, 2.0};
  EXPECT_DOUBLE_EQ(cal.youngs(1000.0, 1), 1.0e9 * 1.8 * 1.8);

  // 4x4x4 voxels of 0.5 m from the origin, value v(i,j,k) = 100 (i + 4 j + 16 k).
  hg::VoxelImage img;
  img.dims = {4, 4, 4};
  img.spacing = Vector3d::Constant(0.5);
  for (int k = 0; k < 4; ++k)
    for (int j = 0; j < 4; ++j)
      for (int i = 0; i < 4; ++i) img.values.push_back(float(100 * (i + 4 * j + 16 * k)));
  img.values[1 + 4 * (1 + 4 * 1)] = std::numeric_limits<float>::quiet_NaN();  // in cell (0,0,0)
  hexcut::LatticeSpec spec;
  spec.h = 1.0;
  spec.dims = {2, 2, 2};
  hg::VoxelGrid grid = hg::make_empty_grid(spec);
  hg::apply(grid, {hg::OpMode::add, hg::make_box(Vector3d::Zero(), Vector3d::Constant(2)), 0});
  hg::apply(grid, {hg::OpMode::assign, hg::make_box(Vector3d(1, 1, 1), Vector3d::Constant(2)),
                   1});  // cell (1,1,1)
  hg::apply_image_calibrated_youngs(grid, img, cal);
  for (int ck = 0; ck < 2; ++ck)
    for (int cj = 0; cj < 2; ++cj)
      for (int ci = 0; ci < 2; ++ci) {
        const int material = ci == 1 && cj == 1 && ck == 1 ? 1 : 0;
        double sum = 0;
        int n = 0;
        for (int k = 2 * ck; k < 2 * ck + 2; ++k)
          for (int j = 2 * cj; j < 2 * cj + 2; ++j)
            for (int i = 2 * ci; i < 2 * ci + 2; ++i) {
              const float v = img.values[i + 4 * (j + 4 * k)];
              if (std::isnan(v)) continue;
              const double rho = std::max(0.0008 * v + 1.0, 0.0);
              sum += std::max(material ? 1.0e9 * rho * rho : 6.85e9 * std::pow(rho, 1.49), 10e6);
              ++n;
            }
        EXPECT_EQ(n, ci + cj + ck == 0 ? 7 : 8);
        EXPECT_NEAR(grid.youngs[spec.cell_index(ci, cj, ck)], sum / n, 1e-12 * sum / n)
            << ci << cj << ck;
      }
  // Cells of 0.25 m: each lies in one voxel and takes its E.
  spec.h = 0.25;
  spec.dims = {8, 8, 8};
  hg::VoxelGrid fine = hg::make_empty_grid(spec);
  hg::apply(fine, {hg::OpMode::add, hg::make_box(Vector3d::Zero(), Vector3d::Constant(2)), 0});
  hg::apply_image_calibrated_youngs(fine, img, cal);
  EXPECT_DOUBLE_EQ(fine.youngs[spec.cell_index(5, 2, 7)],
                   cal.youngs(100.0 * (2 + 4 * 1 + 16 * 3), 0));
  EXPECT_TRUE(std::isnan(fine.youngs[spec.cell_index(2, 2, 2)]));  // the NaN voxel
}
