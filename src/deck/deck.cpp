// YAML deck parser. Every value is checked for type and range where it is read, and
// every map is checked for unknown keys, so a typo never passes silently.
#include "deck/deck.hpp"

#include <yaml-cpp/yaml.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <limits>
#include <map>
#include <set>
#include <sstream>

#include "common/errors.hpp"
#include "deck/expression.hpp"
#include "geometry/triangle_mesh.hpp"
#include "geometry/voxel_image.hpp"

namespace hexcut::deck {
namespace {

namespace fs = std::filesystem;

/// Parsing context: the deck path (for messages) and its directory (relative paths
/// in the deck are relative to the deck file, not to the working directory).
struct Context {
  std::string file;
  fs::path dir;
  const std::vector<Material>* materials = nullptr;
  double h = 1.0;                                // lattice cell size, sets default tolerances
  std::vector<std::string>* warnings = nullptr;  // Deck::warnings
  bool composite = false;                        // discretization: composite (output fields)

  int line(const YAML::Node& n) const { return n.Mark().line >= 0 ? n.Mark().line + 1 : 0; }
  [[noreturn]] void fail(const YAML::Node& n, const std::string& msg) const {
    throw InputError(file, line(n), msg);
  }
  SourceLocation where(const YAML::Node& n) const { return {file, line(n)}; }
  void warn(const YAML::Node& n, const std::string& msg) const {
    if (warnings) warnings->push_back(where(n).prefix() + "warning: " + msg);
  }
  std::string resolve(const std::string& p) const {
    fs::path path(p);
    return path.is_absolute() ? path.string() : (dir / path).lexically_normal().string();
  }
};

/// Throws at the first map key that occurs twice anywhere under `n`: YAML says keys are
/// unique, but yaml-cpp keeps both and lookups silently return the first.
void check_unique_keys(const Context& c, const YAML::Node& n) {
  if (n.IsMap()) {
    std::map<std::string, int> seen;  // key -> line of its first occurrence
    for (const auto& kv : n) {
      if (kv.first.IsScalar()) {
        const auto [it, fresh] = seen.emplace(kv.first.Scalar(), c.line(kv.first));
        if (!fresh)
          c.fail(kv.first, "duplicate key '" + kv.first.Scalar() + "' (first given on line " +
                               std::to_string(it->second) + ")");
      }
      check_unique_keys(c, kv.second);
    }
  } else if (n.IsSequence()) {
    for (const auto& e : n) check_unique_keys(c, e);
  }
}

/// Line (1-based) and column of the first byte of `text` that is not part of a valid
/// UTF-8 sequence (overlong forms, surrogates and code points above U+10FFFF are
/// invalid too), or line 0 when the whole text is valid.
std::pair<int, int> first_invalid_utf8(const std::string& text) {
  int line = 1, column = 1;
  const auto* s = reinterpret_cast<const unsigned char*>(text.data());
  const std::size_t n = text.size();
  for (std::size_t i = 0; i < n;) {
    const unsigned char b = s[i];
    int len = 0;
    std::uint32_t cp = 0, min = 0;
    if (b < 0x80) {
      len = 1, cp = b;
    } else if ((b & 0xE0) == 0xC0) {
      len = 2, cp = b & 0x1F, min = 0x80;
    } else if ((b & 0xF0) == 0xE0) {
      len = 3, cp = b & 0x0F, min = 0x800;
    } else if ((b & 0xF8) == 0xF0) {
      len = 4, cp = b & 0x07, min = 0x10000;
    } else {
      return {line, column};
    }
    if (i + len > n) return {line, column};
    for (int k = 1; k < len; ++k) {
      if ((s[i + k] & 0xC0) != 0x80) return {line, column};
      cp = (cp << 6) | (s[i + k] & 0x3F);
    }
    if (cp < min || cp > 0x10FFFF || (cp >= 0xD800 && cp <= 0xDFFF)) return {line, column};
    if (b == '\n') {
      ++line;
      column = 1;
    } else {
      ++column;
    }
    i += len;
  }
  return {0, 0};
}

/// Input files named in the deck must be regular files: a directory "opens" as a stream
/// on Linux and would fail later with a stream error instead of a deck error.
void check_input_file(const Context& c, const YAML::Node& n, const std::string& path,
                      const std::string& what) {
  std::error_code ec;
  const auto st = fs::status(path, ec);
  if (!fs::exists(st)) c.fail(n, what + " '" + path + "' does not exist");
  if (fs::is_directory(st)) c.fail(n, what + " '" + path + "' is a directory, not a file");
  if (!fs::is_regular_file(st)) c.fail(n, what + " '" + path + "' is not a regular file");
}

void check_map(const Context& c, const YAML::Node& n, const std::string& what) {
  if (!n.IsMap()) c.fail(n, what + " must be a map");
}

void check_keys(const Context& c, const YAML::Node& n, const std::string& what,
                const std::set<std::string>& allowed) {
  check_map(c, n, what);
  for (const auto& kv : n) {
    const auto key = kv.first.as<std::string>();
    if (!allowed.count(key)) {
      std::string list;
      for (const auto& a : allowed) list += (list.empty() ? "" : ", ") + a;
      c.fail(kv.first, "unknown key '" + key + "' in " + what + " (allowed: " + list + ")");
    }
  }
}

double get_double(const Context& c, const YAML::Node& n, const std::string& what) {
  if (!n.IsScalar()) c.fail(n, what + " must be a number");
  try {
    double v = n.as<double>();
    if (!std::isfinite(v)) c.fail(n, what + " must be finite");
    return v;
  } catch (const YAML::Exception&) {
    c.fail(n, what + " must be a number, got '" + n.Scalar() + "'");
  }
}

int get_int(const Context& c, const YAML::Node& n, const std::string& what) {
  if (!n.IsScalar()) c.fail(n, what + " must be an integer");
  try {
    return n.as<int>();
  } catch (const YAML::Exception&) {
    c.fail(n, what + " must be an integer, got '" + n.Scalar() + "'");
  }
}

std::string get_string(const Context& c, const YAML::Node& n, const std::string& what) {
  if (!n.IsScalar()) c.fail(n, what + " must be a string");
  return n.Scalar();
}

/// One deck spelling of an enum value; each enum has one table, read by get_enum and
/// written by to_string.
template <class E>
struct EnumName {
  E value;
  const char* name;
};

/// The value the string at n names in `table`; otherwise an error listing the spellings
/// ("'a' or 'b'", or "one of a, b, c").
template <class E, std::size_t N>
E get_enum(const Context& c, const YAML::Node& n, const std::string& what,
           const EnumName<E> (&table)[N]) {
  const std::string s = get_string(c, n, what);
  for (const auto& e : table)
    if (s == e.name) return e.value;
  std::string list;
  if (N == 2) {
    list = std::string("'") + table[0].name + "' or '" + table[1].name + "'";
  } else {
    list = "one of ";
    for (std::size_t i = 0; i < N; ++i) list += (i ? ", " : "") + std::string(table[i].name);
  }
  c.fail(n, what + " must be " + list);
}

template <class E, std::size_t N>
const char* enum_name(E value, const EnumName<E> (&table)[N]) {
  for (const auto& e : table)
    if (e.value == value) return e.name;
  return "?";
}

constexpr EnumName<Analysis::Type> kAnalysisTypes[] = {{Analysis::Type::static_, "static"},
                                                       {Analysis::Type::dynamic, "dynamic"}};
constexpr EnumName<Analysis::Formulation> kFormulations[] = {
    {Analysis::Formulation::linear, "linear"},
    {Analysis::Formulation::corotational, "corotational"}};
constexpr EnumName<Analysis::Rotations> kRotations[] = {{Analysis::Rotations::iterated, "iterated"},
                                                        {Analysis::Rotations::lagged, "lagged"}};
constexpr EnumName<Analysis::Mass> kMasses[] = {{Analysis::Mass::lumped, "lumped"},
                                                {Analysis::Mass::consistent, "consistent"}};
constexpr EnumName<Solver::Type> kSolverTypes[] = {{Solver::Type::gmg, "gmg"},
                                                   {Solver::Type::gmg_cycles, "gmg-cycles"},
                                                   {Solver::Type::cg_jacobi, "cg-jacobi"},
                                                   {Solver::Type::hypre, "hypre"},
                                                   {Solver::Type::gamg, "gamg"},
                                                   {Solver::Type::direct, "direct"}};

bool get_bool(const Context& c, const YAML::Node& n, const std::string& what) {
  if (!n.IsScalar()) c.fail(n, what + " must be true or false");
  try {
    return n.as<bool>();
  } catch (const YAML::Exception&) {
    c.fail(n, what + " must be true or false, got '" + n.Scalar() + "'");
  }
}

Eigen::Vector3d get_vec3(const Context& c, const YAML::Node& n, const std::string& what) {
  if (!n.IsSequence() || n.size() != 3) c.fail(n, what + " must be a list of 3 numbers");
  return {get_double(c, n[0], what + "[0]"), get_double(c, n[1], what + "[1]"),
          get_double(c, n[2], what + "[2]")};
}

double positive(const Context& c, const YAML::Node& n, const std::string& what) {
  double v = get_double(c, n, what);
  if (!(v > 0)) c.fail(n, what + " must be > 0, got " + n.Scalar());
  return v;
}

int material_index(const Context& c, const YAML::Node& n) {
  const std::string name = get_string(c, n, "material");
  for (size_t i = 0; i < c.materials->size(); ++i)
    if ((*c.materials)[i].name == name) return int(i);
  c.fail(n, "unknown material '" + name + "' (define it under 'materials')");
}

// ---------------------------------------------------------------- shapes
geometry::TriangleMesh load_mesh_entry(const Context& c, const YAML::Node& n) {
  check_keys(c, n, "mesh", {"file", "scale", "rotate", "translate"});
  if (!n["file"]) c.fail(n, "mesh needs 'file'");
  const std::string path = c.resolve(get_string(c, n["file"], "mesh.file"));
  check_input_file(c, n["file"], path, "mesh.file");
  geometry::TriangleMesh mesh;
  try {
    mesh = geometry::load_triangle_mesh(path);
  } catch (const InputError& e) {
    c.fail(n["file"], std::string("cannot load mesh: ") + e.what());
  }
  const double scale = n["scale"] ? positive(c, n["scale"], "mesh.scale") : 1.0;
  const Eigen::Vector3d shift =
      n["translate"] ? get_vec3(c, n["translate"], "mesh.translate") : Eigen::Vector3d::Zero();
  Eigen::Matrix3d rotation = Eigen::Matrix3d::Identity();
  if (n["rotate"]) {
    // An axis and an angle (right-hand rule, degrees): positioning an implant or a blade.
    const auto& r = n["rotate"];
    check_keys(c, r, "mesh.rotate", {"axis", "angle"});
    if (!r["axis"] || !r["angle"])
      c.fail(r, "mesh.rotate needs 'axis' (vec3) and 'angle' (degrees, right-hand rule)");
    const Eigen::Vector3d axis = get_vec3(c, r["axis"], "mesh.rotate.axis");
    if (!(axis.norm() > 0.0)) c.fail(r["axis"], "mesh.rotate.axis must not be zero");
    const double angle = get_double(c, r["angle"], "mesh.rotate.angle");
    rotation = Eigen::AngleAxisd(angle * M_PI / 180.0, axis.normalized()).toRotationMatrix();
  }
  geometry::transform(mesh, scale, shift, rotation);
  return mesh;
}

std::shared_ptr<const geometry::Shape> parse_shape_entry(const Context& c, const std::string& kind,
                                                         const YAML::Node& n) {
  try {
    if (kind == "box") {
      check_keys(c, n, "box", {"min", "max"});
      if (!n["min"] || !n["max"]) c.fail(n, "box needs 'min' and 'max'");
      auto lo = get_vec3(c, n["min"], "box.min"), hi = get_vec3(c, n["max"], "box.max");
      if ((hi.array() <= lo.array()).any()) c.fail(n, "box.max must exceed box.min in every axis");
      return geometry::make_box(lo, hi);
    }
    if (kind == "sphere") {
      check_keys(c, n, "sphere", {"centre", "radius"});
      if (!n["centre"] || !n["radius"]) c.fail(n, "sphere needs 'centre' and 'radius'");
      return geometry::make_sphere(get_vec3(c, n["centre"], "sphere.centre"),
                                   positive(c, n["radius"], "sphere.radius"));
    }
    if (kind == "cylinder") {
      check_keys(c, n, "cylinder", {"start", "end", "radius"});
      if (!n["start"] || !n["end"] || !n["radius"])
        c.fail(n, "cylinder needs 'start', 'end' and 'radius'");
      auto p0 = get_vec3(c, n["start"], "cylinder.start"),
           p1 = get_vec3(c, n["end"], "cylinder.end");
      if ((p1 - p0).norm() == 0) c.fail(n, "cylinder.start and cylinder.end coincide");
      return geometry::make_cylinder(p0, p1, positive(c, n["radius"], "cylinder.radius"));
    }
    if (kind == "half_space") {
      check_keys(c, n, "half_space", {"point", "normal"});
      if (!n["point"] || !n["normal"]) c.fail(n, "half_space needs 'point' and 'normal'");
      auto nn = get_vec3(c, n["normal"], "half_space.normal");
      if (nn.norm() == 0) c.fail(n, "half_space.normal must be nonzero");
      return geometry::make_half_space(get_vec3(c, n["point"], "half_space.point"), nn);
    }
    if (kind == "plane") {  // selector only: a thin slab
      check_keys(c, n, "plane", {"point", "normal", "tolerance"});
      if (!n["point"] || !n["normal"]) c.fail(n, "plane needs 'point' and 'normal'");
      auto nn = get_vec3(c, n["normal"], "plane.normal");
      if (nn.norm() == 0) c.fail(n, "plane.normal must be nonzero");
      // Default tolerance: far below any cell size, far above round-off in positions.
      double tol = n["tolerance"] ? positive(c, n["tolerance"], "plane.tolerance") : 1e-3 * c.h;
      return geometry::make_slab(get_vec3(c, n["point"], "plane.point"), nn.normalized(), tol);
    }
    if (kind == "mesh") {
      auto mesh = load_mesh_entry(c, n);
      try {
        return geometry::make_mesh_solid(std::move(mesh));
      } catch (const std::invalid_argument& e) {  // e.g. a one-sided mesh: name the file
        c.fail(n["file"], "mesh '" + n["file"].Scalar() + "': " + e.what());
      }
    }
  } catch (const std::invalid_argument& e) {
    c.fail(n, e.what());
  }
  return nullptr;
}

const std::set<std::string> kShapeKinds = {"box", "sphere", "cylinder", "half_space", "mesh"};

// ---------------------------------------------------------------- sections
LatticeSpec parse_lattice(const Context& c, const YAML::Node& n) {
  check_keys(c, n, "lattice", {"origin", "h", "dims", "bounds"});
  LatticeSpec s;
  if (!n["h"]) c.fail(n, "lattice needs 'h' (cell size in m)");
  s.h = positive(c, n["h"], "lattice.h");
  if (n["dims"] && n["bounds"])
    c.fail(n, "lattice: give either 'dims' (with 'origin') or 'bounds', not both");
  if (n["bounds"]) {
    const auto& b = n["bounds"];
    if (!b.IsSequence() || b.size() != 2)
      c.fail(b, "lattice.bounds must be [[xmin,ymin,zmin],[xmax,ymax,zmax]]");
    auto lo = get_vec3(c, b[0], "lattice.bounds[0]"), hi = get_vec3(c, b[1], "lattice.bounds[1]");
    if ((hi.array() <= lo.array()).any())
      c.fail(b, "lattice.bounds: max must exceed min in every axis");
    if (n["origin"]) c.fail(n["origin"], "lattice: 'origin' is implied by 'bounds'");
    s.origin = lo;
    for (int d = 0; d < 3; ++d) {
      // A relative slack keeps 0.4/0.01 from becoming 41 cells through round-off.
      s.dims[d] = int(std::ceil((hi[d] - lo[d]) / s.h - 1e-9));
    }
  } else {
    if (!n["dims"]) c.fail(n, "lattice needs 'dims' or 'bounds'");
    const auto& d = n["dims"];
    if (!d.IsSequence() || d.size() != 3) c.fail(d, "lattice.dims must be a list of 3 integers");
    for (int i = 0; i < 3; ++i) s.dims[i] = get_int(c, d[i], "lattice.dims");
    if (n["origin"]) s.origin = get_vec3(c, n["origin"], "lattice.origin");
  }
  for (int i = 0; i < 3; ++i)
    if (s.dims[i] < 1) c.fail(n, "lattice.dims must be >= 1 in every axis");
  if (double(s.dims[0]) * s.dims[1] * s.dims[2] > 2.0e9)
    c.fail(n, "lattice has more than 2e9 cells; hexcut uses 32-bit cell indices");
  return s;
}

std::vector<Material> parse_materials(const Context& c, const YAML::Node& n) {
  check_map(c, n, "materials");
  std::vector<Material> out;
  for (const auto& kv : n) {
    Material m;
    m.name = kv.first.as<std::string>();
    const auto& v = kv.second;
    check_keys(c, v, "material '" + m.name + "'", {"E", "nu", "rho"});
    if (!v["E"] || !v["nu"] || !v["rho"])
      c.fail(v, "material '" + m.name + "' needs E, nu and rho");
    m.youngs_modulus = positive(c, v["E"], "E");
    m.poisson_ratio = get_double(c, v["nu"], "nu");
    if (!(m.poisson_ratio > -1.0 && m.poisson_ratio < 0.5))
      c.fail(v["nu"], "nu must be in (-1, 0.5), got " + v["nu"].Scalar());
    if (m.poisson_ratio > 0.49)
      c.warn(v["nu"], "nu = " + v["nu"].Scalar() +
                          " > 0.49: trilinear displacement elements lock as nu -> 0.5 (the "
                          "displacements come out too small, the stresses oscillate); hexcut has "
                          "no mixed u-p formulation (doc/user-guide.md, \"materials\")");
    m.density = positive(c, v["rho"], "rho");
    out.push_back(m);
  }
  if (out.empty()) c.fail(n, "materials is empty: define at least one");
  if (out.size() > 32000) c.fail(n, "too many materials (limit 32000)");
  return out;
}

/// image.calibration: voxel value -> density -> Young's modulus (doc/user-guide.md, "Images").
geometry::YoungsCalibration parse_calibration(const Context& c, const YAML::Node& n) {
  check_map(c, n, "image.calibration");
  check_keys(c, n, "image.calibration", {"density", "youngs", "E_min", "materials"});
  geometry::YoungsCalibration cal;
  if (!n["density"] || !n["youngs"])
    c.fail(n, "image.calibration needs 'density: {slope, intercept}' and 'youngs: {a, b}'");
  const auto& d = n["density"];
  check_map(c, d, "calibration.density");
  check_keys(c, d, "calibration.density", {"slope", "intercept"});
  if (!d["slope"]) c.fail(d, "calibration.density needs 'slope'");
  cal.density_slope = get_double(c, d["slope"], "calibration.density.slope");
  cal.density_intercept =
      d["intercept"] ? get_double(c, d["intercept"], "calibration.density.intercept") : 0.0;
  auto power_law = [&](const YAML::Node& p, const std::string& what) {
    check_map(c, p, what);
    check_keys(c, p, what, {"a", "b"});
    if (!p["a"] || !p["b"]) c.fail(p, what + " needs 'a' (Pa per density unit^b) and 'b'");
    return std::array<double, 2>{positive(c, p["a"], what + ".a"),
                                 positive(c, p["b"], what + ".b")};
  };
  const auto law = power_law(n["youngs"], "calibration.youngs");
  cal.a = law[0], cal.b = law[1];
  if (n["E_min"]) cal.E_min = positive(c, n["E_min"], "calibration.E_min");
  if (n["materials"]) {
    check_map(c, n["materials"], "calibration.materials");
    for (const auto& kv : n["materials"])
      cal.by_material[material_index(c, kv.first)] =
          power_law(kv.second, "calibration.materials." + kv.first.as<std::string>());
  }
  return cal;
}

GeometryStep parse_image_step(const Context& c, const YAML::Node& n) {
  check_keys(c, n, "image",
             {"file", "format", "dataset", "dims", "dtype", "endian", "origin", "spacing",
              "threshold", "labels", "material", "youngs_scale", "calibration"});
  if (!n["file"]) c.fail(n, "image needs 'file'");
  const std::string path = c.resolve(get_string(c, n["file"], "image.file"));
  // NIfTI files and DICOM series say where their voxels are: the format defaults to nifti
  // for .nii and .nii.gz and to dicom for a folder, and their spacing and origin are not
  // deck keys.
  auto ends_with = [&](const std::string& suffix) {
    return path.size() >= suffix.size() &&
           path.compare(path.size() - suffix.size(), suffix.size(), suffix) == 0;
  };
  const bool nii = ends_with(".nii") || ends_with(".nii.gz");
  const bool folder = fs::is_directory(path);
  const std::string format = n["format"] ? get_string(c, n["format"], "image.format")
                             : nii       ? "nifti"
                             : folder    ? "dicom"
                                         : "raw";
  if (format == "dicom") {
    if (!fs::exists(path)) c.fail(n["file"], "image.file '" + path + "' does not exist");
    if (!folder)
      c.fail(n["file"], "image.file '" + path +
                            "' is not a folder: a DICOM series is read from the folder of its "
                            "slices");
  } else {
    check_input_file(c, n["file"], path, "image.file");
  }
  std::shared_ptr<geometry::VoxelImage> image;
  if (format == "nifti" || format == "dicom") {
    for (const char* key : {"spacing", "origin", "dims", "dtype", "endian", "dataset"})
      if (n[key])
        c.fail(n[key], std::string("image.") + key + " is not used for a " +
                           (format == "nifti" ? "NIfTI image" : "DICOM series") +
                           ": its header gives the voxels, their size and position");
    try {
      if (format == "nifti") {
        geometry::NiftiInfo info;
        image = std::make_shared<geometry::VoxelImage>(geometry::load_nifti_image(path, &info));
        if (info.units == "unknown (mm)")
          c.warn(n["file"], "the NIfTI header gives no spatial unit: taken as mm");
      } else {
        image = std::make_shared<geometry::VoxelImage>(geometry::load_dicom_series(path));
      }
    } catch (const InputError& e) {
      c.fail(n["file"], std::string("cannot load image: ") + e.what());
    }
  } else {
    const Eigen::Vector3d origin =
        n["origin"] ? get_vec3(c, n["origin"], "image.origin") : Eigen::Vector3d::Zero();
    if (!n["spacing"]) c.fail(n, "image needs 'spacing' (voxel size in m, 3 numbers)");
    const Eigen::Vector3d spacing = get_vec3(c, n["spacing"], "image.spacing");
    if ((spacing.array() <= 0).any()) c.fail(n["spacing"], "image.spacing must be > 0");
    try {
      if (format == "raw") {
        if (!n["dims"] || !n["dtype"]) c.fail(n, "raw image needs 'dims' and 'dtype'");
        std::array<int, 3> dims{};
        for (int i = 0; i < 3; ++i) dims[i] = get_int(c, n["dims"][i], "image.dims");
        bool little = !n["endian"] || get_string(c, n["endian"], "image.endian") == "little";
        image = std::make_shared<geometry::VoxelImage>(geometry::load_raw_image(
            path, dims, get_string(c, n["dtype"], "image.dtype"), little, origin, spacing));
      } else if (format == "hdf5") {
        if (!n["dataset"]) c.fail(n, "hdf5 image needs 'dataset'");
        image = std::make_shared<geometry::VoxelImage>(geometry::load_hdf5_image(
            path, get_string(c, n["dataset"], "image.dataset"), origin, spacing));
      } else {
        c.fail(n["format"], "image.format must be 'raw', 'hdf5', 'nifti' or 'dicom'");
      }
    } catch (const InputError& e) {
      c.fail(n["file"], std::string("cannot load image: ") + e.what());
    } catch (const std::invalid_argument& e) {
      c.fail(n, std::string("image: ") + e.what());
    }
  }
  GeometryStep s;
  s.where = c.where(n);
  s.image = image;
  const auto nan_voxels = std::count_if(image->values.begin(), image->values.end(),
                                        [](float v) { return std::isnan(v); });
  if (nan_voxels > 0 && (n["labels"] || n["threshold"]))
    c.warn(n["file"], std::to_string(nan_voxels) + " of " + std::to_string(image->values.size()) +
                          " voxels are NaN: they count as empty (below any threshold, no label)");
  if (n["labels"]) {
    const auto& l = n["labels"];
    check_map(c, l, "image.labels");
    s.kind = GeometryStep::Kind::image_labels;
    for (const auto& kv : l)
      s.label_to_material[get_int(c, kv.first, "label")] = material_index(c, kv.second);
    if (n["threshold"] || n["material"])
      c.fail(n, "image: use either 'labels' or 'threshold'+'material'");
  } else if (n["threshold"]) {
    s.kind = GeometryStep::Kind::add;
    s.shape =
        geometry::make_image_threshold(image, get_double(c, n["threshold"], "image.threshold"));
    if (!n["material"]) c.fail(n, "image with 'threshold' needs 'material'");
    s.material = material_index(c, n["material"]);
  } else if (n["youngs_scale"] || n["calibration"]) {
    s.kind = GeometryStep::Kind::image_youngs;
  } else {
    c.fail(n, "image needs 'labels', 'threshold' (+ 'material'), 'youngs_scale' or 'calibration'");
  }
  if (n["youngs_scale"] && n["calibration"])
    c.fail(n["calibration"], "image: give either 'youngs_scale' or 'calibration', not both");
  if (n["youngs_scale"]) s.youngs_scale = positive(c, n["youngs_scale"], "image.youngs_scale");
  if (n["calibration"]) s.calibration = parse_calibration(c, n["calibration"]);
  return s;
}

std::vector<GeometryStep> parse_geometry(const Context& c, const YAML::Node& n) {
  if (!n.IsSequence()) c.fail(n, "geometry must be a list of operations");
  if (n.size() == 0) c.fail(n, "geometry is empty: add at least one shape");
  std::vector<GeometryStep> out;
  for (const auto& op : n) {
    check_keys(c, op, "geometry operation", {"add", "subtract", "assign", "image", "material"});
    int verbs =
        int(bool(op["add"])) + bool(op["subtract"]) + bool(op["assign"]) + bool(op["image"]);
    if (verbs != 1)
      c.fail(op, "each geometry operation needs exactly one of add, subtract, assign, image");
    if (op["image"]) {
      if (op["material"]) c.fail(op["material"], "put 'material' inside the image map");
      GeometryStep s = parse_image_step(c, op["image"]);
      // A youngs-only image step must also be able to carry labels; add both when given.
      out.push_back(s);
      if (s.kind != GeometryStep::Kind::image_youngs &&
          (op["image"]["youngs_scale"] || op["image"]["calibration"])) {
        s.kind = GeometryStep::Kind::image_youngs;
        out.push_back(s);
      }
      continue;
    }
    GeometryStep s;
    s.where = c.where(op);
    const char* verb = op["add"] ? "add" : op["subtract"] ? "subtract" : "assign";
    s.kind = op["add"]        ? GeometryStep::Kind::add
             : op["subtract"] ? GeometryStep::Kind::subtract
                              : GeometryStep::Kind::assign;
    const auto& body = op[verb];
    check_keys(c, body, std::string(verb), kShapeKinds);
    if (body.size() != 1) c.fail(body, std::string(verb) + " needs exactly one shape");
    const auto kv = *body.begin();
    s.shape = parse_shape_entry(c, kv.first.as<std::string>(), kv.second);
    if (s.kind == GeometryStep::Kind::subtract) {
      if (op["material"]) c.fail(op["material"], "subtract takes no material");
    } else {
      if (op["material"])
        s.material = material_index(c, op["material"]);
      else if (c.materials->size() == 1)
        s.material = 0;
      else
        c.fail(op, std::string(verb) + " needs 'material' when several materials are defined");
    }
    out.push_back(s);
  }
  return out;
}

Selector parse_selector(const Context& c, const YAML::Node& n, const std::string& what) {
  std::set<std::string> allowed = kShapeKinds;
  allowed.insert({"plane", "material", "all"});
  check_keys(c, n, what, allowed);
  Selector s;
  s.where = c.where(n);
  int shapes = 0;
  for (const auto& kv : n) {
    const auto key = kv.first.as<std::string>();
    if (key == "material") {
      s.material = material_index(c, kv.second);
    } else if (key == "all") {
      if (!get_bool(c, kv.second, "all")) c.fail(kv.second, "'all' may only be true");
      ++shapes;
    } else {
      s.shape = parse_shape_entry(c, key, kv.second);
      ++shapes;
    }
  }
  if (shapes > 1) c.fail(n, what + ": give one shape (or 'all: true'), optionally with 'material'");
  if (shapes == 0 && s.material < 0)
    c.fail(n, what + " selects nothing: give a shape, 'material' or 'all: true'");
  return s;
}

TimeFunction parse_time_function(const Context& c, const YAML::Node& n, const std::string& what) {
  TimeFunction f;
  if (n.IsScalar()) {
    f.value = get_double(c, n, what);
    return f;
  }
  check_keys(c, n, what, {"constant", "ramp", "sine"});
  if (n.size() != 1) c.fail(n, what + ": give one of constant, ramp, sine");
  if (n["constant"]) {
    f.value = get_double(c, n["constant"], what + ".constant");
  } else if (n["ramp"]) {
    const auto& r = n["ramp"];
    check_keys(c, r, what + ".ramp", {"value", "start", "end"});
    if (!r["value"] || !r["end"]) c.fail(r, "ramp needs 'value' and 'end' (start defaults to 0)");
    f.kind = TimeFunction::Kind::ramp;
    f.value = get_double(c, r["value"], "ramp.value");
    f.start = r["start"] ? get_double(c, r["start"], "ramp.start") : 0.0;
    f.end = get_double(c, r["end"], "ramp.end");
    if (!(f.end > f.start)) c.fail(r, "ramp.end must be later than ramp.start");
  } else {
    const auto& s = n["sine"];
    check_keys(c, s, what + ".sine", {"amplitude", "frequency", "phase"});
    if (!s["amplitude"] || !s["frequency"]) c.fail(s, "sine needs 'amplitude' and 'frequency'");
    f.kind = TimeFunction::Kind::sine;
    f.value = get_double(c, s["amplitude"], "sine.amplitude");
    f.frequency = positive(c, s["frequency"], "sine.frequency");
    f.phase = s["phase"] ? get_double(c, s["phase"], "sine.phase") : 0.0;
  }
  return f;
}

/// A number, or (when `time_functions`) a time function map, or else an expression: a
/// string that is not a number, compiled here so that its errors carry the deck line.
Field parse_field(const Context& c, const YAML::Node& n, const std::string& what,
                  bool time_functions) {
  Field f;
  f.where = c.where(n);
  if (n.IsMap() && time_functions) {
    f.function = parse_time_function(c, n, what);
    return f;
  }
  if (!n.IsScalar())
    c.fail(n, what + (time_functions ? " must be a number, a time function or an expression"
                                     : " must be a number or an expression"));
  double number = 0.0;
  if (YAML::convert<double>::decode(n, number)) {
    if (!std::isfinite(number)) c.fail(n, what + " must be finite");
    f.function.value = number;
    return f;
  }
  try {
    f.expression = std::make_shared<const Expression>(n.Scalar());
  } catch (const std::invalid_argument& e) {
    c.fail(n, e.what());
  }
  return f;
}

/// A list of three fields (numbers or expressions).
std::array<Field, 3> parse_field3(const Context& c, const YAML::Node& n, const std::string& what) {
  if (!n.IsSequence() || n.size() != 3)
    c.fail(n, what + " must be a list of 3 numbers or expressions");
  return {parse_field(c, n[0], what + "[0]", false), parse_field(c, n[1], what + "[1]", false),
          parse_field(c, n[2], what + "[2]", false)};
}

int component_index(const Context& c, const YAML::Node& n) {
  const auto s = get_string(c, n, "component");
  if (s == "x") return 0;
  if (s == "y") return 1;
  if (s == "z") return 2;
  c.fail(n, "component must be x, y or z, got '" + s + "'");
}

void parse_boundary(const Context& c, const YAML::Node& n, Deck& d) {
  check_keys(c, n, "boundary",
             {"fixed", "traction", "pressure", "point_loads", "gravity", "centrifugal"});
  if (n["fixed"]) {
    if (!n["fixed"].IsSequence()) c.fail(n["fixed"], "boundary.fixed must be a list");
    for (const auto& f : n["fixed"]) {
      check_keys(c, f, "fixed", {"where", "components", "value"});
      if (!f["where"]) c.fail(f, "fixed needs 'where' (a selector)");
      Support s;
      s.selector = parse_selector(c, f["where"], "fixed.where");
      if (f["components"]) {
        const auto& comp = f["components"];
        if (!comp.IsSequence() || comp.size() == 0)
          c.fail(comp, "components must be a list like [x, z]");
        s.constrained = {false, false, false};
        for (const auto& cc : comp) s.constrained[component_index(c, cc)] = true;
      }
      if (f["value"]) {
        const auto& v = f["value"];
        if (v.IsSequence()) {
          if (v.size() != 3)
            c.fail(v, "value must be a number, a time function, an expression, or a list of 3");
          for (int i = 0; i < 3; ++i) s.value[i] = parse_field(c, v[i], "value", true);
        } else {
          const auto one = parse_field(c, v, "value", true);
          s.value = {one, one, one};
        }
      }
      d.supports.push_back(s);
    }
  }
  if (n["traction"]) {
    if (!n["traction"].IsSequence()) c.fail(n["traction"], "boundary.traction must be a list");
    for (const auto& t : n["traction"]) {
      check_keys(c, t, "traction", {"where", "value", "force", "scale"});
      if (!t["where"] || (!t["value"] && !t["force"]))
        c.fail(t, "traction needs 'where' and 'value' [Pa] or 'force' [N]");
      if (t["value"] && t["force"])
        c.fail(t["force"],
               "traction: give either 'value' (force per area, Pa) or 'force' (the "
               "total force, N), not both");
      Traction tr;
      tr.selector = parse_selector(c, t["where"], "traction.where");
      if (t["value"]) {
        tr.value = parse_field3(c, t["value"], "traction.value");
      } else {
        tr.force = get_vec3(c, t["force"], "traction.force");
        if (!tr.force->allFinite()) c.fail(t["force"], "traction.force must be finite");
      }
      tr.scale.value = 1.0;
      if (t["scale"]) tr.scale = parse_time_function(c, t["scale"], "traction.scale");
      d.tractions.push_back(tr);
    }
  }
  if (n["pressure"]) {
    if (!n["pressure"].IsSequence()) c.fail(n["pressure"], "boundary.pressure must be a list");
    for (const auto& e : n["pressure"]) {
      check_keys(c, e, "pressure", {"where", "value", "scale"});
      if (!e["where"] || !e["value"]) c.fail(e, "pressure needs 'where' and 'value' [Pa]");
      Pressure p;
      p.selector = parse_selector(c, e["where"], "pressure.where");
      p.value = parse_field(c, e["value"], "pressure.value", false);
      p.scale.value = 1.0;
      if (e["scale"]) p.scale = parse_time_function(c, e["scale"], "pressure.scale");
      d.pressures.push_back(p);
    }
  }
  if (n["point_loads"]) {
    if (!n["point_loads"].IsSequence())
      c.fail(n["point_loads"], "boundary.point_loads must be a list");
    for (const auto& p : n["point_loads"]) {
      check_keys(c, p, "point load", {"at", "force", "scale"});
      if (!p["at"] || !p["force"]) c.fail(p, "point load needs 'at' [m] and 'force' [N]");
      PointLoad pl;
      pl.where = c.where(p);
      pl.position = get_vec3(c, p["at"], "point_load.at");
      pl.force = get_vec3(c, p["force"], "point_load.force");
      pl.scale.value = 1.0;
      if (p["scale"]) pl.scale = parse_time_function(c, p["scale"], "point_load.scale");
      d.point_loads.push_back(pl);
    }
  }
  if (n["gravity"]) d.gravity = get_vec3(c, n["gravity"], "gravity");
  if (n["centrifugal"]) {
    const auto& f = n["centrifugal"];
    check_keys(c, f, "centrifugal", {"point", "axis", "omega"});
    if (!f["point"] || !f["axis"] || !f["omega"])
      c.fail(f, "centrifugal needs 'point', 'axis' and 'omega' [rad/s]");
    auto& cf = d.centrifugal;
    cf.active = true;
    cf.point = get_vec3(c, f["point"], "centrifugal.point");
    cf.axis = get_vec3(c, f["axis"], "centrifugal.axis");
    if (cf.axis.norm() == 0) c.fail(f["axis"], "centrifugal.axis must be nonzero");
    cf.axis.normalize();
    cf.omega = get_double(c, f["omega"], "centrifugal.omega");
  }
}

/// initial_stress: a list of entries, each a material (optional) and either six values
/// (numbers or expressions of x, y, z) or an HDF5 dataset on the lattice's cells.
std::vector<InitialStress> parse_initial_stress(const Context& c, const YAML::Node& n,
                                                const LatticeSpec& spec) {
  if (!n.IsSequence() || n.size() == 0)
    c.fail(n, "initial_stress must be a list of entries (material, value or file + dataset)");
  static const char* kComponents[6] = {"xx", "yy", "zz", "xy", "yz", "xz"};
  std::vector<InitialStress> out;
  for (const auto& e : n) {
    check_keys(c, e, "initial_stress entry", {"material", "value", "file", "dataset"});
    InitialStress s;
    s.where = c.where(e);
    if (e["material"]) s.material = material_index(c, e["material"]);
    if (e["value"] && (e["file"] || e["dataset"]))
      c.fail(e, "initial_stress: give either 'value' or 'file' + 'dataset', not both");
    if (e["value"]) {
      const auto& v = e["value"];
      if (!v.IsSequence() || v.size() != 6)
        c.fail(v,
               "initial_stress.value must be a list of 6 numbers or expressions: xx, yy, zz, "
               "xy, yz, xz [Pa]");
      for (int i = 0; i < 6; ++i) {
        s.value[i] =
            parse_field(c, v[i], std::string("initial_stress.value.") + kComponents[i], false);
        if (s.value[i].depends_on_time())
          c.fail(v[i], std::string("initial_stress.value.") + kComponents[i] +
                           ": an initial stress is fixed in time; the expression may use x, y "
                           "and z, not t");
      }
    } else if (e["file"] || e["dataset"]) {
      if (!e["file"] || !e["dataset"])
        c.fail(e, "initial_stress from a file needs both 'file' and 'dataset'");
      const std::string path = c.resolve(get_string(c, e["file"], "initial_stress.file"));
      check_input_file(c, e["file"], path, "initial_stress.file");
      const std::string name = get_string(c, e["dataset"], "initial_stress.dataset");
      geometry::Hdf5Array<double> a;
      try {
        a = geometry::load_hdf5_array<double>(path, name);
      } catch (const InputError& err) {
        c.fail(e["file"], std::string("initial_stress: ") + err.what());
      }
      const std::vector<std::uint64_t> want{
          std::uint64_t(spec.dims[2]), std::uint64_t(spec.dims[1]), std::uint64_t(spec.dims[0]), 6};
      if (a.shape != want) {
        std::string got;
        for (auto d : a.shape) got += (got.empty() ? "" : ", ") + std::to_string(d);
        c.fail(e["dataset"], "initial_stress: dataset '" + name + "' has shape (" + got +
                                 "); it must be (nz, ny, nx, 6) = (" + std::to_string(want[0]) +
                                 ", " + std::to_string(want[1]) + ", " + std::to_string(want[2]) +
                                 ", 6) of the lattice's cells, components xx, yy, zz, xy, yz, xz "
                                 "[Pa]");
      }
      if (std::any_of(a.values.begin(), a.values.end(), [](double x) { return std::isinf(x); }))
        c.fail(e["dataset"], "initial_stress: dataset '" + name +
                                 "' holds infinite values (NaN marks cells without a value)");
      s.cells = std::make_shared<const std::vector<double>>(std::move(a.values));
    } else {
      c.fail(e, "initial_stress entry needs 'value' (6 components) or 'file' + 'dataset'");
    }
    out.push_back(std::move(s));
  }
  return out;
}

std::vector<Eigen::Vector3d> get_points(const Context& c, const YAML::Node& n,
                                        const std::string& what, std::size_t min_count) {
  if (!n.IsSequence() || n.size() < min_count)
    c.fail(n,
           what + " must be a list of at least " + std::to_string(min_count) + " points [x, y, z]");
  std::vector<Eigen::Vector3d> out;
  for (const auto& p : n) out.push_back(get_vec3(c, p, what));
  return out;
}

Blade parse_blade(const Context& c, const YAML::Node& n) {
  check_keys(c, n, "blade", {"mesh", "polygon", "scalpel", "cylinder"});
  if (n.size() != 1) c.fail(n, "a blade needs exactly one of mesh, polygon, scalpel, cylinder");
  Blade b;
  const auto kv = *n.begin();
  const auto kind = kv.first.as<std::string>();
  const auto& v = kv.second;
  if (kind == "mesh") {
    b.kind = Blade::Kind::mesh;
    b.mesh = load_mesh_entry(c, v);
  } else if (kind == "polygon") {
    b.kind = Blade::Kind::polygon;
    b.polygon = get_points(c, v, "polygon", 3);
    // Planar: every corner within round-off of the plane of the first three.
    const Eigen::Vector3d nrm = (b.polygon[1] - b.polygon[0]).cross(b.polygon[2] - b.polygon[0]);
    double size = 0.0;
    for (const auto& p : b.polygon) size = std::max(size, (p - b.polygon[0]).norm());
    if (nrm.norm() <= 1e-12 * size * size)
      c.fail(v, "polygon: the first three corners are collinear");
    for (const auto& p : b.polygon)
      if (std::abs(nrm.normalized().dot(p - b.polygon[0])) > 1e-9 * size)
        c.fail(v, "polygon: the corners are not in one plane (use a mesh blade for curved blades)");
    // Convex, corners in order: every turn has the sense of the first.
    const std::size_t m = b.polygon.size();
    for (std::size_t i = 0; i < m; ++i) {
      const auto& p0 = b.polygon[i];
      const auto& p1 = b.polygon[(i + 1) % m];
      const auto& p2 = b.polygon[(i + 2) % m];
      if ((p1 - p0).cross(p2 - p1).dot(nrm) < 0)
        c.fail(v,
               "polygon: the corners must be in order around a convex polygon (split others into "
               "several cuts)");
    }
  } else if (kind == "scalpel") {
    b.kind = Blade::Kind::scalpel;
    check_keys(c, v, "scalpel", {"edge", "path"});
    if (!v["edge"] || !v["path"])
      c.fail(v, "scalpel needs 'edge' (two points) and 'path' (offsets)");
    const auto edge = get_points(c, v["edge"], "scalpel.edge", 2);
    if (edge.size() != 2) c.fail(v["edge"], "scalpel.edge must be exactly two points");
    if ((edge[1] - edge[0]).norm() == 0) c.fail(v["edge"], "scalpel.edge has zero length");
    b.edge = {edge[0], edge[1]};
    b.path = get_points(c, v["path"], "scalpel.path", 2);
  } else {
    b.kind = Blade::Kind::cylinder;
    check_keys(c, v, "cylinder", {"start", "end", "radius", "segments"});
    for (const char* k : {"start", "end", "radius"})
      if (!v[k]) c.fail(v, std::string("cylinder blade needs '") + k + "'");
    b.start = get_vec3(c, v["start"], "cylinder.start");
    b.end = get_vec3(c, v["end"], "cylinder.end");
    if ((b.end - b.start).norm() == 0) c.fail(v, "cylinder.start and cylinder.end coincide");
    b.radius = positive(c, v["radius"], "cylinder.radius");
    if (v["segments"]) {
      b.segments = get_int(c, v["segments"], "cylinder.segments");
      if (b.segments < 3) c.fail(v["segments"], "cylinder.segments must be >= 3");
    }
  }
  return b;
}

std::vector<Cut> parse_cuts(const Context& c, const YAML::Node& n) {
  if (!n.IsSequence()) c.fail(n, "cuts must be a list of cuts");
  std::vector<Cut> out;
  for (const auto& e : n) {
    check_keys(c, e, "cut", {"blade", "time", "window"});
    if (!e["blade"]) c.fail(e, "a cut needs 'blade'");
    Cut cut;
    cut.where = c.where(e);
    cut.blade = parse_blade(c, e["blade"]);
    if (e["time"] && e["window"]) c.fail(e, "give either 'time' or 'window', not both");
    if (e["time"]) {
      cut.time = get_double(c, e["time"], "cut.time");
      if (cut.time < 0) c.fail(e["time"], "cut.time must be >= 0");
    }
    if (e["window"]) {
      const auto& w = e["window"];
      if (cut.blade.kind != Blade::Kind::scalpel)
        c.fail(w, "'window' applies to scalpel blades only (use 'time')");
      if (!w.IsSequence() || w.size() != 2) c.fail(w, "window must be [begin, end] [s]");
      cut.window_begin = get_double(c, w[0], "window[0]");
      cut.window_end = get_double(c, w[1], "window[1]");
      if (cut.window_begin < 0 || cut.window_end <= cut.window_begin)
        c.fail(w, "window must satisfy 0 <= begin < end");
      cut.swept = true;
      cut.time = cut.window_end;
    }
    out.push_back(std::move(cut));
  }
  return out;
}

Analysis parse_analysis(const Context& c, const YAML::Node& n) {
  check_keys(c, n, "analysis",
             {"type", "formulation", "rotations", "load_steps", "tolerance", "max_iterations", "dt",
              "steps", "end_time", "rayleigh", "mass", "energy_tolerance"});
  Analysis a;
  if (n["type"]) a.type = get_enum(c, n["type"], "analysis.type", kAnalysisTypes);
  if (n["formulation"])
    a.formulation = get_enum(c, n["formulation"], "analysis.formulation", kFormulations);
  if (n["load_steps"]) {
    a.load_steps = get_int(c, n["load_steps"], "analysis.load_steps");
    if (a.load_steps < 1) c.fail(n["load_steps"], "analysis.load_steps must be >= 1");
  }
  if (n["tolerance"]) a.tolerance = positive(c, n["tolerance"], "analysis.tolerance");
  if (n["max_iterations"]) {
    a.max_iterations = get_int(c, n["max_iterations"], "analysis.max_iterations");
    if (a.max_iterations < 1) c.fail(n["max_iterations"], "analysis.max_iterations must be >= 1");
  }
  if (a.type == Analysis::Type::dynamic) {
    if (!n["dt"]) c.fail(n, "dynamic analysis needs 'dt' [s]");
    a.dt = positive(c, n["dt"], "analysis.dt");
    if (n["steps"] && n["end_time"]) c.fail(n, "give either 'steps' or 'end_time', not both");
    if (n["steps"])
      a.steps = get_int(c, n["steps"], "analysis.steps");
    else if (n["end_time"]) {
      const double steps = positive(c, n["end_time"], "analysis.end_time") / a.dt;
      // The step counter is an int (and a run of 2^31 steps is a mistake, not a plan).
      if (!(steps < double(std::numeric_limits<int>::max()) + 0.5)) {
        char msg[160];
        std::snprintf(msg, sizeof msg,
                      "end_time / dt = %.3g steps, more than the limit of %d (use a larger dt)",
                      steps, std::numeric_limits<int>::max());
        c.fail(n["end_time"], msg);
      }
      a.steps = int(std::llround(steps));
    } else
      c.fail(n, "dynamic analysis needs 'steps' or 'end_time'");
    if (a.steps < 1) c.fail(n, "dynamic analysis needs at least one step");
    if (n["rayleigh"]) {
      const auto& r = n["rayleigh"];
      if (!r.IsSequence() || r.size() != 2)
        c.fail(r, "rayleigh must be [alpha1 (mass), alpha2 (stiffness)]");
      a.rayleigh_mass = get_double(c, r[0], "rayleigh[0]");
      a.rayleigh_stiffness = get_double(c, r[1], "rayleigh[1]");
      if (a.rayleigh_mass < 0 || a.rayleigh_stiffness < 0)
        c.fail(r, "rayleigh coefficients must be >= 0");
    }
    if (n["rotations"]) {
      a.rotations = get_enum(c, n["rotations"], "analysis.rotations", kRotations);
      if (a.formulation != Analysis::Formulation::corotational)
        c.fail(n["rotations"], "analysis.rotations applies only to formulation: corotational");
    }
    if (n["energy_tolerance"])
      a.energy_tolerance = positive(c, n["energy_tolerance"], "analysis.energy_tolerance");
    if (n["mass"]) a.mass = get_enum(c, n["mass"], "analysis.mass", kMasses);
  } else {
    for (const char* k :
         {"dt", "steps", "end_time", "rayleigh", "mass", "rotations", "energy_tolerance"})
      if (n[k]) c.fail(n[k], std::string("'") + k + "' applies only to dynamic analyses");
  }
  return a;
}

Discretization parse_discretization(const Context& c, const YAML::Node& n) {
  check_keys(c, n, "discretization", {"type", "level"});
  Discretization d;
  d.where = c.where(n);
  if (n["type"]) {
    const std::string t = get_string(c, n["type"], "discretization.type");
    if (t == "hexahedra")
      d.type = Discretization::Type::hexahedra;
    else if (t == "composite")
      d.type = Discretization::Type::composite;
    else
      c.fail(n["type"], "discretization.type must be hexahedra or composite, not '" + t + "'");
  }
  if (n["level"]) {
    if (d.type != Discretization::Type::composite)
      c.fail(n["level"], "discretization.level applies only to type: composite");
    d.level = get_int(c, n["level"], "discretization.level");
    if (d.level < 0 || d.level > 3)
      c.fail(n["level"], "discretization.level must be 1, 2 or 3 (0: the fine hexahedra)");
  } else if (d.type == Discretization::Type::composite) {
    c.fail(n, "discretization type composite needs 'level' (1, 2 or 3)");
  }
  return d;
}

Solver parse_solver(const Context& c, const YAML::Node& n) {
  check_keys(c, n, "solver", {"type", "rtol", "max_iterations", "cycles", "petsc_options"});
  Solver s;
  if (n["type"]) s.type = get_enum(c, n["type"], "solver.type", kSolverTypes);
  if (n["cycles"]) {
    if (s.type != Solver::Type::gmg_cycles)
      c.fail(n["cycles"], "'cycles' applies only to solver type gmg-cycles");
    s.cycles = get_int(c, n["cycles"], "solver.cycles");
    if (s.cycles < 1) c.fail(n["cycles"], "solver.cycles must be >= 1");
  }
  if (n["rtol"]) {
    s.rtol = positive(c, n["rtol"], "solver.rtol");
    if (s.rtol >= 1) c.fail(n["rtol"], "solver.rtol must be < 1");
  }
  if (n["max_iterations"]) {
    s.max_iterations = get_int(c, n["max_iterations"], "solver.max_iterations");
    if (s.max_iterations < 1) c.fail(n["max_iterations"], "solver.max_iterations must be >= 1");
  }
  if (n["petsc_options"]) {
    // A string "-a 1 -b" or a map {ksp_monitor: "", pc_type: lu}.
    const auto& p = n["petsc_options"];
    if (p.IsScalar()) {
      std::istringstream in(p.Scalar());
      std::string tok;
      while (in >> tok) {
        if (tok[0] == '-' && !(tok.size() > 1 && (std::isdigit(tok[1]) || tok[1] == '.'))) {
          s.petsc_options.push_back({tok, ""});
        } else {
          if (s.petsc_options.empty())
            c.fail(p, "petsc_options: value '" + tok + "' has no option name before it");
          s.petsc_options.back().second = tok;
        }
      }
    } else if (p.IsMap()) {
      for (const auto& kv : p) {
        std::string name = get_string(c, kv.first, "petsc_options name");
        if (name.empty()) c.fail(kv.first, "petsc_options: empty option name");
        if (name[0] != '-') name = "-" + name;
        if (!kv.second.IsNull() && !kv.second.IsScalar())
          c.fail(kv.second, "petsc_options: the value of '" + name +
                                "' must be a single value (a number, word or \"\"), not a list "
                                "or map");
        s.petsc_options.push_back({name, kv.second.IsNull() ? "" : kv.second.Scalar()});
      }
    } else {
      c.fail(p, "petsc_options must be a string or a map");
    }
  }
  return s;
}

/// The XDMF index refers to the HDF5 file as "NAME.h5:/path": a ':' (or XML, shell and
/// non-ASCII characters) in NAME breaks some readers, so output names keep to the POSIX
/// portable file name characters.
/// `n`: the deck's output.name, or null for the default (the deck file's stem).
void check_output_name(const Context& c, const YAML::Node* n, const std::string& name) {
  const bool portable = !name.empty() && name[0] != '-' && name[0] != '.' &&
                        std::all_of(name.begin(), name.end(), [](char ch) {
                          return (ch >= 'a' && ch <= 'z') || (ch >= 'A' && ch <= 'Z') ||
                                 (ch >= '0' && ch <= '9') || ch == '.' || ch == '_' || ch == '-';
                        });
  // NAME_surface.xmf is the surface index of NAME.h5: a result may not take that name.
  const std::string surface = "_surface";
  const bool index_name = name.size() >= surface.size() &&
                          name.compare(name.size() - surface.size(), surface.size(), surface) == 0;
  if (portable && !index_name) return;
  const std::string msg = "output.name '" + name +
                          "' must be a plain file name of letters, digits, '.', '_' and '-' "
                          "(not starting with '.' or '-', not ending in '_surface'): the XDMF "
                          "index cannot refer to other names reliably";
  if (!n)
    throw InputError(c.file, 1, msg + "; the default is the deck file's name: give output.name");
  c.fail(*n, msg);
}

Output parse_output(const Context& c, const YAML::Node& n) {
  check_keys(c, n, "output",
             {"directory", "name", "every", "checkpoint_every", "fields", "overwrite"});
  Output o;
  o.where = c.where(n);
  if (n["directory"]) o.directory = get_string(c, n["directory"], "output.directory");
  if (n["name"]) {
    const YAML::Node node = n["name"];
    o.name = get_string(c, node, "output.name");
    check_output_name(c, &node, o.name);
  }
  if (n["overwrite"]) o.overwrite = get_bool(c, n["overwrite"], "output.overwrite");
  if (n["every"]) {
    o.every = get_int(c, n["every"], "output.every");
    if (o.every < 1) c.fail(n["every"], "output.every must be >= 1");
  }
  if (n["checkpoint_every"]) {
    o.checkpoint_every = get_int(c, n["checkpoint_every"], "output.checkpoint_every");
    if (o.checkpoint_every < 0)
      c.fail(n["checkpoint_every"], "output.checkpoint_every must be >= 0");
  }
  if (n["fields"]) {
    static const std::set<std::string> known = {
        "displacement", "velocity",          "acceleration",         "stress",
        "von_mises",    "pressure",          "principal_stress",     "principal_directions",
        "surface",      "composite_element", "strain_energy_density"};
    if (!n["fields"].IsSequence()) c.fail(n["fields"], "output.fields must be a list");
    o.fields.clear();
    for (const auto& f : n["fields"]) {
      auto name = get_string(c, f, "field");
      if (!known.count(name)) c.fail(f, "unknown output field '" + name + "'");
      if (name == "composite_element" && !c.composite)
        c.fail(f, "output field 'composite_element' needs discretization: {type: composite}");
      o.fields.push_back(name);
    }
  }
  return o;
}

}  // namespace

double TimeFunction::operator()(double t) const {
  switch (kind) {
    case Kind::constant:
      return value;
    case Kind::ramp:
      if (t <= start) return 0.0;
      if (t >= end) return value;
      return value * (t - start) / (end - start);
    case Kind::sine:
      return value * std::sin(2.0 * M_PI * frequency * t + phase);
  }
  return value;
}

bool Output::has_field(const std::string& f) const {
  for (const auto& x : fields)
    if (x == f) return true;
  return false;
}

std::vector<geometry::GeometryOp> membership_ops(const GeometryStep& step) {
  std::vector<geometry::GeometryOp> ops;
  switch (step.kind) {
    case GeometryStep::Kind::add:
      ops.push_back({geometry::OpMode::add, step.shape, step.material});
      break;
    case GeometryStep::Kind::subtract:
      ops.push_back({geometry::OpMode::subtract, step.shape, 0});
      break;
    case GeometryStep::Kind::assign:
      ops.push_back({geometry::OpMode::assign, step.shape, step.material});
      break;
    case GeometryStep::Kind::image_labels: {
      // Each cell has one label, so the order of the per-material adds is irrelevant.
      std::map<int, std::set<int>> labels_of;  // material -> labels
      for (const auto& [label, material] : step.label_to_material)
        labels_of[material].insert(label);
      for (auto& [material, labels] : labels_of)
        ops.push_back({geometry::OpMode::add,
                       geometry::make_image_labels(step.image, std::move(labels)), material});
      break;
    }
    case GeometryStep::Kind::image_youngs:
      break;
  }
  return ops;
}

std::vector<geometry::GeometryOp> membership_ops(const Deck& deck) {
  std::vector<geometry::GeometryOp> ops;
  for (const auto& step : deck.geometry) {
    auto more = membership_ops(step);
    ops.insert(ops.end(), more.begin(), more.end());
  }
  return ops;
}

const char* to_string(Solver::Type t) {
  return enum_name(t, kSolverTypes);
}

namespace {
Deck parse_sections(Context& c, const YAML::Node& root, const std::string& text,
                    const std::string& path);
}  // namespace

Deck parse_deck(const std::string& text, const std::string& path) {
  Context c;
  c.file = path;
  c.dir = fs::path(path).parent_path();
  // The deck is stored verbatim in the result file (a UTF-8 string) and names from it go
  // into XML indexes: both need valid UTF-8, which YAML requires anyway.
  if (const auto [line, column] = first_invalid_utf8(text); line > 0)
    throw InputError(
        path, line,
        "the deck is not valid UTF-8 (column " + std::to_string(column) + "): save it as UTF-8");
  std::vector<YAML::Node> documents;
  try {
    documents = YAML::LoadAll(text);
  } catch (const YAML::ParserException& e) {
    throw InputError(path, e.mark.line + 1, "YAML syntax error: " + e.msg);
  }
  if (documents.size() > 1)
    throw InputError(path, c.line(documents[1]) > 0 ? c.line(documents[1]) : 1,
                     "the deck holds more than one YAML document ('---'); hexcut reads one "
                     "deck per file");
  const YAML::Node root = documents.empty() ? YAML::Node() : documents.front();
  if (!root.IsMap()) throw InputError(path, 1, "the deck must be a YAML map of sections");
  check_unique_keys(c, root);
  try {
    return parse_sections(c, root, text, path);
  } catch (const YAML::Exception& e) {
    // A conversion the checks above did not anticipate: still a deck error with its line.
    throw InputError(path, e.mark.line >= 0 ? e.mark.line + 1 : 1, e.msg);
  }
}

namespace {

Deck parse_sections(Context& c, const YAML::Node& root, const std::string& text,
                    const std::string& path) {
  check_keys(c, root, "the deck",
             {"lattice", "materials", "geometry", "boundary", "cuts", "analysis", "discretization",
              "solver", "output", "compare", "initial_stress"});
  for (const char* required : {"lattice", "materials", "geometry"})
    if (!root[required])
      throw InputError(path, 1, std::string("missing section '") + required + "'");

  Deck d;
  d.path = path;
  d.text = text;
  c.warnings = &d.warnings;
  d.lattice = parse_lattice(c, root["lattice"]);
  d.lattice_where = c.where(root["lattice"]);
  c.h = d.lattice.h;
  d.materials = parse_materials(c, root["materials"]);
  c.materials = &d.materials;
  d.geometry = parse_geometry(c, root["geometry"]);
  if (root["boundary"]) parse_boundary(c, root["boundary"], d);
  if (root["cuts"]) d.cuts = parse_cuts(c, root["cuts"]);
  if (root["analysis"]) d.analysis = parse_analysis(c, root["analysis"]);
  if (root["discretization"]) d.discretization = parse_discretization(c, root["discretization"]);
  if (root["solver"]) d.solver = parse_solver(c, root["solver"]);
  c.composite = d.discretization.type == Discretization::Type::composite;
  d.output.where = {path, 1};
  if (root["output"]) d.output = parse_output(c, root["output"]);
  if (d.output.name.empty()) {
    d.output.name = fs::path(path).stem().string();
    check_output_name(c, nullptr, d.output.name);
  }
  if (root["compare"]) {
    const auto& n = root["compare"];
    check_map(c, n, "compare");
    check_keys(c, n, "compare", {"reference"});
    if (!n["reference"]) c.fail(n, "compare needs 'reference' (a hexcut result file)");
    Compare cmp;
    cmp.reference = c.resolve(get_string(c, n["reference"], "compare.reference"));
    check_input_file(c, n["reference"], cmp.reference, "compare.reference");
    cmp.where = c.where(n["reference"]);
    d.compare = cmp;
  }
  if (root["initial_stress"]) {
    d.initial_stress = parse_initial_stress(c, root["initial_stress"], d.lattice);
    // The corotated initial stress turns with each cell (R sigma0 R^T) and would enter every
    // corotational force and right-hand side; not implemented yet (doc/user-guide.md "Not yet").
    if (d.analysis.formulation == Analysis::Formulation::corotational)
      c.fail(root["initial_stress"],
             "initial_stress needs analysis.formulation: linear (the corotational initial "
             "stress is not implemented yet)");
  }
  if (d.analysis.type == Analysis::Type::static_ && d.supports.empty())
    throw InputError(path, c.line(root),
                     "a static analysis needs supports (boundary.fixed); without them the "
                     "stiffness is singular");
  return d;
}

}  // namespace

}  // namespace hexcut::deck
