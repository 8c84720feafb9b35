#include "geometry/voxel_image.hpp"

#include <hdf5.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <fstream>
#include <limits>
#include <stdexcept>
#include <type_traits>

#include "common/errors.hpp"

namespace hexcut::geometry {
namespace {

void check_geometry(const std::array<int, 3>& dims, const Eigen::Vector3d& origin,
                    const Eigen::Vector3d& spacing, const std::string& what) {
  for (int d : dims) {
    if (d <= 0) throw std::invalid_argument(what + ": image dimensions must be positive");
  }
  if (!origin.allFinite()) throw std::invalid_argument(what + ": origin is not finite");
  if (!spacing.allFinite() || !(spacing.array() > 0.0).all()) {
    throw std::invalid_argument(what + ": spacing must be positive and finite");
  }
}

std::uint64_t product(const std::array<int, 3>& dims) {
  return std::uint64_t(dims[0]) * std::uint64_t(dims[1]) * std::uint64_t(dims[2]);
}

template <typename T>
void convert(const std::vector<char>& raw, bool swap, std::vector<float>& out) {
  const std::size_t n = raw.size() / sizeof(T);
  out.resize(n);
  for (std::size_t i = 0; i < n; ++i) {
    unsigned char b[sizeof(T)];
    std::memcpy(b, raw.data() + i * sizeof(T), sizeof(T));
    if (swap) std::reverse(b, b + sizeof(T));
    T v;
    std::memcpy(&v, b, sizeof(T));
    out[i] = static_cast<float>(v);
  }
}

bool host_little_endian() {
  const std::uint16_t one = 1;
  unsigned char b;
  std::memcpy(&b, &one, 1);
  return b == 1;
}

// RAII for HDF5 identifiers.
class H5Handle {
 public:
  H5Handle(hid_t id, herr_t (*close)(hid_t)) : id_(id), close_(close) {}
  ~H5Handle() {
    if (id_ >= 0) close_(id_);
  }
  H5Handle(const H5Handle&) = delete;
  H5Handle& operator=(const H5Handle&) = delete;
  hid_t get() const { return id_; }
  bool ok() const { return id_ >= 0; }

 private:
  hid_t id_;
  herr_t (*close_)(hid_t);
};

// HDF5 prints its error stack to stderr by default; our own messages say what went
// wrong, so silence it while we work and restore the caller's handler afterwards.
class H5Quiet {
 public:
  H5Quiet() {
    H5Eget_auto2(H5E_DEFAULT, &func_, &data_);
    H5Eset_auto2(H5E_DEFAULT, nullptr, nullptr);
  }
  ~H5Quiet() { H5Eset_auto2(H5E_DEFAULT, func_, data_); }

 private:
  H5E_auto2_t func_ = nullptr;
  void* data_ = nullptr;
};

class ImageThreshold final : public Shape {
 public:
  ImageThreshold(std::shared_ptr<const VoxelImage> image, double threshold)
      : image_(std::move(image)), threshold_(threshold) {}
  // NaN (outside the image) compares false, so outside is never inside.
  bool contains(const Eigen::Vector3d& p) const override { return image_->sample(p) >= threshold_; }
  Aabb bounds() const override { return image_->bounds(); }

