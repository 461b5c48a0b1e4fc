// HEIDENHAIN TNC nonlinear axis error compensation: a *.COM table of the axis' error by
// position (column AXISPOS, the axis' own column for the positive direction, BACKLASH for the
// negative one) and the *.CMA assignment that activates it. Sources and what is not verified:
// docs/compensation.md.

#include <fmt/format.h>

#include <algorithm>
#include <sstream>

#include "compensation_text.h"
#include "mtcal/error.h"
#include "mtcal/processing/number_text.h"

namespace mtcal::processing::format_text {
namespace {

constexpr std::size_t kHeidenhainMaxEntries = 256;

std::vector<std::string> wordsOf(const std::string& line) {
  std::vector<std::string> words;
  std::istringstream in(line);
  for (std::string w; in >> w;) words.push_back(w);
  return words;
}

ControllerFile writeCom(const CompensationTable& t, const AxisOfTable& axis) {
  if (t.modulo) throw InputError("Heidenhain: mtcal writes tables of linear axes only (no modulo)");
  if (t.position.size() > kHeidenhainMaxEntries) {
    throw InputError(
        fmt::format("Heidenhain: {} entries, a table takes at most {}", t.position.size(), kHeidenhainMaxEntries));
  }
  ControllerFile f;
  f.extension = ".COM";
  const std::string name = axis.fileName(f.extension);
  f.text = fmt::format("BEGIN {} MM\n{:<6}{:<14}{:<14}{}\n", name, "NR", "AXISPOS", axis.name, "BACKLASH");
  for (std::size_t i = 0; i < t.position.size(); ++i) {
    // The error, actual - nominal: the negative of the correction.
    f.text += fmt::format("{:<6}{:<+14.5f}{:<+14.5f}{:+.5f}\n", i, t.position[i], roundedTo(-t.up_um[i] / kUmPerMm, 5),
                          roundedTo(-t.down_um[i] / kUmPerMm, 5));
  }
  f.text += "[END]\n";
  f.setup = fmt::format(
      "BEGIN CONFIG.CMA\n{0:<6}{1:<{4}}ACTIVE\n{2:<6}{3:<{4}}*\n[END]\n"
      "(the assignment table: column {1} holds the table of axis {1} as a function of its own position; ACTIVE * "
      "activates it)\n",
      "NR", axis.name, 0, name, std::max<std::size_t>(14, name.size() + 2));
  return f;
}

CompensationTable readCom(std::string_view text, const std::string& source) {
  const auto lines = linesOf(text);
  if (lines.empty() || wordsOf(lines[0]).size() < 2 || wordsOf(lines[0])[0] != "BEGIN")
    throw InputError(fmt::format("{}: line 1: a Heidenhain table starts with 'BEGIN name.COM'", source));
  const auto begin = wordsOf(lines[0]);
  if (begin.size() > 2 && begin[2] != "MM")
    throw InputError(fmt::format("{}: line 1: unit '{}': mtcal reads tables in MM", source, begin[2]));
  if (lines.size() < 2) throw InputError(fmt::format("{}: line 2: no column names", source));
  const auto columns = wordsOf(lines[1]);
  std::size_t position_column = columns.size(), value_column = columns.size(), backlash_column = columns.size();
  for (std::size_t c = 0; c < columns.size(); ++c) {
    if (columns[c] == "AXISPOS") {
      position_column = c;
    } else if (columns[c] == "BACKLASH") {
      backlash_column = c;
    } else if (columns[c] != "NR") {
      if (value_column != columns.size())
        throw InputError(
            fmt::format("{}: line 2: two axis columns ({} and {})", source, columns[value_column], columns[c]));
      value_column = c;
    }
  }
  if (position_column == columns.size() || value_column == columns.size())
    throw InputError(fmt::format("{}: line 2: the columns AXISPOS and the axis' own are needed", source));
  CompensationTable t;
  bool ended = false;
  for (std::size_t i = 2; i < lines.size(); ++i) {
    const auto words = wordsOf(lines[i]);
    if (words.empty()) continue;
    if (ended) throw InputError(fmt::format("{}: line {}: text after [END]", source, i + 1));
    if (words[0] == "[END]") {
      ended = true;
      continue;
    }
    if (words.size() != columns.size())
      throw InputError(
          fmt::format("{}: line {}: {} values for {} columns", source, i + 1, words.size(), columns.size()));
    t.position.push_back(numberOf(words[position_column], source, i + 1));
    t.up_um.push_back(-numberOf(words[value_column], source, i + 1) * kUmPerMm + 0.0);
    t.down_um.push_back(backlash_column == columns.size()
                            ? t.up_um.back()
                            : -numberOf(words[backlash_column], source, i + 1) * kUmPerMm + 0.0);
  }
  if (!ended) throw InputError(fmt::format("{}: no [END] line: the table is cut short", source));
  if (t.position.size() > kHeidenhainMaxEntries)
    throw InputError(
        fmt::format("{}: {} entries, a table takes at most {}", source, t.position.size(), kHeidenhainMaxEntries));
  checkTable(t, source.c_str());
  return t;
}

}  // namespace

ControllerFormat heidenhainFormat() {
  return {"heidenhain",
          "HEIDENHAIN TNC nonlinear axis error compensation *.COM (the error, mm; BACKLASH: moving negative) with its "
          "*.CMA",
          {true, true},
          kHeidenhainMaxEntries,
          0.0,
          writeCom,
          readCom};
}

}  // namespace mtcal::processing::format_text
