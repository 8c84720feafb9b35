// Thin RAII layer over the parallel HDF5 C API (MPI-IO driver, collective transfers).
//
// Every member that touches the file is COLLECTIVE over the communicator the file was
// opened on: all ranks must call it, in the same order, with the same path/shape/attribute
// arguments (only the row slab and the data pointer differ per rank). Every HDF5 return code
// is checked; failures throw std::runtime_error("HDF5: <operation> '<path>' in <file>
// failed"). HDF5's automatic error printing is switched off.
//
// Datasets written with write_rows are contiguous (not chunked, no filters); datasets
// created by append_1d are 1-D, chunked and extendible.
#pragma once

#include <hdf5.h>
#include <mpi.h>

#include <cstdint>
#include <string>
#include <vector>

namespace hexcut::output {

/// Owning hid_t (file, group, dataset, dataspace, datatype, property list or attribute).
class H5Handle {
 public:
  using Closer = herr_t (*)(hid_t);
  H5Handle() = default;
  H5Handle(hid_t id, Closer closer) : id_(id), closer_(closer) {}
  H5Handle(const H5Handle&) = delete;
  H5Handle& operator=(const H5Handle&) = delete;
  H5Handle(H5Handle&& other) noexcept : id_(other.id_), closer_(other.closer_) {
    other.id_ = H5I_INVALID_HID;
  }
  H5Handle& operator=(H5Handle&& other) noexcept;
  ~H5Handle() { reset(); }

  hid_t get() const { return id_; }
  bool valid() const { return id_ >= 0; }
  /// Closes the handle; returns the closer's status (0 when nothing was open).
  herr_t reset() noexcept;

 private:
  hid_t id_ = H5I_INVALID_HID;
  Closer closer_ = nullptr;
};

/// The MPI-IO collective buffer of every file H5File opens from now on [bytes] (the
/// "cb_buffer_size" hint, honoured by Open MPI's OMPIO and by ROMIO); 0 leaves it to the MPI
/// library (OMPIO: 32 MiB per aggregator, held while the file is open, so it is part of an
/// aggregator rank's peak memory; doc/benchmarks.md, "Memory per rank"). Process-wide, like
/// ROMIO_HINTS: the job sets it once from -hexcut_io_buffer before the first file opens.
void set_collective_buffer(std::int64_t bytes);

/// An HDF5 file opened with the MPI-IO driver on a communicator.
class H5File {
 public:
  enum class Access { kReadOnly, kReadWrite };

  /// Creates (truncates) `path`. Collective.
  static H5File create(const std::string& path, MPI_Comm comm);
  /// Opens an existing file. Collective.
  static H5File open(const std::string& path, MPI_Comm comm, Access access = Access::kReadWrite);

  H5File() = default;
  H5File(H5File&&) noexcept = default;
  H5File& operator=(H5File&&) noexcept;
  ~H5File();  // closes without throwing; prefer close() to see errors

  bool is_open() const { return file_.valid(); }
  const std::string& filename() const { return filename_; }
  MPI_Comm comm() const { return comm_; }
  int rank() const { return rank_; }
  hid_t id() const { return file_.get(); }

  /// Flushes all buffers to the file (H5Fflush, global scope). Collective.
  void flush();
  /// Closes the file. Collective. No-op when not open.
  void close();

  /// Writes this rank's rows [row_offset, row_offset+local_rows) of a global table of
  /// global_rows x cols (row-major, `data` holds local_rows*cols values; cols == 0 stores a
  /// 1-D dataset of global_rows values and `data` holds local_rows values). Creates the
  /// dataset and missing intermediate groups. An existing dataset with the same shape and
  /// stored type is overwritten in place; one with another shape or type is unlinked and
  /// re-created. Collective; local_rows may be 0 (data may then be null); global_rows may
  /// be 0 (an empty table: the dataset is created, nothing is written).
  /// T is one of double, float, std::int32_t, std::int64_t, std::uint8_t.
  template <class T>
  void write_rows(const std::string& path, std::int64_t global_rows, std::int64_t cols,
                  std::int64_t row_offset, std::int64_t local_rows, const T* data);

