#include "mtcal/processing/plane.h"

#include <cctype>

#include "mtcal/error.h"

namespace mtcal::processing {

PlaneAxes planeAxes(Plane plane) {
  switch (plane) {
    case Plane::kXY:
      return {0, 1, 2};
    case Plane::kZX:
      return {2, 0, 1};
    case Plane::kYZ:
      return {1, 2, 0};
  }
  return {0, 1, 2};
}

const char* planeName(Plane plane) { return plane == Plane::kXY ? "XY" : plane == Plane::kZX ? "ZX" : "YZ"; }

Plane parsePlane(const std::string& name) {
  std::string t;
  for (char c : name) t.push_back(static_cast<char>(std::toupper(static_cast<unsigned char>(c))));
  if (t == "XY") return Plane::kXY;
  if (t == "ZX") return Plane::kZX;
  // Not a synonym: the order fixes which way is counter-clockwise (ISO 230-4: seen from +Y,
  // from Z towards X), and a circle's directions and signs follow it.
  if (t == "XZ")
    throw InputError("plane 'XZ': this plane is named ZX (counter-clockwise from Z towards X, seen from +Y); give ZX");
  if (t == "YZ") return Plane::kYZ;
  throw InputError("plane '" + name + "' is not one of XY, YZ, ZX");
}

}  // namespace mtcal::processing
