#pragma once
// Planes of the machine's axes, named as G-code selects them (G17 XY, G18 ZX, G19 YZ).

#include <string>

namespace mtcal::processing {

enum class Plane { kXY, kYZ, kZX };

/// Axis indices (0 X, 1 Y, 2 Z) of a plane: angles in it run from `first` toward `second`
/// (counter-clockwise seen from the + end of `normal`), as G2/G3 arcs in G17/G18/G19.
/// XY: (0, 1, 2); YZ: (1, 2, 0); ZX: (2, 0, 1).
struct PlaneAxes {
  int first, second, normal;
};
PlaneAxes planeAxes(Plane plane);
const char* planeName(Plane plane);         ///< "XY", "YZ", "ZX"
Plane parsePlane(const std::string& text);  ///< "XY", "YZ" or "ZX", any case. @throws InputError (naming ZX for "XZ")

}  // namespace mtcal::processing
