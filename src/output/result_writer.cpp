#include "output/result_writer.hpp"

#include <fcntl.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <limits>
#include <sstream>
#include <stdexcept>
#include <vector>

#include "hexcut_version.hpp"

namespace hexcut::output {
namespace {

constexpr const char* kFormatName = "hexcut-result";
constexpr std::int64_t kFormatVersion = 2;
// The surface index is "<stem>_surface.xmf" beside the volume index "<stem>.xmf".
constexpr const char* kSurfaceStemSuffix = "_surface";

const char* const kHistoryColumns[] = {
    "step",          "time",          "iterations",      "residual_norm", "relative_residual",
    "setup_seconds", "solve_seconds", "converged_reason"};

/// Runs `f` on rank 0 only and re-throws its error (if any) on every rank.
template <class F>
void on_rank0(MPI_Comm comm, F&& f) {
  int rank = 0;
  MPI_Comm_rank(comm, &rank);
  std::string error;
  if (rank == 0) {
    try {
      f();
    } catch (const std::exception& e) {
      error = e.what();
      if (error.empty()) error = "unknown error";
    }
  }
  int length = static_cast<int>(error.size());
  MPI_Bcast(&length, 1, MPI_INT, 0, comm);
  if (length > 0) {
    error.resize(static_cast<std::size_t>(length));
    MPI_Bcast(error.data(), length, MPI_CHAR, 0, comm);
    throw std::runtime_error(error);
  }
}

std::string system_error(const std::string& what, const std::string& path) {
  return what + " '" + path + "' failed: " + std::strerror(errno);
}

void fsync_path(const std::string& path) {
  int fd = ::open(path.c_str(), O_RDONLY);
  if (fd < 0) throw std::runtime_error(system_error("open for fsync", path));
  int status = ::fsync(fd);
  ::close(fd);
  if (status != 0) throw std::runtime_error(system_error("fsync", path));
}

std::string dirname_of(const std::string& path) {
  auto pos = path.find_last_of('/');
  if (pos == std::string::npos) return ".";
  if (pos == 0) return "/";
  return path.substr(0, pos);
}

std::string basename_of(const std::string& path) {
  auto pos = path.find_last_of('/');
  return pos == std::string::npos ? path : path.substr(pos + 1);
}

/// rename(2) `from` onto `to`, then fsync the directory so the rename is durable.
void atomic_rename(const std::string& from, const std::string& to) {
  if (std::rename(from.c_str(), to.c_str()) != 0)
    throw std::runtime_error(system_error("rename '" + from + "' to", to));
  int fd = ::open(dirname_of(to).c_str(), O_RDONLY | O_DIRECTORY);
  if (fd >= 0) {
    ::fsync(fd);  // best effort: some file systems refuse fsync on directories
    ::close(fd);
  }
}

/// Why `text` cannot be written into an XML 1.0 document as character data ("" when it
/// can): it must be valid UTF-8 (no overlong forms, surrogates or code points past
/// U+10FFFF) without C0 control characters or DEL. Tab, line feed and carriage return
/// are legal XML but are refused too: readers trim or normalize them.
std::string xml_text_problem(const std::string& text) {
  const auto* s = reinterpret_cast<const unsigned char*>(text.data());
  const std::size_t n = text.size();
  for (std::size_t i = 0; i < n;) {
    const unsigned char c = s[i];
    if (c < 0x20 || c == 0x7f) return "a control character (byte " + std::to_string(c) + ")";
    if (c < 0x80) {
      ++i;
      continue;
    }
    int len = 0;
    std::uint32_t cp = 0, min = 0;
    if ((c & 0xe0) == 0xc0) {
      len = 2, cp = c & 0x1f, min = 0x80;
    } else if ((c & 0xf0) == 0xe0) {
      len = 3, cp = c & 0x0f, min = 0x800;
    } else if ((c & 0xf8) == 0xf0) {
      len = 4, cp = c & 0x07, min = 0x10000;
    } else {
      return "bytes that are not UTF-8";
    }
    if (i + len > n) return "bytes that are not UTF-8";
    for (int k = 1; k < len; ++k) {
      if ((s[i + k] & 0xc0) != 0x80) return "bytes that are not UTF-8";
      cp = (cp << 6) | (s[i + k] & 0x3f);
    }
    if (cp < min || cp > 0x10ffff || (cp >= 0xd800 && cp <= 0xdfff))
      return "bytes that are not UTF-8";
    i += len;
  }
  return "";
}

/// Why a dataset path cannot be referenced from an index ("" when it can): besides the
/// XML rules, ':' separates the file from the dataset in a DataItem.
std::string dataset_path_problem(const std::string& path) {
  if (path.find(':') != std::string::npos) return "a ':'";
  return xml_text_problem(path);
}

void validate_name(const std::string& name) {
  if (name.empty() || name.find('/') != std::string::npos || name == "." || name == "..")
    throw std::invalid_argument("output: bad field name '" + name + "'");
  // The XDMF index names the attribute and refers to the dataset by its path.
  const std::string problem = dataset_path_problem(name);
  if (!problem.empty())
    throw std::invalid_argument("output: field name '" + name + "' contains " + problem +
                                ", which the XDMF index cannot carry");
}

void require(bool condition, const std::string& message) {
  if (!condition) throw std::invalid_argument("output: " + message);
}

/// Throws on every rank when `condition` is false on any rank (keeps ranks in step).
void require_all(MPI_Comm comm, bool condition, const std::string& message) {
  int ok = condition ? 1 : 0, all = 0;
  MPI_Allreduce(&ok, &all, 1, MPI_INT, MPI_MIN, comm);
  require(all == 1, message + " (on some rank)");
}

/// True on every rank when `flag` is true on any rank.
bool any_rank(MPI_Comm comm, bool flag) {
  int mine = flag ? 1 : 0, any = 0;
  MPI_Allreduce(&mine, &any, 1, MPI_INT, MPI_MAX, comm);
  return any == 1;
}

/// Throws on every rank when `value` is not the same on all ranks (a global size that the
/// ranks disagree on would make the collective writes diverge).
void require_same(MPI_Comm comm, std::int64_t value, const std::string& message) {
  std::int64_t mine[2] = {value, -value}, max[2] = {0, 0};
  MPI_Allreduce(mine, max, 2, MPI_INT64_T, MPI_MAX, comm);
  require(max[0] == -max[1], message + " differs between ranks");
}

bool valid_slab(const Slab& s) {
  return s.row_offset >= 0 && s.local_rows >= 0 && s.row_offset + s.local_rows <= s.global_rows;
}

/// Throws on every rank unless the ranks' slabs are valid and their rows add up to the
/// table (a caller still using the previous mesh's slabs after a topology change would
/// otherwise leave rows unwritten without an error).
void require_cover(MPI_Comm comm, const Slab& slab, const std::string& what) {
  require_all(comm, valid_slab(slab),
              what + ": bad slab [" + std::to_string(slab.row_offset) + ", +" +
                  std::to_string(slab.local_rows) + ") of " + std::to_string(slab.global_rows) +
                  " rows");
  std::int64_t covered = 0;
  MPI_Allreduce(&slab.local_rows, &covered, 1, MPI_INT64_T, MPI_SUM, comm);
  require(covered == slab.global_rows, what + ": the ranks' slabs hold " + std::to_string(covered) +
                                           " rows, the table has " +
                                           std::to_string(slab.global_rows));
}

/// True when every value of `data[0, n)` lies in [lo, hi).
template <class T>
bool all_in_range(const T* data, std::int64_t n, std::int64_t lo, std::int64_t hi) {
  for (std::int64_t i = 0; i < n; ++i)
    if (data[i] < lo || data[i] >= hi) return false;
  return true;
}

/// The argument checks shared by ResultWriter::create and write_mesh (agreed on by all
/// ranks, so every rank throws or none).
void check_mesh(MPI_Comm comm, const MeshData& mesh) {
  const Slab& p = mesh.points;
  const Slab& c = mesh.cells;
  require_same(comm, p.global_rows, "the mesh's point count");
  require_same(comm, c.global_rows, "the mesh's cell count");
  require_cover(comm, p, "mesh points");
  require_cover(comm, c, "mesh cells");
  require_all(comm, p.local_rows == 0 || mesh.positions != nullptr, "mesh positions missing");
  require_all(comm,
              c.local_rows == 0 ||
                  (mesh.connectivity && mesh.lattice_index && mesh.material && mesh.youngs_modulus),
              "mesh cell tables missing");
}

/// Writes the datasets and attributes of a mesh group (/mesh or a step's mesh).
void write_mesh_group(H5File& f, const std::string& base, const MeshData& mesh) {
  const Slab& p = mesh.points;
  const Slab& c = mesh.cells;
  f.write_rows(base + "/points", p.global_rows, 3, p.row_offset, p.local_rows, mesh.positions);
  f.write_rows(base + "/cells", c.global_rows, 8, c.row_offset, c.local_rows, mesh.connectivity);
  f.write_rows(base + "/cell_lattice_index", c.global_rows, 3, c.row_offset, c.local_rows,
               mesh.lattice_index);
  f.write_rows(base + "/cell_material", c.global_rows, 0, c.row_offset, c.local_rows,
               mesh.material);
  f.write_rows(base + "/cell_youngs_modulus", c.global_rows, 0, c.row_offset, c.local_rows,
               mesh.youngs_modulus);
  f.write_attribute(base + "/points", "unit", "m");
  f.write_attribute(base + "/cell_youngs_modulus", "unit", "Pa");
  const LatticeSpec& l = mesh.lattice;
  f.write_attribute(base, "lattice_origin",
                    std::vector<double>{l.origin.x(), l.origin.y(), l.origin.z()});
  f.write_attribute(base, "lattice_h", l.h);
  f.write_attribute(base, "lattice_dims",
                    std::vector<std::int64_t>{l.dims[0], l.dims[1], l.dims[2]});
  f.write_attribute(base, "num_points", p.global_rows);
  f.write_attribute(base, "num_cells", c.global_rows);
}

std::string xml_escape(const std::string& text) {
  std::string out;
  for (char c : text) {
    switch (c) {
      case '&':
        out += "&amp;";
        break;
      case '<':
        out += "&lt;";
        break;
      case '>':
        out += "&gt;";
        break;
      case '"':
        out += "&quot;";
        break;
      case '\'':
        out += "&apos;";
        break;
      default:
        out += c;
    }
  }
  return out;
}

std::string format_double(double value) {
  char buffer[40];
  std::snprintf(buffer, sizeof buffer, "%.17g", value);
  return buffer;
}

bool all_digits(const std::string& s) {
  return !s.empty() && std::all_of(s.begin(), s.end(), [](char c) { return c >= '0' && c <= '9'; });
}

bool is_complete(H5File& f, const std::string& group) {
  return f.has_attribute(group, "complete") && f.read_attribute_int64(group, "complete") == 1;
}

/// The mesh group a step group uses (its `mesh` attribute; "/mesh" when absent).
std::string mesh_of(H5File& f, const std::string& group) {
  return f.has_attribute(group, "mesh") ? f.read_attribute_string(group, "mesh")
                                        : std::string("/mesh");
}

/// The mesh of the highest-numbered complete step group other than `except` ("/mesh" when
/// there is none): the mesh a (re)started run continues with. Scans the groups instead of
/// trusting /steps@last_complete_step, which can name a step that is being rewritten.
std::string mesh_of_last_complete_step(H5File& f, const std::string& except = "") {
  if (!f.is_group("/steps")) return "/mesh";
  std::vector<std::string> names = f.list("/steps");  // increasing = numerical order
  for (auto it = names.rbegin(); it != names.rend(); ++it) {
    const std::string group = "/steps/" + *it;
    if (!all_digits(*it) || group == except || !f.is_group(group)) continue;
    if (is_complete(f, group)) return mesh_of(f, group);
  }
  return "/mesh";
}

}  // namespace

std::string step_group(std::int64_t step) {
  if (step < 0 || step > 999999) throw std::invalid_argument("output: step out of range");
  char buffer[32];
  std::snprintf(buffer, sizeof buffer, "/steps/%06lld", static_cast<long long>(step));
  return buffer;
}

std::string xdmf_path_for(const std::string& h5_path) {
  const std::string ext = ".h5";
  if (h5_path.size() > ext.size() &&
      h5_path.compare(h5_path.size() - ext.size(), ext.size(), ext) == 0)
    return h5_path.substr(0, h5_path.size() - ext.size()) + ".xmf";
  return h5_path + ".xmf";
}

std::string surface_xdmf_path_for(const std::string& h5_path) {
  const std::string volume = xdmf_path_for(h5_path);
  return volume.substr(0, volume.size() - 4) + kSurfaceStemSuffix + ".xmf";
}

std::vector<std::string> index_paths(const std::string& h5_path) {
  return {xdmf_path_for(h5_path), surface_xdmf_path_for(h5_path)};
}

// ------------------------------------------------------------------------------- XDMF
namespace {

/// The file part of a DataItem: the result file's basename, XML-escaped. ParaView 5.11's
/// "XDMF Reader" (Xdmf2) drops a leading non-ASCII character of a relative file name
/// ("été.h5" opens "té.h5"); "./" in front keeps it (all three readers resolve it
/// relative to the index).
std::string file_reference(const std::string& h5_basename) {
  const bool ascii_first = static_cast<unsigned char>(h5_basename.at(0)) < 0x80;
  return (ascii_first ? "" : "./") + xml_escape(h5_basename);
}

struct XdmfContext {
  H5File& file;
  std::string h5_ref;  // file part of every DataItem (file_reference)
  std::ostringstream& out;
};

/// A <DataItem> for dataset `path`, with dimensions and number type read from the file.
void data_item(XdmfContext& x, const std::string& path, const std::string& indent) {
  std::vector<std::int64_t> d = x.file.dims(path);
  auto [cls, size] = x.file.element_type(path);
  std::string number_type = cls == "float" ? "Float" : (cls == "uint" ? "UInt" : "Int");
  if (cls == "uint" && size == 1) number_type = "UChar";
  std::string dims;
  for (std::size_t i = 0; i < d.size(); ++i) dims += (i ? " " : "") + std::to_string(d[i]);
  x.out << indent << "<DataItem Dimensions=\"" << dims << "\" NumberType=\"" << number_type
        << "\" Precision=\"" << size << "\" Format=\"HDF\">" << x.h5_ref << ":" << xml_escape(path)
        << "</DataItem>\n";
}

/// The XDMF AttributeType of a (rows,) or (rows, cols) table. Checked with ParaView 5.11
/// (doc/output-format.md, "The XDMF indexes"): the Xdmf2 reader expands `Tensor6` to 9
/// components assuming XDMF's order xx, xy, xz, yy, yz, zz, the Xdmf3 readers pass its 6
/// components through unchanged (VTK reads them as xx, yy, zz, xy, yz, xz), so no order
/// of a `Tensor6` is right in every reader. `Matrix` is passed through unchanged by all
/// three, so a 6-column table (hexcut's stress, in VTK's order) is written as `Matrix`.
const char* attribute_type(const std::vector<std::int64_t>& d) {
  if (d.size() == 1 || (d.size() == 2 && d[1] == 1)) return "Scalar";
  if (d.size() == 2 && d[1] == 3) return "Vector";
  if (d.size() == 2 && d[1] == 9) return "Tensor";
  return "Matrix";
}

void attribute(XdmfContext& x, const std::string& name, const std::string& path,
               const std::string& center) {
  std::vector<std::int64_t> d = x.file.dims(path);
  x.out << "        <Attribute Name=\"" << xml_escape(name) << "\" AttributeType=\""
        << attribute_type(d) << "\" Center=\"" << center << "\">\n";
  data_item(x, path, "          ");
  x.out << "        </Attribute>\n";
}

const char* const kIndexHeader =
    "<?xml version=\"1.0\" encoding=\"utf-8\"?>\n"
    "<!DOCTYPE Xdmf SYSTEM \"Xdmf.dtd\" []>\n"
    "<Xdmf xmlns:xi=\"http://www.w3.org/2001/XInclude\" Version=\"3.0\">\n"
    "  <Domain>\n";
const char* const kIndexFooter = "    </Grid>\n  </Domain>\n</Xdmf>\n";

/// The complete step groups of the file, in step order.
std::vector<std::string> complete_steps(H5File& file) {
  std::vector<std::string> steps;
  if (!file.is_group("/steps")) return steps;
  for (const std::string& name : file.list("/steps")) {
    const std::string group = "/steps/" + name;
    if (all_digits(name) && file.is_group(group) && is_complete(file, group))
      steps.push_back(group);
  }
  return steps;
}

/// The volume index: one Uniform grid per complete step.
std::string volume_index(XdmfContext& x, const std::vector<std::string>& steps) {
  H5File& file = x.file;
  auto& out = x.out;
  out.str("");
  out << kIndexHeader
      << "    <Grid Name=\"hexcut\" GridType=\"Collection\" CollectionType=\"Temporal\">\n";
  for (const std::string& group : steps) {
    const std::string mesh = mesh_of(file, group);
    if (!dataset_path_problem(mesh).empty())
      throw std::runtime_error("output: the mesh name of " + group + " cannot be indexed");
    const std::int64_t num_points = file.dims(mesh + "/points").at(0);
    const std::int64_t num_cells = file.dims(mesh + "/cells").at(0);
    out << "      <Grid Name=\"step_" << basename_of(group) << "\" GridType=\"Uniform\">\n"
        << "        <Time Value=\"" << format_double(file.read_attribute_double(group, "time"))
        << "\"/>\n"
        << "        <Topology TopologyType=\"Hexahedron\" NumberOfElements=\"" << num_cells
        << "\">\n";
    data_item(x, mesh + "/cells", "          ");
    out << "        </Topology>\n"
        << "        <Geometry GeometryType=\"XYZ\">\n";
    data_item(x, mesh + "/points", "          ");
    out << "        </Geometry>\n";
    for (const char* cell_table : {"cell_material", "cell_youngs_modulus"}) {
      if (file.exists(mesh + "/" + cell_table))
        attribute(x, cell_table, mesh + "/" + cell_table, "Cell");
    }
    for (const std::string& field : file.list(group)) {
      const std::string path = group + "/" + field;
      // A name the index cannot carry (the writer refuses them; another program may have
      // added one) and tables that do not fit the grid are left out: the index must
      // stay readable.
      if (file.is_group(path) || !dataset_path_problem(path).empty()) continue;
      auto cls = file.element_type(path).first;
      if (cls != "float" && cls != "int" && cls != "uint") continue;
      const std::vector<std::int64_t> d = file.dims(path);
      if (d.empty() || d.size() > 2) continue;
      std::string centering = file.has_attribute(path, "centering")
                                  ? file.read_attribute_string(path, "centering")
                                  : std::string();
      if (centering.empty())
        centering = d[0] == num_points ? "point" : (d[0] == num_cells ? "cell" : "");
      if (centering == "point" && d[0] == num_points) attribute(x, field, path, "Node");
      if (centering == "cell" && d[0] == num_cells) attribute(x, field, path, "Cell");
    }
    out << "      </Grid>\n";
  }
  out << kIndexFooter;
  return out.str();
}

/// The surface index: one Uniform grid per complete step with a non-empty surface; ""
/// when there is none.
std::string surface_index(XdmfContext& x, const std::vector<std::string>& steps) {
  H5File& file = x.file;
  auto& out = x.out;
  out.str("");
  out << kIndexHeader
      << "    <Grid Name=\"hexcut_surface\" GridType=\"Collection\" "
         "CollectionType=\"Temporal\">\n";
  bool any = false;
  for (const std::string& group : steps) {
    const std::string base = group + "/surface";
    if (!file.exists(base + "/triangles") || file.dims(base + "/triangles").at(0) == 0) continue;
    any = true;
    out << "      <Grid Name=\"surface_" << basename_of(group) << "\" GridType=\"Uniform\">\n"
        << "        <Time Value=\"" << format_double(file.read_attribute_double(group, "time"))
        << "\"/>\n"
        << "        <Topology TopologyType=\"Triangle\" NumberOfElements=\""
        << file.dims(base + "/triangles").at(0) << "\">\n";
    data_item(x, base + "/triangles", "          ");
    out << "        </Topology>\n"
        << "        <Geometry GeometryType=\"XYZ\">\n";
    data_item(x, base + "/points", "          ");
    out << "        </Geometry>\n";
    attribute(x, "cut_id", base + "/cut_id", "Cell");
    attribute(x, "owner_cell", base + "/owner_cell", "Node");
    out << "      </Grid>\n";
  }
  out << kIndexFooter;
  return any ? out.str() : std::string();
}

/// Writes `text` to `path` atomically: "<path>.tmp", fsync, rename.
void write_file_atomically(const std::string& path, const std::string& text) {
  const std::string tmp = path + ".tmp";
  std::FILE* f = std::fopen(tmp.c_str(), "wb");
  if (f == nullptr) throw std::runtime_error(system_error("open", tmp));
  bool ok = std::fwrite(text.data(), 1, text.size(), f) == text.size();
  ok = std::fflush(f) == 0 && ok;
  ok = ::fsync(::fileno(f)) == 0 && ok;
  ok = std::fclose(f) == 0 && ok;
  if (!ok) throw std::runtime_error(system_error("write", tmp));
  atomic_rename(tmp, path);
}

}  // namespace

void check_result_path(const std::string& h5_path) {
  const std::string name = basename_of(h5_path);
  auto refuse = [&](const std::string& why) {
    throw std::invalid_argument("output: the result file name '" + name + "' " + why);
  };
  if (name.empty() || name == "." || name == "..") refuse("is empty");
  const std::string problem = xml_text_problem(name);
  if (!problem.empty())
    refuse("contains " + problem + ", which the XDMF index cannot refer to (use UTF-8 text)");
  if (name.find(':') != std::string::npos)
    refuse("contains ':', which separates the file from the dataset in the XDMF index");
  if (name.front() == ' ' || name.back() == ' ')
    refuse("starts or ends with a space, which XDMF readers strip from the file name");
  // "x_surface.h5" would write the index "x_surface.xmf", the surface index of "x.h5".
  const std::string volume = basename_of(xdmf_path_for(h5_path));
  const std::string stem = volume.substr(0, volume.size() - 4);
  const std::string suffix = kSurfaceStemSuffix;
  if (stem.size() >= suffix.size() &&
      stem.compare(stem.size() - suffix.size(), suffix.size(), suffix) == 0)
    refuse("ends in '" + suffix + "': its index '" + volume + "' is the surface index of '" +
           stem.substr(0, stem.size() - suffix.size()) + "'");
}

void write_xdmf(const std::string& h5_path, const std::string& xmf_path) {
  check_result_path(h5_path);
  H5File file = H5File::open(h5_path, MPI_COMM_SELF, H5File::Access::kReadOnly);
  std::ostringstream out;
  XdmfContext x{file, file_reference(basename_of(h5_path)), out};
  const std::string text = volume_index(x, complete_steps(file));
  file.close();
  write_file_atomically(xmf_path, text);
}

void write_indexes(const std::string& h5_path) {
  check_result_path(h5_path);
  H5File file = H5File::open(h5_path, MPI_COMM_SELF, H5File::Access::kReadOnly);
  std::ostringstream out;
  XdmfContext x{file, file_reference(basename_of(h5_path)), out};
  const std::vector<std::string> steps = complete_steps(file);
  const std::string volume = volume_index(x, steps);
  const std::string surface = surface_index(x, steps);
  file.close();
  write_file_atomically(xdmf_path_for(h5_path), volume);
  const std::string surface_path = surface_xdmf_path_for(h5_path);
  if (!surface.empty()) {
    write_file_atomically(surface_path, surface);
  } else if (std::remove(surface_path.c_str()) != 0 && errno != ENOENT) {
    // A surface index of an earlier run of that name would refer to datasets this file
    // does not have.
    throw std::runtime_error(system_error("remove", surface_path));
  }
}

// ------------------------------------------------------------------------ ResultWriter
ResultWriter ResultWriter::create(const std::string& path, MPI_Comm comm, const MeshData& mesh,
                                  const RunInfo& run) {
  check_result_path(path);  // the same path on every rank: all throw or none
  check_mesh(comm, mesh);
  ResultWriter writer(path, comm);
  writer.num_points_ = mesh.points.global_rows;
  writer.num_cells_ = mesh.cells.global_rows;
  const std::string tmp = path + ".tmp";
  {
    H5File f = H5File::create(tmp, comm);
    f.write_attribute("/", "format", kFormatName);
    f.write_attribute("/", "format_version", kFormatVersion);
    write_mesh_group(f, "/mesh", mesh);

    f.write_string_dataset("/input/deck", run.deck);
    f.write_string_dataset("/input/command_line", run.command_line);
    unsigned major = 0, minor = 0, release = 0;
    H5get_libversion(&major, &minor, &release);
    f.write_attribute("/input", "hexcut_version", HEXCUT_VERSION);
    f.write_attribute("/input", "hexcut_git_hash", HEXCUT_GIT_HASH);
    f.write_attribute("/input", "discretization", run.discretization);
    f.write_attribute("/input", "composite_level", run.composite_level);
    f.write_attribute(
        "/input", "hdf5_version",
        std::to_string(major) + "." + std::to_string(minor) + "." + std::to_string(release));
    f.create_group("/steps");
    f.write_attribute("/steps", "last_complete_step", std::int64_t{-1});
    f.close();
  }
  MPI_Barrier(comm);
  on_rank0(comm, [&] {
    fsync_path(tmp);
    atomic_rename(tmp, path);
    write_indexes(path);
  });
  return writer;
}

ResultWriter ResultWriter::open(const std::string& path, MPI_Comm comm) {
  ResultWriter writer(path, comm);
  H5File f = H5File::open(path, comm, H5File::Access::kReadOnly);
  if (!f.has_attribute("/", "format") || f.read_attribute_string("/", "format") != kFormatName)
    throw std::runtime_error("output: '" + path + "' is not a hexcut result file");
  const std::int64_t version = f.read_attribute_int64("/", "format_version");
  if (version != kFormatVersion)
    throw std::runtime_error("output: '" + path + "' has layout version " +
                             std::to_string(version) + "; this hexcut writes version " +
                             std::to_string(kFormatVersion) +
                             " and cannot continue it (doc/output-format.md)");
  check_result_path(path);
  writer.last_complete_step_ = f.read_attribute_int64("/steps", "last_complete_step");
  writer.use_mesh(f, mesh_of_last_complete_step(f));
  f.close();
  return writer;
}

ResultWriter::~ResultWriter() {
  // Leaves an open step incomplete (it is not listed in the XDMF); H5Fclose is collective,
  // so this only ends cleanly when every rank destroys the writer.
  if (file_.is_open()) {
    try {
      file_.close();
    } catch (...) {
    }
  }
}

void ResultWriter::use_mesh(H5File& f, const std::string& mesh) {
  if (!f.exists(mesh + "/points") || !f.exists(mesh + "/cells"))
    throw std::runtime_error("output: mesh '" + mesh + "' named by a step of '" + path_ +
                             "' does not exist");
  num_points_ = f.dims(mesh + "/points").at(0);
  num_cells_ = f.dims(mesh + "/cells").at(0);
  mesh_path_ = mesh;
}

void ResultWriter::require_open_step(std::int64_t step, const std::string& what) const {
  if (!step_open_ || step != open_step_)
    throw std::logic_error("output: " + what + " written for step " + std::to_string(step) +
                           ", which is not the open step");
}

void ResultWriter::open_file() {
  if (!file_.is_open()) file_ = H5File::open(path_, comm_, H5File::Access::kReadWrite);
}

void ResultWriter::close_file() {
  file_.close();
  MPI_Barrier(comm_);
}

void ResultWriter::begin_step(std::int64_t step, double time) {
  if (step_open_)
    throw std::logic_error("output: begin_step(" + std::to_string(step) + ") while step " +
                           std::to_string(open_step_) + " is open");
  const std::string group = step_group(step);
  open_file();
  if (file_.exists(group)) {
    const std::string owned = group + "/mesh";
    if (file_.is_group(owned)) {
      // Deleting the group deletes its mesh: no other complete step may use it.
      for (const std::string& name : file_.list("/steps")) {
        const std::string other = "/steps/" + name;
        if (other == group || !all_digits(name) || !file_.is_group(other)) continue;
        if (is_complete(file_, other) && mesh_of(file_, other) == owned) {
          close_file();
          throw std::logic_error("output: begin_step(" + std::to_string(step) +
                                 ") would delete the mesh " + owned + " that step " + name +
                                 " uses (truncate_steps_after first)");
        }
      }
      if (mesh_path_ == owned) use_mesh(file_, mesh_of_last_complete_step(file_, group));
    }
    file_.delete_link(group);
  }
  file_.create_group(group);
  file_.write_attribute(group, "step", step);
  file_.write_attribute(group, "time", time);
  file_.write_attribute(group, "complete", std::int64_t{0});
  file_.write_attribute(group, "mesh", mesh_path_);
  step_open_ = true;
  step_has_fields_ = false;
  open_step_ = step;
}

void ResultWriter::write_field(std::int64_t step, const std::string& name, const char* centering,
                               std::int64_t global_rows, int cols, std::int64_t row_offset,
                               std::int64_t local_rows, const double* data,
                               const std::string& unit) {
  require_open_step(step, "field '" + name + "'");
  validate_name(name);
  require(cols >= 1, "field '" + name + "' needs cols >= 1");
  // "mesh" and "surface" are the step's subgroups, not fields.
  require(name != "mesh" && name != "surface", "'" + name + "' is reserved, not a field name");
  require_cover(comm_, Slab{global_rows, row_offset, local_rows},
                std::string(centering) + " field '" + name + "' (mesh " + mesh_path_ + ")");
  step_has_fields_ = true;
  const std::string path = step_group(step) + "/" + name;
  file_.write_rows(path, global_rows, cols == 1 ? 0 : cols, row_offset, local_rows, data);
  file_.write_attribute(path, "centering", centering);
  if (!unit.empty()) file_.write_attribute(path, "unit", unit);
}

void ResultWriter::write_step_table(std::int64_t step, const std::string& name, std::int64_t rows,
                                    int cols, const std::vector<double>& data,
                                    const std::string& columns,
                                    const std::vector<std::string>& row_names) {
  require_open_step(step, "table '" + name + "'");
  validate_name(name);
  require(cols >= 1 && rows >= 0 && data.size() == std::size_t(rows) * std::size_t(cols) &&
              row_names.size() == std::size_t(rows),
          "table '" + name + "': data or row names do not match rows x cols");
  require(name != "mesh" && name != "surface", "'" + name + "' is reserved, not a table name");
  int rank = 0;
  MPI_Comm_rank(comm_, &rank);
  const std::string path = step_group(step) + "/" + name;
  file_.write_rows(path, rows, cols, 0, rank == 0 ? rows : 0, data.data());
  file_.write_attribute(path, "centering", "none");
  file_.write_attribute(path, "columns", columns);
  std::string joined;
  for (std::size_t r = 0; r < row_names.size(); ++r) joined += (r ? "\n" : "") + row_names[r];
  file_.write_attribute(path, "rows", joined);
}

void ResultWriter::write_point_field(std::int64_t step, const std::string& name, int cols,
                                     std::int64_t row_offset, std::int64_t local_rows,
                                     const double* data, const std::string& unit) {
  write_field(step, name, "point", num_points_, cols, row_offset, local_rows, data, unit);
}

void ResultWriter::write_cell_field(std::int64_t step, const std::string& name, int cols,
                                    std::int64_t row_offset, std::int64_t local_rows,
                                    const double* data, const std::string& unit) {
  write_field(step, name, "cell", num_cells_, cols, row_offset, local_rows, data, unit);
}

void ResultWriter::write_mesh(std::int64_t step, const MeshData& mesh) {
  require_open_step(step, "mesh");
  if (step_has_fields_)
    throw std::logic_error("output: write_mesh for step " + std::to_string(step) +
                           " after a field of that step (the fields would not match the mesh)");
  check_mesh(comm_, mesh);
  // Stale indices into the previous (smaller) point table are the likely error after a
  // topology change; catch them here rather than in the viewer.
  require_all(
      comm_,
      mesh.cells.local_rows == 0 ||
          all_in_range(mesh.connectivity, 8 * mesh.cells.local_rows, 0, mesh.points.global_rows),
      "mesh connectivity refers to a point outside [0, n_points)");
  const std::string group = step_group(step);
  const std::string base = group + "/mesh";
  write_mesh_group(file_, base, mesh);
  file_.write_attribute(base, "step", step);
  file_.write_attribute(group, "mesh", base);
  mesh_path_ = base;
  num_points_ = mesh.points.global_rows;
  num_cells_ = mesh.cells.global_rows;
}

void ResultWriter::write_surface(std::int64_t step, const SurfaceData& s) {
  require_open_step(step, "surface");
  const Slab& v = s.vertices;
  const Slab& t = s.faces;
  require_same(comm_, v.global_rows, "the surface's vertex count");
  require_same(comm_, t.global_rows, "the surface's triangle count");
  require_cover(comm_, v, "surface vertices");
  require_cover(comm_, t, "surface triangles");
  require_all(comm_, v.local_rows == 0 || (s.positions && s.owner_cell),
              "surface vertex tables missing");
  require_all(comm_, t.local_rows == 0 || (s.triangles && s.cut_id),
              "surface triangle tables missing");
  require_all(comm_, v.local_rows == 0 || all_in_range(s.owner_cell, v.local_rows, 0, num_cells_),
              "surface owner_cell outside [0, n_cells) of the current mesh");
  require_all(comm_,
              t.local_rows == 0 || all_in_range(s.triangles, 3 * t.local_rows, 0, v.global_rows),
              "surface triangle refers to a vertex outside [0, n_vertices)");
  require_all(comm_,
              t.local_rows == 0 ||
                  all_in_range(s.cut_id, t.local_rows, 0, std::numeric_limits<std::int32_t>::max()),
              "surface cut_id < 0");
  const std::string base = step_group(step) + "/surface";
  file_.write_rows(base + "/points", v.global_rows, 3, v.row_offset, v.local_rows, s.positions);
  file_.write_rows(base + "/owner_cell", v.global_rows, 0, v.row_offset, v.local_rows,
                   s.owner_cell);
  file_.write_rows(base + "/triangles", t.global_rows, 3, t.row_offset, t.local_rows, s.triangles);
  file_.write_rows(base + "/cut_id", t.global_rows, 0, t.row_offset, t.local_rows, s.cut_id);
  file_.write_attribute(base + "/points", "unit", "m");
  file_.write_attribute(base, "num_points", v.global_rows);
  file_.write_attribute(base, "num_triangles", t.global_rows);
  file_.write_attribute(base, "mesh", mesh_path_);
}

void ResultWriter::end_step() {
  if (!step_open_) throw std::logic_error("output: end_step without begin_step");
  const std::string group = step_group(open_step_);
  file_.flush();  // the data reaches the file before the step is marked complete
  file_.write_attribute(group, "complete", std::int64_t{1});
  last_complete_step_ = std::max(last_complete_step_, open_step_);
  file_.write_attribute("/steps", "last_complete_step", last_complete_step_);
  file_.flush();
  step_open_ = false;
  step_has_fields_ = false;
  open_step_ = -1;
  close_file();
  rewrite_xdmf();
}

void ResultWriter::append_solve_open(const SolverHistoryRow& r) {
  file_.append_1d("/solver_history/step", &r.step, 1);
  file_.append_1d("/solver_history/time", &r.time, 1);
  file_.append_1d("/solver_history/iterations", &r.iterations, 1);
  file_.append_1d("/solver_history/residual_norm", &r.residual_norm, 1);
  file_.append_1d("/solver_history/relative_residual", &r.relative_residual, 1);
  file_.append_1d("/solver_history/setup_seconds", &r.setup_seconds, 1);
  file_.append_1d("/solver_history/solve_seconds", &r.solve_seconds, 1);
  file_.append_1d("/solver_history/converged_reason", &r.converged_reason, 1);
}

void ResultWriter::append_solve(const SolverHistoryRow& record) {
  if (step_open_) {
    append_solve_open(record);
    return;
  }
  open_file();
  append_solve_open(record);
  close_file();
}

void ResultWriter::write_checkpoint(std::int64_t step, double time, std::int64_t point_offset,
                                    std::int64_t local_points, const double* u, const double* v,
                                    const double* a, const Slab& links, int link_cols,
                                    const std::int32_t* link_data) {
  write_checkpoint(step, time, Slab{num_points_, point_offset, local_points}, u, v, a, links,
                   link_cols, link_data);
}

void ResultWriter::write_checkpoint(std::int64_t step, double time, const Slab& points,
                                    const double* u, const double* v, const double* a,
                                    const Slab& links, int link_cols,
                                    const std::int32_t* link_data) {
  require_same(comm_, points.global_rows, "the checkpoint's point count");
  require_cover(
      comm_, points,
      "checkpoint (current mesh " + mesh_path_ + ": " + std::to_string(num_points_) + " points)");
  const std::int64_t point_offset = points.row_offset, local_points = points.local_rows;
  const bool opened_here = !file_.is_open();
  open_file();
  std::int64_t current = file_.has_attribute("/checkpoint", "current_slot")
                             ? file_.read_attribute_int64("/checkpoint", "current_slot")
                             : -1;
  const std::int64_t slot = current == 0 ? 1 : 0;
  const std::string base = "/checkpoint/slot" + std::to_string(slot);
  // Invalidate the slot before overwriting it.
  file_.create_group(base);
  file_.write_attribute(base, "complete", std::int64_t{0});
  file_.write_rows(base + "/displacement", points.global_rows, 3, point_offset, local_points, u);
  file_.write_rows(base + "/velocity", points.global_rows, 3, point_offset, local_points, v);
  file_.write_rows(base + "/acceleration", points.global_rows, 3, point_offset, local_points, a);
  if (links.global_rows > 0) {
    file_.write_rows(base + "/topology/links", links.global_rows, link_cols, links.row_offset,
                     links.local_rows, link_data);
  } else if (file_.exists(base + "/topology/links")) {
    file_.delete_link(base + "/topology/links");
  }
  file_.write_attribute(base, "step", step);
  file_.write_attribute(base, "time", time);
  file_.flush();
  file_.write_attribute(base, "complete", std::int64_t{1});
  file_.flush();
  file_.write_attribute("/checkpoint", "current_slot", slot);
  file_.write_attribute("/checkpoint", "step", step);
  file_.write_attribute("/checkpoint", "time", time);
  if (opened_here) {
    close_file();
  } else {
    file_.flush();
  }
}

std::optional<CheckpointInfo> ResultWriter::checkpoint_info() {
  const bool opened_here = !file_.is_open();
  open_file();
  std::optional<CheckpointInfo> info;
  if (file_.has_attribute("/checkpoint", "current_slot")) {
    const std::string base = "/checkpoint/slot" + std::to_string(file_.read_attribute_int64(
                                                      "/checkpoint", "current_slot"));
    CheckpointInfo i;
    i.step = file_.read_attribute_int64(base, "step");
    i.time = file_.read_attribute_double(base, "time");
    i.num_points = file_.dims(base + "/displacement").at(0);
    if (file_.exists(base + "/topology/links")) {
      auto d = file_.dims(base + "/topology/links");
      i.link_rows = d.at(0);
      i.link_cols = d.size() > 1 ? d[1] : 0;
    }
    info = i;
  }
  if (opened_here) close_file();
  return info;
}

CheckpointInfo ResultWriter::read_checkpoint(std::int64_t point_offset, std::int64_t local_points,
                                             double* u, double* v, double* a,
                                             std::int64_t link_offset, std::int64_t local_link_rows,
                                             std::int32_t* link_data) {
  const bool opened_here = !file_.is_open();
  std::optional<CheckpointInfo> info = checkpoint_info();
  if (!info) throw std::runtime_error("output: '" + path_ + "' holds no checkpoint");
  open_file();
  const std::string base = "/checkpoint/slot" + std::to_string(file_.read_attribute_int64(
                                                    "/checkpoint", "current_slot"));
  file_.read_rows(base + "/displacement", info->num_points, 3, point_offset, local_points, u);
  file_.read_rows(base + "/velocity", info->num_points, 3, point_offset, local_points, v);
  file_.read_rows(base + "/acceleration", info->num_points, 3, point_offset, local_points, a);
  // The decision must be the same on every rank (the read is collective).
  if (any_rank(comm_, link_data != nullptr || local_link_rows > 0)) {
    if (info->link_rows == 0)
      throw std::runtime_error("output: checkpoint in '" + path_ + "' holds no topology/links");
    file_.read_rows(base + "/topology/links", info->link_rows, info->link_cols, link_offset,
                    local_link_rows, link_data);
  }
  if (opened_here) close_file();
  return *info;
}

void ResultWriter::truncate_steps_after(std::int64_t step) {
  if (step_open_) throw std::logic_error("output: truncate_steps_after inside an open step");
  open_file();
  std::int64_t last = -1;
  if (file_.is_group("/steps")) {
    for (const std::string& name : file_.list("/steps")) {
      if (!all_digits(name)) continue;
      const std::int64_t number = std::stoll(name);
      const std::string group = "/steps/" + name;
      if (number > step) {
        file_.delete_link(group);
      } else if (is_complete(file_, group)) {
        last = std::max(last, number);
      }
    }
  }
  file_.write_attribute("/steps", "last_complete_step", last);
  last_complete_step_ = last;
  // Steps after `step` are gone, and with them the meshes they introduced.
  use_mesh(file_, last >= 0 ? mesh_of(file_, step_group(last)) : std::string("/mesh"));
  if (file_.exists("/solver_history/step")) {
    const std::int64_t rows = file_.dims("/solver_history/step").at(0);
    std::vector<std::int64_t> steps(static_cast<std::size_t>(rows));
    file_.read_rows("/solver_history/step", rows, 0, 0, rows, steps.data());
    std::int64_t keep = 0;
    while (keep < rows && steps[static_cast<std::size_t>(keep)] <= step) ++keep;
    if (keep < rows) {
      for (const char* column : kHistoryColumns) {
        const std::string path = std::string("/solver_history/") + column;
        if (file_.exists(path)) file_.resize_1d(path, keep);
      }
    }
  }
  close_file();
  rewrite_xdmf();
}

void ResultWriter::rewrite_xdmf() {
  if (step_open_) throw std::logic_error("output: rewrite_xdmf inside an open step");
  MPI_Barrier(comm_);
  on_rank0(comm_, [&] { write_indexes(path_); });
}

}  // namespace hexcut::output
