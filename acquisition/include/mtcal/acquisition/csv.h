#pragma once
// Reading CSV files as people save them, shared by every import: the separator (',', ';', tab
// or '|') and the decimal mark ('.' or ',') are detected from the header and the first rows
// unless given, a UTF-8 byte-order mark is skipped, quoted cells ("a;b", "" for a quote) are
// read, '#' lines and blank lines are skipped, and trailing empty columns (a spreadsheet's
// ";;;") are ignored.
//
// Columns are asked for by mtcal's names ("target_mm", "deviation_um", "direction"). A header
// matches one case- and blank-insensitively ("Target mm", "TARGET_MM"), and a unit written in
// the header ("deviation [um]", "(µm)", "/ mm", "pitch [arcsec]", "[mm/m]") is converted to the
// unit of the name: a header with a unit of another quantity, or none where the name has one,
// does not match. A mapping (--columns target_mm=Position) names the file's column for any
// name; a mapped header without a unit is taken in the name's unit.

#include <fstream>
#include <istream>
#include <map>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "mtcal/error.h"

namespace mtcal::acquisition {

/// How a CSV file is written; what is left empty is detected from the file.
struct CsvDialect {
  char delimiter = 0;                          ///< ',', ';', '\t', '|' or ' ' (runs of blanks); 0: detect
  char decimal = 0;                            ///< '.' or ','; 0: detect
  std::map<std::string, std::string> columns;  ///< mtcal's column name -> the file's header

  /// From the command line's --delimiter (",", ";", "tab", "|", "space"), --decimal ("." or ",")
  /// and --columns ("name=HEADER,name=HEADER"). @throws InputError naming the option
  static CsvDialect fromOptions(const std::string& delimiter, const std::string& decimal,
                                const std::vector<std::string>& columns);
};

/// A unit as written in a header: the quantity it measures and its size in that quantity's
/// SI unit (length: m, angle: rad, time: s, pressure: Pa; temperature degC, fraction %, speed rpm).
struct CsvUnit {
  std::string quantity;
  double si = 1.0;
};
/// "um", "µm", "arcsec", "mm/m", "hPa", "°C" ...; nullopt when not a unit mtcal knows.
std::optional<CsvUnit> csvUnit(std::string_view text);

/// A header or column name split into its name (lower case, blanks as '_') and unit: from
/// "[unit]", "(unit)", "/ unit" at the end, or a last "_unit" part ("deviation_um").
struct CsvName {
  std::string base;
  std::string unit_text;  ///< as written; empty without a unit
  std::optional<CsvUnit> unit;
};
CsvName csvName(std::string_view header);

/// A machine's error, a probe's reading or a displacement beyond 100 mm is no such thing: a
/// column in nm read as um, or positions rather than deviations.
inline constexpr double kLargestDeviationUm = 1e5;

/// A column found in the header.
struct CsvColumn {
  std::size_t index = 0;
  std::string header;   ///< as written
  double factor = 1.0;  ///< the file's value times this is the value in the asked name's unit
  /// The largest magnitude in that unit a reading of it can have (0: 1e12 only): a machine's
  /// error, a probe's reading, a displacement (in um) within kLargestDeviationUm.
  double largest = 0.0;
};

class CsvReader {
 public:
  /// Reads up to the header and the first rows (for the detection). @throws InputError for an
  /// empty or UTF-16 file, or a mapping naming no column
  CsvReader(std::istream& in, std::string source, CsvDialect dialect = {});

  const std::string& source() const { return source_; }
  const std::vector<std::string>& header() const { return header_; }
  int headerLine() const { return header_line_; }
  char delimiter() const { return delimiter_; }
  char decimal() const { return decimal_; }