 private:
  std::shared_ptr<const VoxelImage> image_;
  double threshold_;
};

}  // namespace

double VoxelImage::sample(const Eigen::Vector3d& p) const {
  std::array<std::int64_t, 3> idx;
  for (int a = 0; a < 3; ++a) {
    const double x = std::floor((p[a] - origin[a]) / spacing[a]);
    if (!(x >= 0.0 && x < dims[a])) return std::numeric_limits<double>::quiet_NaN();
    idx[a] = static_cast<std::int64_t>(x);
  }
  return values[idx[0] + dims[0] * (idx[1] + dims[1] * idx[2])];
}

Aabb VoxelImage::bounds() const {
  const Eigen::Vector3d n(dims[0], dims[1], dims[2]);
  return {origin, origin + spacing.cwiseProduct(n)};
}

VoxelImage load_raw_image(const std::string& path, const std::array<int, 3>& dims,
                          const std::string& dtype, bool little_endian,
                          const Eigen::Vector3d& origin, const Eigen::Vector3d& spacing) {
  check_geometry(dims, origin, spacing, "raw image " + path);
  std::size_t bytes = 0;
  if (dtype == "uint8") {
    bytes = 1;
  } else if (dtype == "uint16" || dtype == "int16") {
    bytes = 2;
  } else if (dtype == "int32" || dtype == "float32") {
    bytes = 4;
  } else if (dtype == "float64") {
    bytes = 8;
  } else {
    throw std::invalid_argument("raw image " + path + ": unknown dtype '" + dtype +
                                "' (uint8, uint16, int16, int32, float32, float64)");
  }
  std::ifstream in(path, std::ios::binary | std::ios::ate);
  if (!in) throw InputError(path + ": cannot open image file");
  const std::uint64_t size = static_cast<std::uint64_t>(in.tellg());
  const std::uint64_t expected = product(dims) * bytes;
  if (size != expected) {
    throw InputError(path + ": file has " + std::to_string(size) + " bytes, but " +
                     std::to_string(dims[0]) + "x" + std::to_string(dims[1]) + "x" +
                     std::to_string(dims[2]) + " " + dtype + " needs " + std::to_string(expected));
  }
  std::vector<char> raw(expected);
  in.seekg(0);
  in.read(raw.data(), static_cast<std::streamsize>(expected));
  if (!in) throw InputError(path + ": error reading image file");

  VoxelImage image;
  image.dims = dims;
  image.origin = origin;
  image.spacing = spacing;
  const bool swap = little_endian != host_little_endian();
  if (dtype == "uint8") convert<std::uint8_t>(raw, swap, image.values);
  if (dtype == "uint16") convert<std::uint16_t>(raw, swap, image.values);
  if (dtype == "int16") convert<std::int16_t>(raw, swap, image.values);
  if (dtype == "int32") convert<std::int32_t>(raw, swap, image.values);
  if (dtype == "float32") convert<float>(raw, swap, image.values);
  if (dtype == "float64") convert<double>(raw, swap, image.values);
  return image;
}

template <typename T>
Hdf5Array<T> load_hdf5_array(const std::string& path, const std::string& dataset) {
  if (!std::ifstream(path)) throw InputError(path + ": cannot open file");
  H5Quiet quiet;
  if (H5Fis_hdf5(path.c_str()) <= 0) throw InputError(path + ": not an HDF5 file");
  // Default (serial) file access: input arrays are small next to the solve, and every rank
  // reading them independently is simpler than a collective open.
  H5Handle file(H5Fopen(path.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT), H5Fclose);
  if (!file.ok()) throw InputError(path + ": cannot open HDF5 file");
  if (H5Lexists(file.get(), dataset.c_str(), H5P_DEFAULT) <= 0) {
    throw InputError(path + ": no dataset '" + dataset + "'");
  }
  H5Handle dset(H5Dopen2(file.get(), dataset.c_str(), H5P_DEFAULT), H5Dclose);
  if (!dset.ok()) throw InputError(path + ": cannot open dataset '" + dataset + "'");
  H5Handle type(H5Dget_type(dset.get()), H5Tclose);
  const H5T_class_t cls = H5Tget_class(type.get());
  if (cls != H5T_INTEGER && cls != H5T_FLOAT) {
    throw InputError(path + ": dataset '" + dataset + "' is not numeric");
  }
  H5Handle space(H5Dget_space(dset.get()), H5Sclose);
  const int rank = H5Sget_simple_extent_ndims(space.get());
  if (rank < 0) throw InputError(path + ": cannot read the shape of dataset '" + dataset + "'");
  Hdf5Array<T> out;
  std::vector<hsize_t> shape(std::size_t(rank) + 1);
  H5Sget_simple_extent_dims(space.get(), shape.data(), nullptr);
  std::uint64_t count = 1;
  for (int a = 0; a < rank; ++a) {
    out.shape.push_back(std::uint64_t(shape[a]));
    count *= std::uint64_t(shape[a]);
  }
  out.values.resize(count);
  // HDF5 converts any stored integer/float type to the native type asked for on read.
  const hid_t native = std::is_same_v<T, float> ? H5T_NATIVE_FLOAT : H5T_NATIVE_DOUBLE;
  if (count > 0 &&
      H5Dread(dset.get(), native, H5S_ALL, H5S_ALL, H5P_DEFAULT, out.values.data()) < 0) {
    throw InputError(path + ": cannot read dataset '" + dataset + "'");
  }
  return out;
}

template Hdf5Array<float> load_hdf5_array(const std::string&, const std::string&);
template Hdf5Array<double> load_hdf5_array(const std::string&, const std::string&);

VoxelImage load_hdf5_image(const std::string& path, const std::string& dataset,
                           const Eigen::Vector3d& origin, const Eigen::Vector3d& spacing) {
  auto array = load_hdf5_array<float>(path, dataset);
  if (array.shape.size() != 3) {
    throw InputError(path + ": dataset '" + dataset + "' must be 3-dimensional [nz][ny][nx]");
  }
  VoxelImage image;
  for (int a = 0; a < 3; ++a) {
    const std::uint64_t n = array.shape[2 - a];
    if (n == 0 || n > std::uint64_t(std::numeric_limits<int>::max())) {
      throw InputError(path + ": dataset '" + dataset + "' has an empty or huge dimension");
    }
    image.dims[a] = static_cast<int>(n);  // [nz][ny][nx] -> (nx, ny, nz)
  }
  check_geometry(image.dims, origin, spacing, "HDF5 image " + path);
  image.origin = origin;
  image.spacing = spacing;
  image.values = std::move(array.values);
  return image;
}

ShapePtr make_image_threshold(std::shared_ptr<const VoxelImage> image, double threshold) {
  if (!image) throw std::invalid_argument("image threshold: null image");
  if (image->values.size() != product(image->dims)) {
    throw std::invalid_argument("image threshold: image values do not match its dimensions");
  }
  if (std::isnan(threshold)) throw std::invalid_argument("image threshold: threshold is NaN");
  return std::make_shared<ImageThreshold>(std::move(image), threshold);
}

}  // namespace hexcut::geometry
