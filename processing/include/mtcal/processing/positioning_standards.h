#pragma once
// A positioning run's figures under the standards calibration engineers are asked for: ISO 230-2
// (its editions and the national standards that adopt it), VDI/DGQ 3441 and ASME B5.54, each
// with its own quantities and names, computed from the per-target means and standard deviations
// of an ISO 230-2 evaluation. What is and is not verified of each: docs/linear-calibration.md.
// Pure functions, thread-safe.

#include <string>
#include <string_view>
#include <vector>

#include "mtcal/processing/iso230_2.h"

namespace mtcal::processing {

/// One quantity of a standard, um.
struct StandardFigure {
  std::string symbol;  ///< as the standard writes it: "E", "Ps max", ...
  std::string name;    ///< what it is, in words
  double value_um = 0.0;
};

struct StandardEvaluation {
  std::string standard;  ///< the name given to --standard: "iso230-2:2014", "vdi3441", ...
  std::string title;     ///< the document: "ISO 230-2:2014", "VDI/DGQ 3441:1977", ...
  /// How the definitions were checked: true when they are ISO 230-2's (checked against two
  /// independent implementations that quote its clauses), false when they come from secondary
  /// descriptions only.
  bool definitions_verified = false;
  std::string note;  ///< the edition adopted, or what could not be verified
  std::vector<StandardFigure> figures;

  /// @throws InputError when the standard has no such figure
  double value(std::string_view symbol) const;
};

/// The standards there are, as --standard takes them.
std::vector<std::string> positioningStandards();

/// `result`'s figures under `standard`. Figures that need both approach directions are left out
/// of a unidirectional run. @throws InputError naming the standards there are; VDI 3441 and ASME
/// B5.54 need both directions
StandardEvaluation evaluateStandard(const Iso230Result& result, std::string_view standard);

}  // namespace mtcal::processing
