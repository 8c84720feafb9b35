#include "output/h5_file.hpp"

#include <algorithm>
#include <stdexcept>
#include <type_traits>
#include <utility>

namespace hexcut::output {
namespace {

/// Native (memory) type and little-endian file type of T.
template <class T>
struct H5Types;
template <>
struct H5Types<double> {
  static hid_t mem() { return H5T_NATIVE_DOUBLE; }
  static hid_t file() { return H5T_IEEE_F64LE; }
};
template <>
struct H5Types<float> {
  static hid_t mem() { return H5T_NATIVE_FLOAT; }
  static hid_t file() { return H5T_IEEE_F32LE; }
};
template <>
struct H5Types<std::int32_t> {
  static hid_t mem() { return H5T_NATIVE_INT32; }
  static hid_t file() { return H5T_STD_I32LE; }
};
template <>
struct H5Types<std::int64_t> {
  static hid_t mem() { return H5T_NATIVE_INT64; }
  static hid_t file() { return H5T_STD_I64LE; }
};
template <>
struct H5Types<std::uint8_t> {
  static hid_t mem() { return H5T_NATIVE_UINT8; }
  static hid_t file() { return H5T_STD_U8LE; }
};

/// Silences HDF5's automatic error stack printing once per process.
void silence_hdf5() {
  static const bool done = [] {
    H5Eset_auto2(H5E_DEFAULT, nullptr, nullptr);
    return true;
  }();
  (void)done;
}

std::vector<hsize_t> shape_of(std::int64_t rows, std::int64_t cols) {
  if (cols == 0) return {static_cast<hsize_t>(rows)};
  return {static_cast<hsize_t>(rows), static_cast<hsize_t>(cols)};
}

std::string parent_of(const std::string& path) {
  auto pos = path.find_last_of('/');
  if (pos == std::string::npos || pos == 0) return "/";
  return path.substr(0, pos);
}

herr_t collect_name(hid_t, const char* name, const H5L_info_t*, void* out) {
  static_cast<std::vector<std::string>*>(out)->emplace_back(name);
  return 0;
}

}  // namespace

// ---------------------------------------------------------------------------- H5Handle
H5Handle& H5Handle::operator=(H5Handle&& other) noexcept {
  if (this != &other) {
    reset();
    id_ = other.id_;
    closer_ = other.closer_;
    other.id_ = H5I_INVALID_HID;
  }
  return *this;
}

herr_t H5Handle::reset() noexcept {
  herr_t status = 0;
  if (id_ >= 0 && closer_ != nullptr) status = closer_(id_);
  id_ = H5I_INVALID_HID;
  return status;
}

// ------------------------------------------------------------------------------ H5File
H5File::H5File(H5Handle file, std::string filename, MPI_Comm comm)
    : file_(std::move(file)), filename_(std::move(filename)), comm_(comm) {
  MPI_Comm_rank(comm_, &rank_);
}

H5File& H5File::operator=(H5File&& other) noexcept {
  if (this != &other) {
    file_.reset();
    file_ = std::move(other.file_);
    filename_ = std::move(other.filename_);
    comm_ = other.comm_;
    rank_ = other.rank_;
  }
  return *this;
}

H5File::~H5File() {
  file_.reset();
}

void H5File::fail(const std::string& operation, const std::string& path) const {
  throw std::runtime_error("HDF5: " + operation + " '" + path + "' in " + filename_ + " failed");
}

hid_t H5File::check(hid_t id, const char* operation, const std::string& path) const {
  if (id < 0) fail(operation, path);
  return id;
}

void H5File::check_status(herr_t status, const char* operation, const std::string& path) const {
  if (status < 0) fail(operation, path);
}

namespace {
// 4 MiB: measured as fast as OMPIO's default 32 MiB in hexcut's writes (11.5M DOFs on 2
// ranks: 5.2-6.3 s either way) and 21 MiB less on an aggregator rank (doc/benchmarks.md).
std::int64_t collective_buffer_bytes = std::int64_t(4) << 20;

H5Handle mpio_fapl(MPI_Comm comm, const std::string& filename) {
  H5Handle fapl(H5Pcreate(H5P_FILE_ACCESS), H5Pclose);
  MPI_Info info = MPI_INFO_NULL;
  if (collective_buffer_bytes > 0) {
    MPI_Info_create(&info);
    MPI_Info_set(info, "cb_buffer_size", std::to_string(collective_buffer_bytes).c_str());
  }
  // HDF5 duplicates the info object: it is freed here either way.
  const bool ok = fapl.valid() && H5Pset_fapl_mpio(fapl.get(), comm, info) >= 0;
  if (info != MPI_INFO_NULL) MPI_Info_free(&info);
  if (!ok) throw std::runtime_error("HDF5: set MPI-IO file access for '" + filename + "' failed");
  return fapl;
}
}  // namespace

void set_collective_buffer(std::int64_t bytes) {
  collective_buffer_bytes = bytes;
}

H5File H5File::create(const std::string& path, MPI_Comm comm) {
  silence_hdf5();
  H5Handle fapl = mpio_fapl(comm, path);
  hid_t id = H5Fcreate(path.c_str(), H5F_ACC_TRUNC, H5P_DEFAULT, fapl.get());
  if (id < 0) throw std::runtime_error("HDF5: create file '" + path + "' failed");
  return H5File(H5Handle(id, H5Fclose), path, comm);
}

H5File H5File::open(const std::string& path, MPI_Comm comm, Access access) {
  silence_hdf5();
  H5Handle fapl = mpio_fapl(comm, path);
  unsigned flags = access == Access::kReadOnly ? H5F_ACC_RDONLY : H5F_ACC_RDWR;
  hid_t id = H5Fopen(path.c_str(), flags, fapl.get());
  if (id < 0) throw std::runtime_error("HDF5: open file '" + path + "' failed");
  return H5File(H5Handle(id, H5Fclose), path, comm);
}

void H5File::flush() {
  if (!is_open()) return;
  check_status(H5Fflush(file_.get(), H5F_SCOPE_GLOBAL), "flush", "/");
}

void H5File::close() {
  if (!is_open()) return;
  if (file_.reset() < 0) throw std::runtime_error("HDF5: close file '" + filename_ + "' failed");
}

H5Handle H5File::collective_xfer() const {
  H5Handle dxpl(check(H5Pcreate(H5P_DATASET_XFER), "create transfer list for", filename_),
                H5Pclose);
  check_status(H5Pset_dxpl_mpio(dxpl.get(), H5FD_MPIO_COLLECTIVE), "set collective transfer for",
               filename_);
  return dxpl;
}

H5Handle H5File::open_object(const std::string& path) {
  if (!exists(path)) fail("open (no such object)", path);
  return H5Handle(check(H5Oopen(file_.get(), path.c_str(), H5P_DEFAULT), "open object", path),
                  H5Oclose);
}

H5Handle H5File::open_dataset(const std::string& path) {
  if (!exists(path)) fail("open dataset (no such dataset)", path);
  return H5Handle(check(H5Dopen2(file_.get(), path.c_str(), H5P_DEFAULT), "open dataset", path),
                  H5Dclose);
}

bool H5File::exists(const std::string& path) {
  if (path.empty() || path[0] != '/') fail("exists (path must be absolute)", path);
  std::size_t pos = 1;
  while (pos <= path.size()) {
    std::size_t next = path.find('/', pos);
    if (next == std::string::npos) next = path.size();
    if (next > pos) {
      std::string prefix = path.substr(0, next);
      htri_t e = H5Lexists(file_.get(), prefix.c_str(), H5P_DEFAULT);
      check_status(e, "check existence of", prefix);
      if (e == 0) return false;
      if (next < path.size()) {
        // An intermediate component must be a group for the next H5Lexists to be valid.
        H5O_info_t info;
        check_status(
            H5Oget_info_by_name2(file_.get(), prefix.c_str(), &info, H5O_INFO_BASIC, H5P_DEFAULT),
            "get info of", prefix);
        if (info.type != H5O_TYPE_GROUP) return false;
      }
    }
    pos = next + 1;
  }
  return true;
}

bool H5File::is_group(const std::string& path) {
  if (!exists(path)) return false;
  H5O_info_t info;
  check_status(H5Oget_info_by_name2(file_.get(), path.c_str(), &info, H5O_INFO_BASIC, H5P_DEFAULT),
               "get info of", path);
  return info.type == H5O_TYPE_GROUP;
}

void H5File::create_group(const std::string& path) {
  if (path == "/" || exists(path)) return;
  H5Handle lcpl(check(H5Pcreate(H5P_LINK_CREATE), "create link list for", path), H5Pclose);
  check_status(H5Pset_create_intermediate_group(lcpl.get(), 1), "set intermediate groups for",
               path);
  H5Handle group(check(H5Gcreate2(file_.get(), path.c_str(), lcpl.get(), H5P_DEFAULT, H5P_DEFAULT),
                       "create group", path),
                 H5Gclose);
}

void H5File::delete_link(const std::string& path) {
  if (!exists(path)) fail("delete (no such link)", path);
  check_status(H5Ldelete(file_.get(), path.c_str(), H5P_DEFAULT), "delete", path);
}

std::vector<std::string> H5File::list(const std::string& path) {
  if (!is_group(path)) fail("list (not a group)", path);
  std::vector<std::string> names;
  hsize_t index = 0;
  check_status(H5Literate_by_name(file_.get(), path.c_str(), H5_INDEX_NAME, H5_ITER_INC, &index,
                                  collect_name, &names, H5P_DEFAULT),
               "list", path);
  std::sort(names.begin(), names.end());
  return names;
}

std::vector<std::int64_t> H5File::dims(const std::string& path) {
  H5Handle dset = open_dataset(path);
  H5Handle space(check(H5Dget_space(dset.get()), "get dataspace of", path), H5Sclose);
  int rank = H5Sget_simple_extent_ndims(space.get());
  check_status(rank, "get rank of", path);
  std::vector<hsize_t> d(static_cast<std::size_t>(rank));
  check_status(H5Sget_simple_extent_dims(space.get(), d.data(), nullptr), "get dims of", path);
  return std::vector<std::int64_t>(d.begin(), d.end());
}

std::pair<std::string, int> H5File::element_type(const std::string& path) {
  H5Handle dset = open_dataset(path);
  H5Handle type(check(H5Dget_type(dset.get()), "get type of", path), H5Tclose);
  H5T_class_t cls = H5Tget_class(type.get());
  int size = static_cast<int>(H5Tget_size(type.get()));
  if (cls == H5T_FLOAT) return {"float", size};
  if (cls == H5T_STRING) return {"string", size};
  if (cls == H5T_INTEGER) {
    return {H5Tget_sign(type.get()) == H5T_SGN_NONE ? "uint" : "int", size};
  }
  return {"other", size};
}

// -------------------------------------------------------------------------- row tables
template <class T>
void H5File::write_rows(const std::string& path, std::int64_t global_rows, std::int64_t cols,
                        std::int64_t row_offset, std::int64_t local_rows, const T* data) {
  if (global_rows < 0 || cols < 0 || row_offset < 0 || local_rows < 0 ||
      row_offset + local_rows > global_rows)
    fail("write_rows (bad slab [" + std::to_string(row_offset) + ", +" +
             std::to_string(local_rows) + ") of " + std::to_string(global_rows) + " rows)",
         path);
  const std::vector<hsize_t> gshape = shape_of(global_rows, cols);
  const int ndims = static_cast<int>(gshape.size());

  H5Handle dset;
  if (exists(path)) {
    bool same = false;
    {
      H5Handle old = open_dataset(path);
      H5Handle type(check(H5Dget_type(old.get()), "get type of", path), H5Tclose);
      htri_t same_type = H5Tequal(type.get(), H5Types<T>::file());
      check_status(same_type, "compare type of", path);
      std::vector<std::int64_t> d = dims(path);
      same = same_type > 0 && d == std::vector<std::int64_t>(gshape.begin(), gshape.end());
      if (same) dset = std::move(old);
    }
    if (!same) delete_link(path);
  }
  if (!dset.valid()) {
    create_group(parent_of(path));
    H5Handle space(
        check(H5Screate_simple(ndims, gshape.data(), nullptr), "create dataspace for", path),
        H5Sclose);
    dset = H5Handle(check(H5Dcreate2(file_.get(), path.c_str(), H5Types<T>::file(), space.get(),
                                     H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT),
                          "create dataset", path),
                    H5Dclose);
  }

  // An empty table has no storage to write to (H5Dwrite fails on it); every rank sees the
  // same global_rows, so all skip the collective call together.
  if (global_rows == 0) return;

  H5Handle fspace(check(H5Dget_space(dset.get()), "get dataspace of", path), H5Sclose);
  std::vector<hsize_t> start(gshape.size(), 0), count = gshape;
  start[0] = static_cast<hsize_t>(row_offset);
  count[0] = static_cast<hsize_t>(local_rows);
  std::vector<hsize_t> mshape = count;
  mshape[0] = std::max<hsize_t>(mshape[0], 1);
  if (ndims == 2) mshape[1] = std::max<hsize_t>(mshape[1], 1);
  H5Handle mspace(
      check(H5Screate_simple(ndims, mshape.data(), nullptr), "create memory space for", path),
      H5Sclose);
  if (local_rows == 0) {
    check_status(H5Sselect_none(fspace.get()), "select none in", path);
    check_status(H5Sselect_none(mspace.get()), "select none in memory for", path);
  } else {
    check_status(H5Sselect_hyperslab(fspace.get(), H5S_SELECT_SET, start.data(), nullptr,
                                     count.data(), nullptr),
                 "select rows of", path);
  }
  T dummy{};
  H5Handle dxpl = collective_xfer();
  check_status(H5Dwrite(dset.get(), H5Types<T>::mem(), mspace.get(), fspace.get(), dxpl.get(),
                        data != nullptr ? static_cast<const void*>(data) : &dummy),
               "write", path);
}

template <class T>
void H5File::read_rows(const std::string& path, std::int64_t global_rows, std::int64_t cols,
                       std::int64_t row_offset, std::int64_t local_rows, T* data) {
  const std::vector<hsize_t> gshape = shape_of(global_rows, cols);
  std::vector<std::int64_t> d = dims(path);
  if (d != std::vector<std::int64_t>(gshape.begin(), gshape.end())) {
    std::string have, want;
    for (auto v : d) have += std::to_string(v) + " ";
    for (auto v : gshape) want += std::to_string(v) + " ";
    fail("read_rows (shape is [ " + have + "], expected [ " + want + "])", path);
  }
  if (row_offset < 0 || local_rows < 0 || row_offset + local_rows > global_rows)
    fail("read_rows (bad slab)", path);
  if (global_rows == 0) return;  // nothing to read (see write_rows)
  const int ndims = static_cast<int>(gshape.size());
  H5Handle dset = open_dataset(path);
  H5Handle fspace(check(H5Dget_space(dset.get()), "get dataspace of", path), H5Sclose);
  std::vector<hsize_t> start(gshape.size(), 0), count = gshape;
  start[0] = static_cast<hsize_t>(row_offset);
  count[0] = static_cast<hsize_t>(local_rows);
  std::vector<hsize_t> mshape = count;
  for (auto& m : mshape) m = std::max<hsize_t>(m, 1);
  H5Handle mspace(
      check(H5Screate_simple(ndims, mshape.data(), nullptr), "create memory space for", path),
      H5Sclose);
  if (local_rows == 0) {
    check_status(H5Sselect_none(fspace.get()), "select none in", path);
    check_status(H5Sselect_none(mspace.get()), "select none in memory for", path);
  } else {
    check_status(H5Sselect_hyperslab(fspace.get(), H5S_SELECT_SET, start.data(), nullptr,
                                     count.data(), nullptr),
                 "select rows of", path);
  }
  T dummy{};
  H5Handle dxpl = collective_xfer();
  check_status(H5Dread(dset.get(), H5Types<T>::mem(), mspace.get(), fspace.get(), dxpl.get(),
                       data != nullptr ? static_cast<void*>(data) : &dummy),
               "read", path);
}

template <class T>
void H5File::append_1d(const std::string& path, const T* values, std::int64_t n) {
  if (n < 0) fail("append (negative count)", path);
  if (!exists(path)) {
    create_group(parent_of(path));
    hsize_t zero = 0, unlimited = H5S_UNLIMITED, chunk = 256;
    H5Handle space(check(H5Screate_simple(1, &zero, &unlimited), "create dataspace for", path),
                   H5Sclose);
    H5Handle dcpl(check(H5Pcreate(H5P_DATASET_CREATE), "create creation list for", path), H5Pclose);
    check_status(H5Pset_chunk(dcpl.get(), 1, &chunk), "set chunking of", path);
    H5Handle created(check(H5Dcreate2(file_.get(), path.c_str(), H5Types<T>::file(), space.get(),
                                      H5P_DEFAULT, dcpl.get(), H5P_DEFAULT),
                           "create dataset", path),
                     H5Dclose);
  }
  std::vector<std::int64_t> d = dims(path);
  if (d.size() != 1) fail("append (not a 1-D dataset)", path);
  const hsize_t old_size = static_cast<hsize_t>(d[0]);
  hsize_t new_size = old_size + static_cast<hsize_t>(n);
  H5Handle dset = open_dataset(path);
  check_status(H5Dset_extent(dset.get(), &new_size), "extend", path);
  H5Handle fspace(check(H5Dget_space(dset.get()), "get dataspace of", path), H5Sclose);
  hsize_t count = static_cast<hsize_t>(n), mcount = std::max<hsize_t>(count, 1);
  H5Handle mspace(check(H5Screate_simple(1, &mcount, nullptr), "create memory space for", path),
                  H5Sclose);
  if (rank_ == 0 && n > 0) {
    check_status(
        H5Sselect_hyperslab(fspace.get(), H5S_SELECT_SET, &old_size, nullptr, &count, nullptr),
        "select appended rows of", path);
  } else {
    check_status(H5Sselect_none(fspace.get()), "select none in", path);
    check_status(H5Sselect_none(mspace.get()), "select none in memory for", path);
  }
  T dummy{};
  H5Handle dxpl = collective_xfer();
  check_status(H5Dwrite(dset.get(), H5Types<T>::mem(), mspace.get(), fspace.get(), dxpl.get(),
                        values != nullptr ? static_cast<const void*>(values) : &dummy),
               "append to", path);
}

void H5File::resize_1d(const std::string& path, std::int64_t size) {
  H5Handle dset = open_dataset(path);
  hsize_t s = static_cast<hsize_t>(size);
  check_status(H5Dset_extent(dset.get(), &s), "resize", path);
}

#define HEXCUT_INSTANTIATE(T)                                                                      \
  template void H5File::write_rows<T>(const std::string&, std::int64_t, std::int64_t,              \
                                      std::int64_t, std::int64_t, const T*);                       \
  template void H5File::read_rows<T>(const std::string&, std::int64_t, std::int64_t, std::int64_t, \
                                     std::int64_t, T*);                                            \
  template void H5File::append_1d<T>(const std::string&, const T*, std::int64_t);
HEXCUT_INSTANTIATE(double)
HEXCUT_INSTANTIATE(float)
HEXCUT_INSTANTIATE(std::int32_t)
HEXCUT_INSTANTIATE(std::int64_t)
HEXCUT_INSTANTIATE(std::uint8_t)
#undef HEXCUT_INSTANTIATE

// -------------------------------------------------------------------------- attributes
void H5File::write_attribute_raw(const std::string& object_path, const std::string& name,
                                 hid_t file_type, hid_t mem_type, const std::vector<hsize_t>& shape,
                                 const void* data) {
  const std::string where = object_path + "@" + name;
  H5Handle obj = open_object(object_path);
  htri_t e = H5Aexists(obj.get(), name.c_str());
  check_status(e, "check attribute", where);
  if (e > 0) check_status(H5Adelete(obj.get(), name.c_str()), "delete attribute", where);
  H5Handle space(
      check(shape.empty() ? H5Screate(H5S_SCALAR)
                          : H5Screate_simple(static_cast<int>(shape.size()), shape.data(), nullptr),
            "create dataspace for attribute", where),
      H5Sclose);
  H5Handle attr(
      check(H5Acreate2(obj.get(), name.c_str(), file_type, space.get(), H5P_DEFAULT, H5P_DEFAULT),
            "create attribute", where),
      H5Aclose);
  check_status(H5Awrite(attr.get(), mem_type, data), "write attribute", where);
}

void H5File::write_attribute(const std::string& object_path, const std::string& name,
                             double value) {
  write_attribute_raw(object_path, name, H5T_IEEE_F64LE, H5T_NATIVE_DOUBLE, {}, &value);
}

void H5File::write_attribute(const std::string& object_path, const std::string& name,
                             std::int64_t value) {
  write_attribute_raw(object_path, name, H5T_STD_I64LE, H5T_NATIVE_INT64, {}, &value);
}

namespace {
H5Handle string_type(std::size_t length) {
  H5Handle type(H5Tcopy(H5T_C_S1), H5Tclose);
  if (!type.valid() || H5Tset_size(type.get(), std::max<std::size_t>(length, 1)) < 0 ||
      H5Tset_strpad(type.get(), H5T_STR_NULLPAD) < 0 || H5Tset_cset(type.get(), H5T_CSET_UTF8) < 0)
    throw std::runtime_error("HDF5: create string type failed");
  return type;
}
}  // namespace

void H5File::write_attribute(const std::string& object_path, const std::string& name,
                             const std::string& value) {
  H5Handle type = string_type(value.size());
  std::string padded = value.empty() ? std::string(1, '\0') : value;
  write_attribute_raw(object_path, name, type.get(), type.get(), {}, padded.data());
}

void H5File::write_attribute(const std::string& object_path, const std::string& name,
                             const std::vector<double>& values) {
  write_attribute_raw(object_path, name, H5T_IEEE_F64LE, H5T_NATIVE_DOUBLE, {values.size()},
                      values.data());
}

void H5File::write_attribute(const std::string& object_path, const std::string& name,
                             const std::vector<std::int64_t>& values) {
  write_attribute_raw(object_path, name, H5T_STD_I64LE, H5T_NATIVE_INT64, {values.size()},
                      values.data());
}

bool H5File::has_attribute(const std::string& object_path, const std::string& name) {
  if (!exists(object_path)) return false;
  H5Handle obj = open_object(object_path);
  htri_t e = H5Aexists(obj.get(), name.c_str());
  check_status(e, "check attribute", object_path + "@" + name);
  return e > 0;
}

template <class T>
std::vector<T> H5File::read_attribute_vector(const std::string& object_path,
                                             const std::string& name) {
  const std::string where = object_path + "@" + name;
  H5Handle obj = open_object(object_path);
  if (!has_attribute(object_path, name)) fail("read attribute (missing)", where);
  H5Handle attr(check(H5Aopen(obj.get(), name.c_str(), H5P_DEFAULT), "open attribute", where),
                H5Aclose);
  H5Handle space(check(H5Aget_space(attr.get()), "get dataspace of attribute", where), H5Sclose);
  hssize_t n = H5Sget_simple_extent_npoints(space.get());
  check_status(static_cast<herr_t>(n < 0 ? -1 : 0), "size attribute", where);
  std::vector<T> values(static_cast<std::size_t>(n));
  if (n > 0)
    check_status(H5Aread(attr.get(), H5Types<T>::mem(), values.data()), "read attribute", where);
  return values;
}

double H5File::read_attribute_double(const std::string& object_path, const std::string& name) {
  auto v = read_attribute_vector<double>(object_path, name);
  if (v.size() != 1) fail("read attribute (not a scalar)", object_path + "@" + name);
  return v[0];
}

std::int64_t H5File::read_attribute_int64(const std::string& object_path, const std::string& name) {
  auto v = read_attribute_vector<std::int64_t>(object_path, name);
  if (v.size() != 1) fail("read attribute (not a scalar)", object_path + "@" + name);
  return v[0];
}

std::vector<double> H5File::read_attribute_doubles(const std::string& object_path,
                                                   const std::string& name) {
  return read_attribute_vector<double>(object_path, name);
}

std::vector<std::int64_t> H5File::read_attribute_int64s(const std::string& object_path,
                                                        const std::string& name) {
  return read_attribute_vector<std::int64_t>(object_path, name);
}

namespace {
/// Reads a scalar string from an attribute (is_attr) or dataset, fixed or variable length.
std::string read_scalar_string(hid_t obj, hid_t type, bool is_attr, hid_t dxpl) {
  if (H5Tget_class(type) != H5T_STRING) throw std::runtime_error("not a string");
  htri_t vl = H5Tis_variable_str(type);
  if (vl < 0) throw std::runtime_error("type query failed");
  H5Handle mem(H5Tcopy(H5T_C_S1), H5Tclose);
  H5T_cset_t cset = H5Tget_cset(type);
  if (cset < 0 || H5Tset_cset(mem.get(), cset) < 0) throw std::runtime_error("cset failed");
  if (vl > 0) {
    if (H5Tset_size(mem.get(), H5T_VARIABLE) < 0) throw std::runtime_error("type failed");
    char* text = nullptr;
    herr_t s = is_attr ? H5Aread(obj, mem.get(), &text)
                       : H5Dread(obj, mem.get(), H5S_ALL, H5S_ALL, dxpl, &text);
    if (s < 0) throw std::runtime_error("read failed");
    std::string out = text != nullptr ? text : "";
    H5free_memory(text);
    return out;
  }
  std::size_t size = H5Tget_size(type);
  if (H5Tset_size(mem.get(), size) < 0 || H5Tset_strpad(mem.get(), H5T_STR_NULLPAD) < 0)
    throw std::runtime_error("type failed");
  std::string out(size, '\0');
  herr_t s = is_attr ? H5Aread(obj, mem.get(), out.data())
                     : H5Dread(obj, mem.get(), H5S_ALL, H5S_ALL, dxpl, out.data());
  if (s < 0) throw std::runtime_error("read failed");
  out.erase(out.find_last_not_of('\0') + 1);
  return out;
}
}  // namespace

std::string H5File::read_attribute_string(const std::string& object_path, const std::string& name) {
  const std::string where = object_path + "@" + name;
  if (!has_attribute(object_path, name)) fail("read attribute (missing)", where);
  H5Handle obj = open_object(object_path);
  H5Handle attr(check(H5Aopen(obj.get(), name.c_str(), H5P_DEFAULT), "open attribute", where),
                H5Aclose);
  H5Handle type(check(H5Aget_type(attr.get()), "get type of attribute", where), H5Tclose);
  try {
    return read_scalar_string(attr.get(), type.get(), true, H5P_DEFAULT);
  } catch (const std::runtime_error& e) {
    fail(std::string("read string attribute (") + e.what() + ")", where);
  }
}

void H5File::write_string_dataset(const std::string& path, const std::string& text) {
  if (exists(path)) delete_link(path);
  create_group(parent_of(path));
  H5Handle type = string_type(text.size());
  H5Handle space(check(H5Screate(H5S_SCALAR), "create dataspace for", path), H5Sclose);
  H5Handle dset(check(H5Dcreate2(file_.get(), path.c_str(), type.get(), space.get(), H5P_DEFAULT,
                                 H5P_DEFAULT, H5P_DEFAULT),
                      "create dataset", path),
                H5Dclose);
  H5Handle fspace(check(H5Dget_space(dset.get()), "get dataspace of", path), H5Sclose);
  H5Handle mspace(check(H5Screate(H5S_SCALAR), "create memory space for", path), H5Sclose);
  if (rank_ != 0) {
    check_status(H5Sselect_none(fspace.get()), "select none in", path);
    check_status(H5Sselect_none(mspace.get()), "select none in memory for", path);
  }
  std::string padded = text.empty() ? std::string(1, '\0') : text;
  H5Handle dxpl = collective_xfer();
  check_status(
      H5Dwrite(dset.get(), type.get(), mspace.get(), fspace.get(), dxpl.get(), padded.data()),
      "write", path);
}

std::string H5File::read_string_dataset(const std::string& path) {
  H5Handle dset = open_dataset(path);
  H5Handle type(check(H5Dget_type(dset.get()), "get type of", path), H5Tclose);
  H5Handle dxpl = collective_xfer();
  try {
    return read_scalar_string(dset.get(), type.get(), false, dxpl.get());
  } catch (const std::runtime_error& e) {
    fail(std::string("read string dataset (") + e.what() + ")", path);
  }
}

}  // namespace hexcut::output
