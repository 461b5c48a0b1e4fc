#include "mtcal/acquisition/csv.h"

#include <fmt/format.h>

#include <algorithm>
#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <numbers>
#include <set>
#include <sstream>

namespace mtcal::acquisition {

namespace {
constexpr double kLargestReading = 1e12;
}  // namespace

namespace {

constexpr std::size_t kDetectionRows = 20;
constexpr std::string_view kBlanks = " \t\r";

std::string trim(std::string_view s) {
  const auto b = s.find_first_not_of(kBlanks);
  if (b == std::string_view::npos) return {};
  return std::string(s.substr(b, s.find_last_not_of(kBlanks) - b + 1));
}

std::string lower(std::string_view s) {
  std::string out(s);
  for (auto& c : out) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return out;
}

/// Lower case, blanks and '_' runs as one '_', none at the ends.
std::string key(std::string_view s) {
  std::string out;
  for (const char c : lower(trim(s))) {
    if (c == ' ' || c == '\t' || c == '_') {
      if (!out.empty() && out.back() != '_') out.push_back('_');
    } else {
      out.push_back(c);
    }
  }
  while (!out.empty() && out.back() == '_') out.pop_back();
  return out;
}

std::string delimiterName(char c) {
  switch (c) {
    case '\t':
      return "tab";
    case ' ':
      return "space";
    default:
      return std::string(1, c);
  }
}

/// The delimiter's occurrences outside quoted cells.
std::size_t countOutsideQuotes(const std::string& text, char c) {
  std::size_t n = 0;
  bool quoted = false;
  for (const char ch : text) {
    if (ch == '"') quoted = !quoted;
    if (!quoted && ch == c) ++n;
  }
  return n;
}

bool digits(std::string_view s) {
  return !s.empty() && std::all_of(s.begin(), s.end(), [](unsigned char c) { return std::isdigit(c); });
}

/// `int<mark>frac[e[+-]exp]` with an optional sign and digits on both sides of the mark.
bool decimalWith(std::string_view s, char mark) {
  if (!s.empty() && (s[0] == '-' || s[0] == '+')) s.remove_prefix(1);
  const auto e = s.find_first_of("eE");
  if (e != std::string_view::npos) {
    auto exponent = s.substr(e + 1);
    if (!exponent.empty() && (exponent[0] == '-' || exponent[0] == '+')) exponent.remove_prefix(1);
    if (!digits(exponent)) return false;
    s = s.substr(0, e);
  }
  const auto m = s.find(mark);
  return m != std::string_view::npos && digits(s.substr(0, m)) && digits(s.substr(m + 1));
}

/// Whether `header` is the column a --columns mapping names: the same text, case and blanks
/// aside, or the same name with its unit left out ("Luftdruck" for "Luftdruck [hPa]").
bool isMapped(const std::string& header, const std::string& mapped) {
  if (header == mapped || key(header) == key(mapped)) return true;
  const CsvName m = csvName(mapped);
  return m.unit_text.empty() && csvName(header).base == m.base;
}

std::string shortened(const std::string& text) { return text.size() <= 40 ? text : text.substr(0, 37) + "..."; }

}  // namespace

CsvDialect CsvDialect::fromOptions(const std::string& delimiter, const std::string& decimal,
                                   const std::vector<std::string>& columns) {
  CsvDialect d;
  const std::string del = lower(delimiter);
  if (del.empty() || del == "auto") {
    d.delimiter = 0;
  } else if (del == "," || del == "comma") {
    d.delimiter = ',';
  } else if (del == ";" || del == "semicolon") {
    d.delimiter = ';';
  } else if (del == "tab" || del == "\\t" || del == "\t") {
    d.delimiter = '\t';
  } else if (del == "|" || del == "pipe") {
    d.delimiter = '|';
  } else if (del == "space" || del == " ") {
    d.delimiter = ' ';
  } else {
    throw InputError("--delimiter must be one of , ; tab | space (or auto), got '" + delimiter + "'");
  }
  if (decimal.empty() || decimal == "auto") {
    d.decimal = 0;
  } else if (decimal == "." || decimal == ",") {
    d.decimal = decimal[0];
  } else {
    throw InputError("--decimal must be . or , (or auto), got '" + decimal + "'");
  }
  if (d.delimiter == ',' && d.decimal == ',')
    throw InputError("--decimal , needs another separator than ',' (--delimiter ';' or tab)");
  for (const auto& list : columns) {
    std::size_t start = 0;
    while (start <= list.size()) {
      auto end = list.find(',', start);
      if (end == std::string::npos) end = list.size();
      const std::string pair = list.substr(start, end - start);
      const auto eq = pair.find('=');
      const std::string name = eq == std::string::npos ? "" : trim(pair.substr(0, eq));
      const std::string header = eq == std::string::npos ? "" : trim(pair.substr(eq + 1));
      if (name.empty() || header.empty())
        throw InputError("--columns takes NAME=HEADER pairs (target_mm=Position,deviation_um=Error), got '" + pair +
                         "'");
      if (!d.columns.emplace(name, header).second) throw InputError("--columns names '" + name + "' twice");
      start = end + 1;
    }
  }
  return d;
}

std::optional<CsvUnit> csvUnit(std::string_view written) {
  constexpr double kArcsec = std::numbers::pi / 648000.0;
  static const std::map<std::string, CsvUnit> kUnits = {
      {"nm", {"length", 1e-9}},
      {"um", {"length", 1e-6}},
      {"µm", {"length", 1e-6}},
      {"μm", {"length", 1e-6}},
      {"micron", {"length", 1e-6}},
      {"microns", {"length", 1e-6}},
      {"mm", {"length", 1e-3}},
      {"m", {"length", 1.0}},
      {"rad", {"angle", 1.0}},
      {"mrad", {"angle", 1e-3}},
      {"urad", {"angle", 1e-6}},
      {"µrad", {"angle", 1e-6}},
      {"μrad", {"angle", 1e-6}},
      {"arcsec", {"angle", kArcsec}},
      {"asec", {"angle", kArcsec}},
      {"\"", {"angle", kArcsec}},
      {"deg", {"angle", std::numbers::pi / 180.0}},
      {"°", {"angle", std::numbers::pi / 180.0}},
      {"mm/m", {"angle", 1e-3}},
      {"um/m", {"angle", 1e-6}},
      {"µm/m", {"angle", 1e-6}},
      {"μm/m", {"angle", 1e-6}},
      {"c", {"temperature", 1.0}},
      {"degc", {"temperature", 1.0}},
      {"°c", {"temperature", 1.0}},
      {"s", {"time", 1.0}},
      {"ms", {"time", 1e-3}},
      {"min", {"time", 60.0}},
      {"h", {"time", 3600.0}},
      {"pa", {"pressure", 1.0}},
      {"hpa", {"pressure", 100.0}},
      {"mbar", {"pressure", 100.0}},
      {"kpa", {"pressure", 1000.0}},
      {"pct", {"fraction", 1.0}},
      {"%", {"fraction", 1.0}},
      {"%rh", {"fraction", 1.0}},
      {"rpm", {"speed", 1.0}},
  };
  std::string k;
  for (const char c : lower(trim(written)))
    if (c != ' ') k.push_back(c);
  const auto it = kUnits.find(k);
  if (it == kUnits.end()) return std::nullopt;
  return it->second;
}

CsvName csvName(std::string_view header) {
  const std::string text = trim(header);
  CsvName n;
  auto take = [&](std::size_t unit_begin, std::size_t unit_end, std::size_t base_end) {
    n.unit_text = trim(std::string_view(text).substr(unit_begin, unit_end - unit_begin));
    n.unit = csvUnit(n.unit_text);
    n.base = key(std::string_view(text).substr(0, base_end));
  };
  if (!text.empty() && (text.back() == ']' || text.back() == ')')) {
    const char open = text.back() == ']' ? '[' : '(';
    const auto o = text.rfind(open);
    if (o != std::string::npos && o > 0) {
      take(o + 1, text.size() - 1, o);
      return n;
    }
  }
  if (const auto slash = text.find('/'); slash != std::string::npos && slash > 0) {
    if (csvUnit(std::string_view(text).substr(slash + 1))) {
      take(slash + 1, text.size(), slash);
      return n;
    }
  }
  n.base = key(text);
  if (const auto u = n.base.rfind('_'); u != std::string::npos && u > 0) {
    if (const auto unit = csvUnit(std::string_view(n.base).substr(u + 1))) {
      n.unit_text = n.base.substr(u + 1);
      n.unit = unit;
      n.base.resize(u);
    }
  }
  return n;
}

CsvReader::CsvReader(std::istream& in, std::string source, CsvDialect dialect)
    : in_(in), source_(std::move(source)), dialect_(std::move(dialect)) {
  const auto header = nextLine();
  if (!header) throw InputError(source_ + ": empty file, expected a header line");
  header_line_ = header->number;
  std::string header_text = header->text;
  // Excel's "sep=;" first line names the separator.
  if (header_text.size() == 5 && lower(header_text.substr(0, 4)) == "sep=") {
    if (!dialect_.delimiter) dialect_.delimiter = header_text[4];
    const auto next = nextLine();
    if (!next) throw InputError(source_ + ": no header line after '" + header_text + "'");
    header_line_ = next->number;
    header_text = next->text;
  }
  std::vector<Line> rows;
  while (rows.size() < kDetectionRows) {
    auto l = nextLine();
    if (!l) break;
    rows.push_back(std::move(*l));
  }
  delimiter_ = dialect_.delimiter;
  if (!delimiter_) {
    // The first separator found the same number of times in the header and every row read;
    // else the one the header has most of.
    std::size_t most = 0;
    delimiter_ = ',';
    for (const char c : {'\t', ';', ',', '|'}) {
      const std::size_t n = countOutsideQuotes(header_text, c);
      if (n == 0) continue;
      if (std::all_of(rows.begin(), rows.end(), [&](const Line& r) { return countOutsideQuotes(r.text, c) == n; })) {
        delimiter_ = c;
        most = std::numeric_limits<std::size_t>::max();
        break;
      }
      if (n > most) {
        most = n;
        delimiter_ = c;
      }
    }
  }
  header_ = split(header_text, header_line_);
  while (!header_.empty() && header_.back().empty()) header_.pop_back();
  for (std::size_t i = 0; i < header_.size(); ++i) {
    if (header_[i].empty()) throw InputError(fmt::format("{}:{}: column {} has no name", source_, header_line_, i + 1));
    for (std::size_t j = 0; j < i; ++j) {
      if (key(header_[j]) == key(header_[i]))
        throw InputError(fmt::format("{}:{}: column '{}' appears twice", source_, header_line_, header_[i]));
    }
  }
  claimed_.assign(header_.size(), false);
  for (const auto& [name, mapped] : dialect_.columns) {
    const bool found =
        std::any_of(header_.begin(), header_.end(), [&](const std::string& h) { return isMapped(h, mapped); });
    if (!found) {
      throw InputError(fmt::format("{}:{}: --columns {}={}: the header has no column '{}' (it has '{}')", source_,
                                   header_line_, name, mapped, mapped, fmt::join(header_, "', '")));
    }
  }
  detect(rows);
  buffered_ = std::move(rows);
}

void CsvReader::detect(const std::vector<Line>& rows) {
  decimal_ = dialect_.decimal;
  if (decimal_ == ',' && delimiter_ == ',') {
    throw InputError(fmt::format("{}: the decimal mark ',' needs another separator than ',' (--delimiter)", source_));
  }
  if (decimal_) return;
  decimal_ = '.';
  if (delimiter_ == ',') return;
  int comma_line = 0, point_line = 0;
  std::string comma_cell, point_cell;
  for (const auto& r : rows) {
    for (const auto& cell : split(r.text, r.number)) {
      if (!comma_line && decimalWith(cell, ',')) {
        comma_line = r.number;
        comma_cell = cell;
      }
      if (!point_line && decimalWith(cell, '.')) {
        point_line = r.number;
        point_cell = cell;
      }
    }
  }
  if (comma_line && point_line) {
    throw InputError(fmt::format(
        "{}: line {} writes '{}' with a decimal comma, line {} '{}' with a decimal point: say which with --decimal",
        source_, comma_line, comma_cell, point_line, point_cell));
  }
  if (comma_line) {
    decimal_ = ',';
    decimal_evidence_line_ = comma_line;
  }
}

std::optional<CsvReader::Line> CsvReader::nextLine() {
  std::string text;
  while (std::getline(in_, text)) {
    ++file_line_;
    if (file_line_ == 1) {
      if (text.size() >= 2 && ((text[0] == '\xFF' && text[1] == '\xFE') || (text[0] == '\xFE' && text[1] == '\xFF')))
        throw InputError(source_ + ": UTF-16 text; save it as UTF-8 (Excel: \"CSV UTF-8\")");
      if (text.rfind("\xEF\xBB\xBF", 0) == 0) text.erase(0, 3);
    }
    while (!text.empty() && text.back() == '\r') text.pop_back();  // CRLF, or CR CR LF (a Windows writer's twice)
    // A control character (but the tab) is no text's: a binary file, whose bytes an error
    // quoting the line would print as they are.
    const auto control = std::find_if(text.begin(), text.end(), [](char c) {
      const auto byte = static_cast<unsigned char>(c);
      return (byte < 0x20 && c != '\t') || byte == 0x7F;
    });
    if (control != text.end()) {
      const auto byte = static_cast<unsigned char>(*control);
      throw InputError(fmt::format(
          "{}:{}: byte {} of the line is 0x{:02X}, a control character: {}", source_, file_line_,
          control - text.begin() + 1, byte,
          byte == '\r' ? "lines ended by a carriage return alone (an old Mac text file)? save it with LF or CRLF "
                         "line ends"
          : byte == 0  ? "UTF-16 text without a byte-order mark, or not a text file? save it as UTF-8 (Excel: "
                         "\"CSV UTF-8\")"
                       : "not a text file (a CSV file is text)"));
    }
    const std::string t = trim(text);
    if (!t.empty() && t[0] != '#') return Line{file_line_, text};
  }
  return std::nullopt;
}

std::vector<std::string> CsvReader::split(const std::string& text, int line) const {
  std::vector<std::string> cells;
  std::string cell;
  bool quoted = false, was_quoted = false;
  auto push = [&] {
    cells.push_back(was_quoted ? cell : trim(cell));
    cell.clear();
    was_quoted = false;
  };
  for (std::size_t i = 0; i < text.size(); ++i) {
    const char c = text[i];
    if (quoted) {
      if (c == '"' && i + 1 < text.size() && text[i + 1] == '"') {
        cell.push_back('"');
        ++i;
      } else if (c == '"') {
        quoted = false;
      } else {
        cell.push_back(c);
      }
    } else if (c == '"' && trim(cell).empty()) {
      quoted = was_quoted = true;
      cell.clear();
    } else if (delimiter_ == ' ' ? (c == ' ' || c == '\t') : c == delimiter_) {
      if (delimiter_ == ' ' && trim(cell).empty() && !was_quoted) continue;  // a run of blanks
      push();
    } else if (!(was_quoted && (c == ' ' || c == '\t' || c == '\r'))) {
      cell.push_back(c);
    }
  }
  if (quoted) {
    throw InputError(
        fmt::format("{}:{}: a quoted cell is not closed: its '\"' has no closing '\"' on the line", source_, line));
  }
  if (!(delimiter_ == ' ' && trim(cell).empty() && !was_quoted)) push();
  return cells;
}

std::optional<CsvColumn> CsvReader::find(const std::string& name, const std::string& unit_if_none) {
  const CsvName wanted = csvName(name);
  std::optional<CsvUnit> default_unit;
  if (!unit_if_none.empty()) {
    default_unit = csvUnit(unit_if_none);
    if (!default_unit || !wanted.unit || default_unit->quantity != wanted.unit->quantity)
      throw InputError(fmt::format("{}: '{}' is not a unit of '{}'", source_, unit_if_none, name));
  }
  std::vector<std::size_t> matches;
  const auto mapped = std::find_if(dialect_.columns.begin(), dialect_.columns.end(),
                                   [&](const auto& m) { return key(m.first) == key(name); });
  asked_.push_back(name);
  for (std::size_t i = 0; i < header_.size(); ++i) {
    if (mapped != dialect_.columns.end()) {
      if (isMapped(header_[i], mapped->second)) matches.push_back(i);
      continue;
    }
    const CsvName h = csvName(header_[i]);
    if (h.base == wanted.base && h.unit_text.empty() && default_unit) {
      matches.push_back(i);
      continue;
    }
    if (h.base != wanted.base || h.unit_text.empty() != wanted.unit_text.empty()) continue;
    if (!h.unit_text.empty() && (!h.unit || !wanted.unit || h.unit->quantity != wanted.unit->quantity)) continue;
    matches.push_back(i);
  }
  if (matches.empty()) return std::nullopt;
  if (matches.size() > 1) {
    throw InputError(fmt::format("{}:{}: columns '{}' and '{}' both read as '{}' (--columns {}=HEADER says which)",
                                 source_, header_line_, header_[matches[0]], header_[matches[1]], name, name));
  }
  CsvColumn column{matches[0], header_[matches[0]], 1.0};
  if (wanted.unit_text == "um") column.largest = kLargestDeviationUm;
  const CsvName h = csvName(column.header);
  if (h.unit_text.empty() && default_unit) {
    column.factor = default_unit->si / wanted.unit->si;
  } else if (!h.unit_text.empty() && wanted.unit) {
    if (!h.unit || h.unit->quantity != wanted.unit->quantity) {
      throw InputError(fmt::format("{}:{}: column '{}' for '{}': '{}' is not a unit of {}", source_, header_line_,
                                   column.header, name, h.unit_text, wanted.unit->quantity));
    }
    column.factor = h.unit->si / wanted.unit->si;
  }
  claimed_[column.index] = true;
  return column;
}

CsvColumn CsvReader::require(const std::string& name, const std::string& need, const std::string& unit_if_none) {
  if (auto c = find(name, unit_if_none)) return *c;
  const std::string where = fmt::format("{}:{}: missing column '{}' (need {})", source_, header_line_, name, need);
  if (header_.size() == 1) {
    for (const char c : {';', '\t', ',', '|'}) {
      if (header_[0].find(c) != std::string::npos) {
        throw InputError(fmt::format("{}: the header has 1 column '{}': is '{}' the separator? use --delimiter '{}'",
                                     where, shortened(header_[0]), delimiterName(c), delimiterName(c)));
      }
    }
  }
  const CsvName wanted = csvName(name);
  for (const auto& h : header_) {
    const CsvName n = csvName(h);
    if (n.base != wanted.base) continue;
    if (n.unit_text.empty()) {
      throw InputError(fmt::format("{}: column '{}' has no unit; write it '{} [{}]' or map it with --columns {}={}",
                                   where, h, h, wanted.unit_text, name, h));
    }
    if (!n.unit) {
      throw InputError(fmt::format("{}: column '{}': unknown unit '{}'; map it with --columns {}={} if it is {}", where,
                                   h, n.unit_text, name, h, wanted.unit_text.empty() ? "it" : wanted.unit_text));
    }
  }
  throw InputError(fmt::format("{}; the header has '{}' (separator '{}'): map one with --columns {}=HEADER", where,
                               fmt::join(header_, "', '"), delimiterName(delimiter_), name));
}

void CsvReader::refuseUnusedMappings() const {
  for (const auto& [name, mapped] : dialect_.columns) {
    if (std::none_of(asked_.begin(), asked_.end(), [&](const std::string& a) { return key(a) == key(name); })) {
      throw InputError(fmt::format("{}: --columns {}={}: this file's format has no column '{}' (it reads {})", source_,
                                   name, mapped, name, fmt::join(asked_, ", ")));
    }
  }
}

std::vector<std::size_t> CsvReader::unclaimed() const {
  std::vector<std::size_t> out;
  for (std::size_t i = 0; i < header_.size(); ++i)
    if (!claimed_[i]) out.push_back(i);
  return out;
}

std::optional<std::vector<std::string>> CsvReader::row() {
  std::optional<Line> l;
  if (next_buffered_ < buffered_.size()) {
    l = buffered_[next_buffered_++];
  } else {
    buffered_.clear();
    next_buffered_ = 0;
    l = nextLine();
  }
  if (!l) return std::nullopt;
  line_ = l->number;
  auto cells = split(l->text, l->number);
  if (cells.size() > header_.size() && std::all_of(cells.begin() + static_cast<std::ptrdiff_t>(header_.size()),
                                                   cells.end(), [](const std::string& c) { return c.empty(); }))
    cells.resize(header_.size());
  if (cells.size() != header_.size()) {
    throw InputError(fmt::format("{}:{}: {} fields, the header has {} (separator '{}')", source_, line_, cells.size(),
                                 header_.size(), delimiterName(delimiter_)));
  }
  return cells;
}

InputError CsvReader::error(const std::string& column, const std::string& why) const {
  return InputError(fmt::format("{}:{}: column '{}': {}", source_, line_, column, why));
}

std::optional<double> CsvReader::number(const std::vector<std::string>& cells, const CsvColumn& column) const {
  const std::string& cell = cells.at(column.index);
  if (cell.empty()) return std::nullopt;
  std::string text = cell;
  bool ok = true;
  if (decimal_ == ',') {
    if (text.find('.') != std::string::npos) ok = false;
    std::replace(text.begin(), text.end(), ',', '.');
  }
  if (!text.empty() && text[0] == '+') text.erase(0, 1);
  double value = 0.0;
  const char* end = text.data() + text.size();
  const auto [ptr, ec] = std::from_chars(text.data(), end, value);
  // A number beyond a double's range ('1e400') is one, too large; below it ('1e-400') it is 0.
  // (from_chars leaves the value alone there: the exponent's sign tells which.)
  if (ec == std::errc::result_out_of_range && ptr == end) {
    const auto e = text.find_first_of("eE");
    const bool below = e != std::string::npos && e + 1 < text.size() && text[e + 1] == '-';
    value = std::copysign(below ? 0.0 : std::numeric_limits<double>::infinity(), text[0] == '-' ? -1.0 : 1.0);
  }
  const bool parsed = ok && !text.empty() && (ec == std::errc() || ec == std::errc::result_out_of_range) &&
                      ptr == end && !std::isnan(value);
  if (parsed) {
    // Beyond 1e12 in any unit mtcal reads (1000 km in um, 30 000 years in s) is no measurement,
    // and its square overflows the sums of a fit of many readings.
    if (!(std::abs(value * column.factor) <= kLargestReading)) {
      throw error(column.header,
                  column.factor == 1.0 || std::isinf(value)
                      ? fmt::format("'{}' is beyond +-{:g}: not a measurement", cell, kLargestReading)
                      : fmt::format("'{}' is {:g} in the unit mtcal reads, beyond +-{:g}: not a measurement", cell,
                                    value * column.factor, kLargestReading));
    }
    if (column.largest > 0.0 && std::abs(value * column.factor) > column.largest) {
      throw error(column.header, fmt::format("'{}' is {:g} um, beyond +-{:g} mm: no machine's error, probe's reading "
                                             "or displacement (a column in nm read as um, or positions rather than "
                                             "deviations?)",
                                             cell, value * column.factor, 1e-3 * column.largest));
    }
    return value * column.factor;
  }
  std::string hint;
  if (decimal_ == '.' && cell.find(',') != std::string::npos) {
    hint = " (the decimal mark is '.'; give --decimal , if the file writes decimal commas)";
  } else if (decimal_ == ',' && cell.find('.') != std::string::npos) {
    hint = decimal_evidence_line_
               ? fmt::format(" (the decimal mark is ',' as line {} shows; give --decimal . if it is not)",
                             decimal_evidence_line_)
               : " (the decimal mark is ',')";
  }
  throw error(column.header, "'" + cell + "' is not a number" + hint);
}

double CsvReader::required(const std::vector<std::string>& cells, const CsvColumn& column) const {
  const auto v = number(cells, column);
  if (!v) throw error(column.header, "value missing");
  return *v;
}

std::ifstream openInputFile(const std::string& path) {
  if (path.empty()) throw InputError("a file name is needed, got ''");
  std::error_code error;
  if (std::filesystem::is_directory(path, error)) throw InputError(path + ": cannot open file: it is a directory");
  std::ifstream in(path);
  if (!in) throw InputError(path + ": cannot open file: " + std::strerror(errno));
  return in;
}

nlohmann::json parseJsonText(const std::string& text, const std::string& source) {
  // The keys of each object open, outermost first: a key given twice is refused (JSON keeps the
  // last without a word: "radius_mm": 100, "radius_mm": 50 ran a circle of 50 mm).
  std::vector<std::set<std::string>> keys;
  const nlohmann::json::parser_callback_t twice = [&](int, nlohmann::json::parse_event_t event,
                                                      nlohmann::json& parsed) {
    using Event = nlohmann::json::parse_event_t;
    if (event == Event::object_start) keys.emplace_back();
    if (event == Event::object_end && !keys.empty()) keys.pop_back();
    if (event == Event::key && !keys.empty() && !keys.back().insert(parsed.get<std::string>()).second) {
      throw InputError(fmt::format("{}: key '{}' is given twice in one object (which one is meant?)", source,
                                   parsed.get<std::string>()));
    }
    return true;
  };
  try {
    return nlohmann::json::parse(text, twice);
  } catch (const nlohmann::json::exception& e) {  // where the syntax breaks
    const std::string why = e.what();             // "[json.exception.parse_error.101] parse error at line 1, ..."
    const auto bracket = why.find("] ");
    throw InputError(source + ": not valid JSON: " + (bracket == std::string::npos ? why : why.substr(bracket + 2)));
  }
}

nlohmann::json readJsonFile(const std::string& path) {
  auto in = openInputFile(path);
  std::stringstream text;
  text << in.rdbuf();
  return parseJsonText(text.str(), path);
}

ColumnTable readColumnTable(std::istream& in, const std::string& source, const std::vector<std::string>& required,
                            const std::vector<std::string>& optional, const std::vector<std::string>& text,
                            const CsvDialect& dialect) {
  CsvReader reader(in, source, dialect);
  std::vector<std::string> all = required;
  all.insert(all.end(), text.begin(), text.end());
  const std::string need = fmt::format("{}", fmt::join(all, ", "));
  std::vector<std::pair<std::string, CsvColumn>> numbers, texts;
  for (const auto& name : required) numbers.emplace_back(name, reader.require(name, need));
  for (const auto& name : text) texts.emplace_back(name, reader.require(name, need));
  for (const auto& name : optional) {
    if (std::find(required.begin(), required.end(), name) != required.end()) continue;
    if (auto c = reader.find(name)) numbers.emplace_back(name, *c);
  }
  reader.refuseUnusedMappings();
  ColumnTable table;
  for (const auto& [name, c] : numbers) table.numbers[name];
  for (const auto& [name, c] : texts) table.texts[name];
  while (const auto row = reader.row()) {
    for (const auto& [name, c] : numbers) table.numbers[name].push_back(reader.required(*row, c));
    for (const auto& [name, c] : texts) {
      const std::string& cell = (*row)[c.index];
      if (cell.empty()) throw reader.error(c.header, "empty");
      table.texts[name].push_back(cell);
    }
    table.lines.push_back(reader.line());
  }
  if (table.lines.empty()) throw InputError(source + ": no data rows");
  return table;
}

std::map<std::string, std::vector<double>> readColumnsCsv(std::istream& in, const std::string& source,
                                                          const std::vector<std::string>& required,
                                                          const std::vector<std::string>& optional,
                                                          const CsvDialect& dialect) {
  return readColumnTable(in, source, required, optional, {}, dialect).numbers;
}

}  // namespace mtcal::acquisition
