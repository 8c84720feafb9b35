// A deck whose geometry is one scanner image, shared by the NIfTI and DICOM tests: the format
// comes from the file (no format key), and the keys the file's header answers are refused.
#pragma once

#include <gtest/gtest.h>

#include <Eigen/Core>
#include <string>

#include "common/errors.hpp"
#include "deck/deck.hpp"

namespace hexcut::geometry::test {

/// Parses `image: {file: FILE, threshold: 0, material: bone}` on the lattice of `bounds`
/// (a YAML pair of corners) and expects the image's spacing [m]; then the same image with
/// `spacing:` added must fail at that line (d.yaml:8) with `refusal` in the message.
inline void expect_image_deck(const std::string& bounds, const std::string& file,
                              const Eigen::Vector3d& spacing, const std::string& refusal) {
  const std::string head = "lattice: {h: 0.0005, bounds: " + bounds +
                           "}\n"
                           "materials: {bone: {E: 1.0e9, nu: 0.3, rho: 1900}}\n"
                           "geometry:\n"
                           "  - image:\n"
                           "      file: " +
                           file + "\n      threshold: 0\n      material: bone\n";
  const std::string analysis = "analysis: {type: dynamic, dt: 0.001, steps: 1}\n";
  const auto deck = hexcut::deck::parse_deck(head + analysis, "d.yaml");
  ASSERT_EQ(deck.geometry.size(), 1u);
  ASSERT_TRUE(deck.geometry[0].image);
  EXPECT_LT((deck.geometry[0].image->spacing - spacing).norm(), 1e-15);
  try {
    hexcut::deck::parse_deck(head + "      spacing: [1, 1, 1]\n" + analysis, "d.yaml");
    FAIL() << "no InputError";
  } catch (const hexcut::InputError& e) {
    const std::string m = e.what();
    EXPECT_NE(m.find("d.yaml:8:"), std::string::npos) << m;
    EXPECT_NE(m.find(refusal), std::string::npos) << m;
  }
}

}  // namespace hexcut::geometry::test
