// The input deck as plain data (doc/user-guide.md is the reference for every key).
// Parsing validates everything that can be checked without voxelizing, so a wrong deck
// fails with "deck.yaml:LINE: message" before any heavy work.
#pragma once

#include <Eigen/Core>
#include <array>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "common/lattice_spec.hpp"
#include "geometry/shape.hpp"
#include "geometry/triangle_mesh.hpp"
#include "geometry/voxel_image.hpp"
#include "geometry/voxelize.hpp"

namespace hexcut::deck {

/// Where in the deck a value came from, for error messages found later (e.g. a
/// selector that selects nothing is only known after voxelization).
struct SourceLocation {
  std::string file;
  int line = 0;
  std::string prefix() const { return file + ":" + std::to_string(line) + ": "; }
};

struct Material {
  std::string name;
  double youngs_modulus = 0.0;  // E [Pa]
  double poisson_ratio = 0.0;   // nu [-], in (-1, 0.5)
  double density = 0.0;         // rho [kg/m^3]
};

/// One geometry operation, applied in deck order (doc/theory.md, "Voxelization").
struct GeometryStep {
  enum class Kind { add, subtract, assign, image_labels, image_youngs };
  Kind kind = Kind::add;
  std::shared_ptr<const geometry::Shape> shape;            // add/subtract/assign
  int material = 0;                                        // add/assign
  std::shared_ptr<const geometry::VoxelImage> image;       // image_* kinds
  std::map<int, int> label_to_material;                    // image_labels
  double youngs_scale = 1.0;                               // image_youngs
  std::optional<geometry::YoungsCalibration> calibration;  // image_youngs, instead of the scale
  SourceLocation where;
};

/// A scalar function of time: constant, linear ramp or sine.
struct TimeFunction {
  enum class Kind { constant, ramp, sine };
  Kind kind = Kind::constant;
  double value = 0.0;      // constant value, ramp end value, or sine amplitude
  double start = 0.0;      // ramp: time at which it starts from 0 [s]
  double end = 0.0;        // ramp: time at which it reaches `value` [s]
  double frequency = 0.0;  // sine [Hz]
  double phase = 0.0;      // sine [rad]
  double operator()(double t) const;
};

class Expression;  // deck/expression.hpp

/// A prescribed value that may vary in space: a time function, or an expression of the
/// reference position x, y, z [m] and time t [s] (doc/user-guide.md "Expressions").
struct Field {
  TimeFunction function;                         // used when there is no expression
  std::shared_ptr<const Expression> expression;  // null: the time function
  SourceLocation where;                          // the deck line of the value
  /// The value at reference position x [m] and time t [s]; an expression may give inf or
  /// nan (the callers check).
  double operator()(const Eigen::Vector3d& x, double t) const;
  bool depends_on_time() const;
};

/// Selects vertex copies (supports, point loads), boundary faces (tractions) or cells.
struct Selector {
  std::shared_ptr<const geometry::Shape> shape;  // null = everything
  int material = -1;                             // -1 = any material
  SourceLocation where;
};

struct Support {  // fixed or prescribed displacement
  Selector selector;
  std::array<bool, 3> constrained{true, true, true};
  std::array<Field, 3> value;  // [m], at the vertex; default 0
};

struct Traction {
  Selector selector;
  std::array<Field, 3> value;  // [Pa], force per reference area (constants or expressions)
  /// Instead of `value`: the total force [N], spread as a uniform traction over the
  /// reference area of the faces the selector selects (a joint or muscle force).
  std::optional<Eigen::Vector3d> force;
  TimeFunction scale;          // multiplies value; default constant 1
};

/// A pressure on boundary faces: the force on a face is -p n dA with n its outward
/// normal in the reference configuration (a dead load; doc/theory.md "Supports and loads").
struct Pressure {
  Selector selector;
  Field value;         // p [Pa], positive pushes into the body (a constant or an expression)
  TimeFunction scale;  // multiplies value; default constant 1
};

struct PointLoad {
  Eigen::Vector3d position{0, 0, 0};  // [m]; applied at the nearest vertex copy
  Eigen::Vector3d force{0, 0, 0};     // [N]
  TimeFunction scale;
  SourceLocation where;
};

struct Analysis {
  enum class Type { static_, dynamic };
  enum class Formulation { linear, corotational };
  enum class Mass { lumped, consistent };
  // dynamic corotational: rotations iterated within each step by the mid-point scheme
  // (doc/theory.md "Mid-point corotational step"), or lagged: taken from the previous
  // step, one solve per step (the theses' real-time mode; not energy-consistent)
  enum class Rotations { iterated, lagged };
  Type type = Type::static_;
  Formulation formulation = Formulation::linear;
  Rotations rotations = Rotations::iterated;
  // corotational fixed-point iterations: per load step (static), per time step (dynamic)
  int load_steps = 1;
  double tolerance = 1e-6;  // static: ||u_k+1 - u_k|| <= tolerance * ||u_k+1||; dynamic:
                            // <= tolerance * ||u_k+1 - u_n|| (the step's increment)
  int max_iterations = 50;
  // dynamic: stop (SolverError) when the energy the time integration created exceeds this
  // fraction of the energy supplied (doc/theory.md "Energy balance")
  double energy_tolerance = 0.1;
  // dynamic (Newmark beta=1/4, gamma=1/2)
  double dt = 0.0;                  // [s]
  int steps = 0;                    // number of time steps (from end_time / dt if given)
  double rayleigh_mass = 0.0;       // alpha1 [1/s]
  double rayleigh_stiffness = 0.0;  // alpha2 [s]
  Mass mass = Mass::lumped;
};

struct Solver {
  enum class Type { cg_jacobi, hypre, gamg, direct, gmg, gmg_cycles };
  // hexcut's own multigrid: 10 CG iterations on the 1.4M-DOF cantilever where hypre needs
  // 57 and 20x the time (doc/benchmarks.md).
  Type type = Type::gmg;
  int cycles = 2;  // gmg-cycles: multigrid cycles per solve (Richardson, no convergence test)
  double rtol = 1e-8;
  int max_iterations = 10000;
  std::vector<std::pair<std::string, std::string>> petsc_options;  // name (with '-'), value
};

/// The simulation's discretization (doc/theory.md, "Composite elements"): the fine hexahedra
/// of the lattice, or composite elements, the cells of multigrid hierarchy level `level`
/// (each a connected piece of a (2^level)^3 block of fine cells) with Galerkin matrices
/// K~ = I^T K I, M~ = I^T M I from the fine cells they contain (Wu 2014, eq. 4.3-4.5).
struct Discretization {
  enum class Type { hexahedra, composite };
  Type type = Type::hexahedra;
  int level = 0;  // composite: 1..3 (0: the fine hexahedra through the composite path)
  SourceLocation where;
};

struct Output {
  std::string directory = "results";
  std::string name;          // default: deck file stem
  int every = 1;             // write every N steps (static: the final state is always written)
  int checkpoint_every = 0;  // 0 = only at the end
  bool overwrite = false;    // replace an existing result when the run ends (result_files.hpp)
  SourceLocation where;      // the output section (line 1 without one), for errors
  std::vector<std::string> fields{"displacement",     "velocity",
                                  "acceleration",     "stress",
                                  "von_mises",        "pressure",
                                  "principal_stress", "principal_directions",
                                  "surface",          "strain_energy_density"};
  bool has_field(const std::string& f) const;
};

/// The body force of a steady spin about an axis, rho omega^2 r (r: distance vector
/// from the axis), in the reference configuration.
struct Centrifugal {
  bool active = false;
  Eigen::Vector3d point{0, 0, 0};  // a point of the axis [m]
  Eigen::Vector3d axis{0, 0, 1};   // unit axis direction
  double omega = 0.0;              // angular velocity [rad/s]
};

/// A blade (doc/theory.md, "Cutting"): the surface that disconnects the links it crosses.
struct Blade {
  enum class Kind { mesh, polygon, scalpel, cylinder };
  Kind kind = Kind::polygon;
  geometry::TriangleMesh mesh;                   // mesh: triangles as given (scaled, moved)
  std::vector<Eigen::Vector3d> polygon;          // polygon: planar, >= 3 corners [m]
  std::array<Eigen::Vector3d, 2> edge;           // scalpel: the cutting edge at path offset 0 [m]
  std::vector<Eigen::Vector3d> path;             // scalpel: offsets of the edge, >= 2 [m]
  Eigen::Vector3d start{0, 0, 0}, end{0, 0, 0};  // cylinder: ends of the axis [m]
  double radius = 0.0;                           // cylinder [m]
  int segments = 48;                             // cylinder: facets around the axis
};

/// A cut: a blade and when it acts. Cut ids are 1, 2, ... in deck order.
struct Cut {
  Blade blade;
  double time =
      0.0;  // [s]: acts at the first step ending at or after it (static: before the solve)
  bool swept = false;  // scalpel over a window: path offset k is reached at
  double window_begin = 0.0, window_end = 0.0;  // t0 + k (t1 - t0) / (n - 1) [s]
  SourceLocation where;
};

/// compare: the stress of this run against a reference result of the same lattice
/// (doc/user-guide.md, "compare").
struct Compare {
  std::string reference;  // result file (.h5), resolved against the deck's directory
  SourceLocation where;
};

/// An initial (residual) stress sigma0 of cells, constant in time (doc/theory.md "Initial
/// stress"): it enters the equilibrium as -integral B^T sigma0 where the body's uncut
/// reference state does not balance it, is released on the faces cuts open, and the
/// stress output is sigma0 + sigma(u). Entries apply in deck order; a later one replaces
/// an earlier one on the cells it covers.
struct InitialStress {
  int material = -1;  // -1: cells of every material
  /// ParaView order xx, yy, zz, xy, yz, xz [Pa]: numbers or expressions of x, y, z,
  /// evaluated at cell centres. Unused when `cells` is set.
  std::array<Field, 6> value;
  /// From an HDF5 dataset of shape (nz, ny, nx, 6) on the lattice's cells: 6 values per
  /// lattice cell (dense, x fastest); a row with a NaN is "no value" (such a cell keeps an
  /// earlier entry's value; counted in a warning after voxelization). Null: `value`.
  std::shared_ptr<const std::vector<double>> cells;
  SourceLocation where;
};

struct Deck {
  std::string path;
  std::string text;  // verbatim, stored in the output
  /// "file:line: warning: ..." for input hexcut accepts but the user should know about
  /// (e.g. NaN voxels in an image); the job prints them once.
  std::vector<std::string> warnings;
  LatticeSpec lattice;
  SourceLocation lattice_where;  // the lattice section, for errors found later
  std::vector<Material> materials;
  std::vector<GeometryStep> geometry;
  std::vector<Support> supports;
  std::vector<Traction> tractions;
  std::vector<Pressure> pressures;
  std::vector<PointLoad> point_loads;
  Eigen::Vector3d gravity{0, 0, 0};  // [m/s^2]
  Centrifugal centrifugal;
  std::vector<Cut> cuts;
  Analysis analysis;
  Discretization discretization;
  Solver solver;
  Output output;
  std::optional<Compare> compare;
  std::vector<InitialStress> initial_stress;
};

/// A geometry step as the membership operations it applies (a label image: one add per
/// material; a Young's modulus image changes no membership: none).
std::vector<geometry::GeometryOp> membership_ops(const GeometryStep& step);
/// Every step's operations, in deck order: the body build_lattice voxelizes.
std::vector<geometry::GeometryOp> membership_ops(const Deck& deck);

/// Parses and validates a deck. `text` is the file content, `path` names it in errors.
/// Throws InputError ("path:line: message").
Deck parse_deck(const std::string& text, const std::string& path);

const char* to_string(Solver::Type t);

}  // namespace hexcut::deck
