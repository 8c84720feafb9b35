// Which rigid motions the supports of a piece leave free (analysis::find_pieces,
// doc/theory.md "Pieces"), against what geometry says for each support: a roller base
// leaves the in-plane motions, an edge held in place the rotation about that edge, a
// point the rotations about it. Runs on any number of ranks (ctest: 1 and 2); the
// supports of a piece are spread over the ranks.
#include <cstdio>
#include <regex>

#include "analysis/cutting.hpp"
#include "fixture.hpp"

namespace hexcut::testing {
namespace {

/// A cube [0,1]^3 of 4^3 cells with the given supports (YAML list items).
std::string cube(const std::string& fixed) {
  return "lattice: {h: 0.25, dims: [4, 4, 4]}\n"
         "materials: {m: {E: 1.0e6, nu: 0.3, rho: 1000}}\n"
         "geometry: [{add: {box: {min: [0, 0, 0], max: [1, 1, 1]}}}]\n"
         "boundary:\n  fixed:\n" +
         fixed + "solver: {type: cg-jacobi}\n";
}

std::string free_modes(const std::string& fixed) {
  Job job(PETSC_COMM_WORLD, cube(fixed));
  const auto pieces = analysis::find_pieces(PETSC_COMM_WORLD, job.model);
  EXPECT_EQ(pieces.size(), 1u);
  return pieces.at(0).free_modes;
}

/// The free rotation axes described as "rotation about the axis through (p) along (a)".
std::vector<std::pair<Eigen::Vector3d, Eigen::Vector3d>> axes(const std::string& modes) {
  std::vector<std::pair<Eigen::Vector3d, Eigen::Vector3d>> out;
  const std::regex re(
      R"(rotation about the axis through \(([-0-9.e]+), ([-0-9.e]+), ([-0-9.e]+)\) along \(([-0-9.e]+), ([-0-9.e]+), ([-0-9.e]+)\))");
  for (std::sregex_iterator it(modes.begin(), modes.end(), re), end; it != end; ++it) {
    const auto& m = *it;
    out.push_back({{std::stod(m[1]), std::stod(m[2]), std::stod(m[3])},
                   {std::stod(m[4]), std::stod(m[5]), std::stod(m[6])}});
  }
  return out;
}

const char* kBase = "    - where: {plane: {point: [0, 0, 0], normal: [0, 0, 1]}}\n";

TEST(Supports, ClampedBaseHoldsEverything) {
  EXPECT_EQ(free_modes(kBase), "");
}

TEST(Supports, RollerBaseLeavesInPlaneMotions) {
  EXPECT_EQ(free_modes(std::string(kBase).replace(std::string(kBase).size() - 1, 1,
                                                  "\n      components: [z]\n")),
            "translation x, y; rotation about z");
}

TEST(Supports, NoSupportLeavesAllSix) {
  Job job(PETSC_COMM_WORLD,
          "lattice: {h: 0.25, dims: [4, 4, 4]}\n"
          "materials: {m: {E: 1.0e6, nu: 0.3, rho: 1000}}\n"
          "geometry: [{add: {box: {min: [0, 0, 0], max: [1, 1, 1]}}}]\n"
          "analysis: {type: dynamic, dt: 0.1, steps: 1}\n"
          "solver: {type: cg-jacobi}\n");
  const auto pieces = analysis::find_pieces(PETSC_COMM_WORLD, job.model);
  ASSERT_EQ(pieces.size(), 1u);
  EXPECT_FALSE(pieces[0].supported);
  EXPECT_EQ(pieces[0].free_modes, "translation x, y, z; rotation about x, y, z");
}

TEST(Supports, HeldEdgeLeavesTheRotationAboutIt) {
  // Every vertex of the edge y = z = 0 fixed: the only free motion turns about it.
  const auto modes =
      free_modes("    - where: {box: {min: [-0.01, -0.01, -0.01], max: [1.01, 0.01, 0.01]}}\n");
  const auto a = axes(modes);
  ASSERT_EQ(a.size(), 1u) << modes;
  EXPECT_NEAR(a[0].first.y(), 0.0, 1e-3) << modes;
  EXPECT_NEAR(a[0].first.z(), 0.0, 1e-3) << modes;
  EXPECT_NEAR(a[0].second.x(), 1.0, 1e-3) << modes;
}

TEST(Supports, HeldCornerLeavesTheRotationsAboutIt) {
  // One vertex fixed in all components: three independent rotations, about axes through
  // it (p x a = 0 for an axis through the origin).
  const auto modes =
      free_modes("    - where: {box: {min: [-0.01, -0.01, -0.01], max: [0.01, 0.01, 0.01]}}\n");
  const auto a = axes(modes);
  ASSERT_EQ(a.size(), 3u) << modes;
  Eigen::Matrix3d directions;
  for (int i = 0; i < 3; ++i) {
    EXPECT_LT(a[i].first.cross(a[i].second).norm(), 1e-3) << modes;
    directions.col(i) = a[i].second;
  }
  EXPECT_GT(std::abs(directions.determinant()), 0.5) << modes;  // independent
}

TEST(Supports, PartlyHeldComponentsCombine) {
  // Roller base plus the vertices of the edge y = z = 0 held in y: x stays free.
  EXPECT_EQ(free_modes(std::string(kBase).replace(std::string(kBase).size() - 1, 1,
                                                  "\n      components: [z]\n") +
                       "    - where: {box: {min: [-0.01, -0.01, -0.01], max: [1.01, 0.01, "
                       "0.01]}}\n      components: [y]\n"),
            "translation x");
}

}  // namespace
}  // namespace hexcut::testing