  /// The column for mtcal's `name`; nullopt when the file has none. With `unit_if_none` (a
  /// unit of the name's quantity), a header of the name without a unit is read in that unit.
  /// @throws InputError when two columns match it
  std::optional<CsvColumn> find(const std::string& name, const std::string& unit_if_none = "");
  /// As find; a missing column's error says what was read and how to name it. `need` lists
  /// the file format's columns for the message.
  /// @throws InputError "SOURCE:LINE: missing column 'name' (need ...): why"
  CsvColumn require(const std::string& name, const std::string& need, const std::string& unit_if_none = "");
  /// After every find(): a --columns mapping of a name the format does not read (a typo, or the
  /// wrong import) is an error, not a mapping silently unused. @throws InputError
  void refuseUnusedMappings() const;
  /// Header columns no find() or require() has returned, in file order.
  std::vector<std::size_t> unclaimed() const;

  /// The next data row (as many cells as the header); nothing at the end of the file.
  /// @throws InputError "SOURCE:LINE: N fields, the header has M"
  std::optional<std::vector<std::string>> row();
  int line() const { return line_; }  ///< of the row last returned

  /// The cell as a finite number in the asked name's unit; nullopt when the cell is empty.
  /// @throws InputError "SOURCE:LINE: column 'h': 'text' is not a number"
  std::optional<double> number(const std::vector<std::string>& cells, const CsvColumn& column) const;
  /// As number(); an empty cell is an error.
  double required(const std::vector<std::string>& cells, const CsvColumn& column) const;
  /// "SOURCE:LINE: column 'header': why" for the row last returned.
  InputError error(const std::string& column, const std::string& why) const;

 private:
  struct Line {
    int number;
    std::string text;
  };
  std::optional<Line> nextLine();
  /// The cells of line `line`'s `text`. @throws InputError where a quoted cell is not closed
  std::vector<std::string> split(const std::string& text, int line) const;
  void detect(const std::vector<Line>& rows);

  std::istream& in_;
  std::string source_;
  CsvDialect dialect_;
  std::vector<std::string> header_;
  int header_line_ = 0;
  char delimiter_ = ',';
  char decimal_ = '.';
  int decimal_evidence_line_ = 0;  ///< the row the decimal mark was detected from; 0: given or none seen
  std::vector<Line> buffered_;     ///< rows read for the detection, not yet returned
  std::size_t next_buffered_ = 0;
  int file_line_ = 0;
  int line_ = 0;
  std::vector<bool> claimed_;
  std::vector<std::string> asked_;  ///< the names find() was asked for
};

/// Numeric and text columns of a table, by mtcal's name, in row order; `lines` the file line of
/// each row.
struct ColumnTable {
  std::map<std::string, std::vector<double>> numbers;
  std::map<std::string, std::vector<std::string>> texts;
  std::vector<int> lines;
};

/// The table with these numeric columns (`required`, and `optional` where the header has
/// them) and text columns (`text`, required, cells non-empty); extra columns are ignored.
/// @throws InputError "SOURCE:LINE: column 'c': why"
ColumnTable readColumnTable(std::istream& in, const std::string& source, const std::vector<std::string>& required,
                            const std::vector<std::string>& optional, const std::vector<std::string>& text,
                            const CsvDialect& dialect = {});

/// A file opened for reading. @throws InputError "PATH: cannot open file: why" (no such file, a
/// directory, no permission)
std::ifstream openInputFile(const std::string& path);

/// A JSON text. @throws InputError "SOURCE: not valid JSON: parse error at line L, column C: why"
/// (a syntax error, a text cut short, a number beyond a double's range)
nlohmann::json parseJsonText(const std::string& text, const std::string& source);
/// A JSON file. @throws InputError naming it when it cannot be read (openInputFile) or is not JSON
nlohmann::json readJsonFile(const std::string& path);

/// Column name -> values in row order; optional columns are present only when the header
/// has them. @throws InputError "SOURCE:LINE: column 'c': why"
std::map<std::string, std::vector<double>> readColumnsCsv(std::istream& in, const std::string& source,
                                                          const std::vector<std::string>& required,
                                                          const std::vector<std::string>& optional = {},
                                                          const CsvDialect& dialect = {});

}  // namespace mtcal::acquisition
