#pragma once
// The CSV reading shared by the importers: comma-separated cells, surrounding blanks and a
// trailing CR removed. (Quoted cells are not supported: the formats mtcal reads have none.)

#include <fmt/format.h>

#include <charconv>
#include <cmath>
#include <istream>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "mtcal/error.h"

namespace mtcal::acquisition::csv {

inline std::string trim(std::string_view s) {
  const auto b = s.find_first_not_of(" \t\r");
  if (b == std::string_view::npos) return {};
  return std::string(s.substr(b, s.find_last_not_of(" \t\r") - b + 1));
}

/// The cell as a finite number; nullopt for anything else (empty, text, inf, nan).
inline std::optional<double> number(const std::string& text) {
  double value = 0.0;
  const char* end = text.data() + text.size();
  const auto [ptr, ec] = std::from_chars(text.data(), end, value);
  if (text.empty() || ec != std::errc() || ptr != end || !std::isfinite(value)) return std::nullopt;
  return value;
}

inline std::vector<std::string> split(const std::string& line) {
  std::vector<std::string> cells;
  std::size_t start = 0;
  for (;;) {
    const auto comma = line.find(',', start);
    cells.push_back(
        trim(std::string_view(line).substr(start, comma == std::string::npos ? std::string::npos : comma - start)));
    if (comma == std::string::npos) return cells;
    start = comma + 1;
  }
}

/// The rows of a CSV in order: '#' lines and blank lines skipped, the file's line numbers kept.
class Reader {
 public:
  Reader(std::istream& in, std::string source) : in_(in), source_(std::move(source)) {}
  /// The next row's cells; nothing at the end of the file.
  std::optional<std::vector<std::string>> next() {
    std::string text;
    while (std::getline(in_, text)) {
      ++line_;
      const std::string t = trim(text);
      if (!t.empty() && t[0] != '#') return split(t);
    }
    return std::nullopt;
  }
  /// The next data row, which must have as many cells as the header.
  /// @throws InputError "SOURCE:LINE: N fields, the header has M"
  std::optional<std::vector<std::string>> row(const std::vector<std::string>& header) {
    auto cells = next();
    if (cells && cells->size() != header.size()) {
      throw InputError(
          fmt::format("{}:{}: {} fields, the header has {}", source_, line_, cells->size(), header.size()));
    }
    return cells;
  }
  int line() const { return line_; }  ///< of the row last returned

 private:
  std::istream& in_;
  std::string source_;
  int line_ = 0;
};

}  // namespace mtcal::acquisition::csv