  /// Reads rows [row_offset, row_offset+local_rows) into `data` (converting the stored type
  /// to T). Throws when the dataset's shape is not global_rows x cols (cols == 0: 1-D).
  template <class T>
  void read_rows(const std::string& path, std::int64_t global_rows, std::int64_t cols,
                 std::int64_t row_offset, std::int64_t local_rows, T* data);

  /// Appends `n` values to the 1-D extendible (chunked) dataset `path`, creating it empty
  /// first when missing. All ranks must pass identical values; rank 0 writes them.
  template <class T>
  void append_1d(const std::string& path, const T* values, std::int64_t n);
  /// Shrinks or grows the 1-D extendible dataset `path` to `size` entries.
  void resize_1d(const std::string& path, std::int64_t size);

  /// Dataset dimensions (empty for a scalar dataset).
  std::vector<std::int64_t> dims(const std::string& path);
  /// Stored element class and size of a dataset, e.g. {"float", 8}, {"int", 4},
  /// {"uint", 1}, {"string", n}.
  std::pair<std::string, int> element_type(const std::string& path);

  /// Attributes on a group or dataset (`object_path`, "/" for the root group). Replaces an
  /// existing attribute of the same name. Strings are fixed-length, UTF-8, null-padded.
  void write_attribute(const std::string& object_path, const std::string& name, double value);
  void write_attribute(const std::string& object_path, const std::string& name, std::int64_t value);
  void write_attribute(const std::string& object_path, const std::string& name, int value) {
    write_attribute(object_path, name, static_cast<std::int64_t>(value));
  }
  void write_attribute(const std::string& object_path, const std::string& name,
                       const std::string& value);
  void write_attribute(const std::string& object_path, const std::string& name, const char* value) {
    write_attribute(object_path, name, std::string(value));
  }
  void write_attribute(const std::string& object_path, const std::string& name,
                       const std::vector<double>& values);
  void write_attribute(const std::string& object_path, const std::string& name,
                       const std::vector<std::int64_t>& values);

  bool has_attribute(const std::string& object_path, const std::string& name);
  double read_attribute_double(const std::string& object_path, const std::string& name);
  std::int64_t read_attribute_int64(const std::string& object_path, const std::string& name);
  std::string read_attribute_string(const std::string& object_path, const std::string& name);
  std::vector<double> read_attribute_doubles(const std::string& object_path,
                                             const std::string& name);
  std::vector<std::int64_t> read_attribute_int64s(const std::string& object_path,
                                                  const std::string& name);

  /// Scalar fixed-length UTF-8 string dataset holding `text` verbatim (replaced if present).
  void write_string_dataset(const std::string& path, const std::string& text);
  std::string read_string_dataset(const std::string& path);

  /// Creates the group and missing intermediate groups; no-op when it exists.
  void create_group(const std::string& path);
  /// True when every component of `path` exists ("/" always exists).
  bool exists(const std::string& path);
  /// True when `path` exists and is a group.
  bool is_group(const std::string& path);
  /// Removes the link `path` (a group's whole subtree). The space is not reclaimed in the
  /// file (HDF5 limitation; h5repack compacts). Throws when `path` does not exist.
  void delete_link(const std::string& path);
  /// Names of the links in group `path`, in increasing name order.
  std::vector<std::string> list(const std::string& path);

 private:
  H5File(H5Handle file, std::string filename, MPI_Comm comm);
  [[noreturn]] void fail(const std::string& operation, const std::string& path) const;
  hid_t check(hid_t id, const char* operation, const std::string& path) const;
  void check_status(herr_t status, const char* operation, const std::string& path) const;
  H5Handle open_object(const std::string& path);
  H5Handle open_dataset(const std::string& path);
  H5Handle collective_xfer() const;
  void write_attribute_raw(const std::string& object_path, const std::string& name, hid_t file_type,
                           hid_t mem_type, const std::vector<hsize_t>& shape, const void* data);
  template <class T>
  std::vector<T> read_attribute_vector(const std::string& object_path, const std::string& name);

  H5Handle file_;
  std::string filename_;
  MPI_Comm comm_ = MPI_COMM_NULL;
  int rank_ = 0;
};

}  // namespace hexcut::output
