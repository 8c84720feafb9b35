// Umbrella header of the element stage (doc/theory.md, "Elements" to "Stress"): reference Q1
// matrices, centre-point kinematics, corotation, stress recovery and Newmark coefficients.
#pragma once

#include "element/corotation.hpp"
#include "element/kinematics.hpp"
#include "element/newmark.hpp"
#include "element/reference.hpp"
#include "element/stress.hpp"
