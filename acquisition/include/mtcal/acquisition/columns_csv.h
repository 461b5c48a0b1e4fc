#pragma once
// A CSV file of numeric columns named by its header (points to predict, probe readings):
// columns in any order, extra columns ignored, '#' lines and blank lines skipped. A missing
// column, a short row or a cell that is not a finite number is reported with the line and the
// column, and nothing is returned.

#include <istream>
#include <map>
#include <string>
#include <vector>

namespace mtcal::acquisition {

/// Numeric and text columns of a table, by name, in row order; `lines` the file line of each row.
struct ColumnTable {
  std::map<std::string, std::vector<double>> numbers;
  std::map<std::string, std::vector<std::string>> texts;
  std::vector<int> lines;
};

/// The table with these numeric columns (`required`, and `optional` where the header has
/// them) and text columns (`text`, required, cells non-empty).
/// @throws InputError "SOURCE:LINE: column 'c': why"
ColumnTable readColumnTable(std::istream& in, const std::string& source, const std::vector<std::string>& required,
                            const std::vector<std::string>& optional, const std::vector<std::string>& text);

/// Column name -> values in row order; optional columns are present only when the header
/// has them. @throws InputError "SOURCE:LINE: column 'c': why"
std::map<std::string, std::vector<double>> readColumnsCsv(std::istream& in, const std::string& source,
                                                          const std::vector<std::string>& required,
                                                          const std::vector<std::string>& optional = {});

}  // namespace mtcal::acquisition
