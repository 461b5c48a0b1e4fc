// Beckhoff TwinCAT: NC PTP table-based position compensation (Tc2_MC2
// MC_TableBasedPositionCompensation: ST_PositionCompensationTableElement tables, the additive
// compensation in mm, one table per direction) as Structured Text declarations, and the
// TwinCAT CNC (ISG kernel) leadscrew error compensation list (kw.ssfk.*: the error, 0.1 um).
// Sources and what is not verified: docs/compensation.md.

#include <fmt/format.h>

#include <cmath>
#include <map>
#include <regex>
#include <sstream>

#include "compensation_text.h"
#include "mtcal/error.h"

namespace mtcal::processing::format_text {
namespace {

// --- NC PTP: Structured Text arrays of (Position, Compensation) with their parameters --------

ControllerFile writePtp(const CompensationTable& table, const AxisOfTable& axis) {
  equidistantStep(table, "TwinCAT NC PTP");
  const auto t = withPeriodEnd(table);
  const bool both = !t.bidirectional();
  std::vector<std::pair<std::string, const std::vector<double>*>> tables{{both ? "Both" : "Positive", &t.up_um}};
  if (!both) tables.push_back({"Negative", &t.down_um});
  ControllerFile f;
  f.extension = ".st";
  f.text = fmt::format(
      "(* axis {}: MC_TableBasedPositionCompensation tables (Tc2_MC2); Position: the uncorrected position (mm), "
      "Compensation: added to it (mm) *)\nVAR_GLOBAL\n",
      axis.name);
  for (const auto& [direction, values] : tables) {
    f.text += fmt::format("\taCompensation{}{} : ARRAY[1..{}] OF ST_PositionCompensationTableElement := [\n", axis.name,
                          direction, t.position.size());
    for (std::size_t i = 0; i < t.position.size(); ++i) {
      f.text += fmt::format("\t\t(Position := {:.6f}, Compensation := {:.6f}){}\n", t.position[i],
                            (*values)[i] / kUmPerMm + 0.0, i + 1 < t.position.size() ? "," : "");
    }
    f.text += fmt::format(
        "\t];\n\tstCompensation{0}{1}Parameter : ST_PositionCompensationTableParameter := (MinPosition := {2:.6f}, "
        "MaxPosition := {3:.6f}, NoOfTableElements := {4}, Direction := WorkDirection{1}, Modulo := {5});\n",
        axis.name, direction, t.position.front(), t.position.back(), t.position.size(), t.modulo ? "TRUE" : "FALSE");
  }
  f.text += "END_VAR\n";
  f.setup = fmt::format(
      "(* one MC_TableBasedPositionCompensation instance per table, for axis {0}: pTable := ADR(aCompensation{0}...), "
      "TableSize := SIZEOF(aCompensation{0}...), TableParameter := stCompensation{0}...Parameter, Enable := TRUE *)\n",
      axis.name);
  return f;
}

CompensationTable readPtp(std::string_view text, const std::string& source) {
  static const std::regex kArray(R"(\s*aCompensation\w*\s*:\s*ARRAY\s*\[\s*1\s*\.\.\s*(\d{1,6})\s*\].*:=\s*\[\s*)");
  static const std::regex kElement(
      R"(\s*\(\s*Position\s*:=\s*([^,]+?)\s*,\s*Compensation\s*:=\s*([^)]+?)\s*\)\s*,?\s*)");
  static const std::regex kParameter(
      R"(\s*stCompensation\w*\s*:.*Direction\s*:=\s*WorkDirection(\w+)\s*,\s*Modulo\s*:=\s*(TRUE|FALSE)\s*\)\s*;\s*)");
  static const std::regex kPass(R"(\s*(VAR_GLOBAL|END_VAR|\];|\(\*.*\*\))?\s*)");
  struct Read {
    std::size_t declared = 0;
    std::vector<double> position, um;
    std::string direction;
    bool modulo = false;
  };
  std::vector<Read> tables;
  const auto lines = linesOf(text);
  for (std::size_t i = 0; i < lines.size(); ++i) {
    std::smatch m;
    if (std::regex_match(lines[i], m, kArray)) {
      tables.push_back({static_cast<std::size_t>(numberOf(m[1].str(), source, i + 1)), {}, {}, "", false});
    } else if (std::regex_match(lines[i], m, kElement)) {
      if (tables.empty()) throw InputError(fmt::format("{}: line {}: an element outside an array", source, i + 1));
      tables.back().position.push_back(numberOf(m[1].str(), source, i + 1));
      tables.back().um.push_back(numberOf(m[2].str(), source, i + 1) * kUmPerMm);
    } else if (std::regex_match(lines[i], m, kParameter)) {
      if (tables.empty()) throw InputError(fmt::format("{}: line {}: parameters without a table", source, i + 1));
      tables.back().direction = m[1];
      tables.back().modulo = m[2] == "TRUE";
    } else if (!std::regex_match(lines[i], kPass)) {
      throw InputError(fmt::format("{}: line {}: '{}' is not part of a compensation table", source, i + 1, lines[i]));
    }
  }
  CompensationTable t;
  bool up = false, down = false;
  for (const auto& r : tables) {
    if (r.um.size() != r.declared)
      throw InputError(fmt::format("{}: an array of {} elements holds {}", source, r.declared, r.um.size()));
    if (!t.position.empty() && r.position != t.position)
      throw InputError(fmt::format("{}: the {} table has other positions than the first", source, r.direction));
    t.position = r.position;
    if (r.direction == "Both" || r.direction == "Positive") t.up_um = r.um, up = true;
    if (r.direction == "Both" || r.direction == "Negative") t.down_um = r.um, down = true;
    if (r.direction != "Both" && r.direction != "Positive" && r.direction != "Negative")
      throw InputError(fmt::format("{}: a table without its Direction parameter", source));
  }
  if (!up || !down)
    throw InputError(fmt::format("{}: no table for the {} direction", source, up ? "negative" : "positive"));
  equidistantStep(t, source);
  return closedTable(t, tables.front().modulo, source);
}

// --- TwinCAT CNC (ISG): the axis compensation list, kw.ssfk.*, positions and errors in 0.1 um --

constexpr double kIsgUnitUm = 0.1;
constexpr std::size_t kIsgMaxPoints = 1500;  ///< P-COMP-00059 max_points, its default

long isgUnits(double um) { return std::lround(um / kIsgUnitUm); }

ControllerFile writeIsg(const CompensationTable& t, const AxisOfTable& axis) {
  if (t.modulo) throw InputError("TwinCAT CNC: mtcal writes lists of linear axes only (no modulo)");
  if (t.position.size() > kIsgMaxPoints)
    throw InputError(fmt::format("TwinCAT CNC: {} entries, the list takes at most {} (P-COMP-00059)", t.position.size(),
                                 kIsgMaxPoints));
  const double step = equidistantStep(t, "TwinCAT CNC");
  const bool bilateral = t.bidirectional();
  ControllerFile f;
  f.extension = ".lis";
  f.text = fmt::format(
      "kopf.log_achs_nr {}\nkopf.log_achs_name {}\nkw.ssfk.interval {}\nkw.ssfk.kw_startpos {}\n"
      "kw.ssfk.kw_nr_max {}\nkw.ssfk.unit 1\nkw.ssfk.bilateral {}\n",
      axis.index + 1, axis.name, isgUnits(step * kUmPerMm), isgUnits(t.position.front() * kUmPerMm), t.position.size(),
      bilateral ? 1 : 0);
  // The error, actual - nominal: the negative of the correction.
  for (std::size_t i = 0; i < t.position.size(); ++i)
    f.text += fmt::format("kw.ssfk.table[{}].pos {}\n", i, -isgUnits(t.up_um[i]));
  if (bilateral)
    for (std::size_t i = 0; i < t.position.size(); ++i)
      f.text += fmt::format("kw.ssfk.table[{}].neg {}\n", i, -isgUnits(t.down_um[i]));
  f.setup = fmt::format(
      "axis {} (logical axis {}): axis parameter lr_param.ssfk 1 (P-AXIS-00175); the list is read at start-up; "
      "active once the axis is homed, switched by X[COMP ON LEAD] / X[COMP OFF LEAD]\n",
      axis.name, axis.index + 1);
  return f;
}

CompensationTable readIsg(std::string_view text, const std::string& source) {
  static const std::regex kTable(R"(kw\.ssfk\.table\[(\d{1,6})\]\.(pos|neg))");
  std::map<std::string, double> key;
  std::map<std::size_t, double> pos, neg;
  const auto lines = linesOf(text);
  for (std::size_t i = 0; i < lines.size(); ++i) {
    std::istringstream in(lines[i]);
    std::string name, value, more;
    if (!(in >> name)) continue;
    if (name.rfind("#", 0) == 0) continue;
    if (!(in >> value) || (in >> more))
      throw InputError(fmt::format("{}: line {}: '{}' is not a keyword and one value", source, i + 1, lines[i]));
    std::smatch m;
    if (std::regex_match(name, m, kTable)) {
      auto& side = m[2] == "pos" ? pos : neg;
      if (!side.emplace(std::stoul(m[1]), numberOf(value, source, i + 1)).second)
        throw InputError(fmt::format("{}: line {}: {} given twice", source, i + 1, name));
    } else if (name == "kopf.log_achs_name") {
      continue;
    } else {
      key[name] = numberOf(value, source, i + 1);
    }
  }
  const auto need = [&](const char* name) {
    const auto it = key.find(name);
    if (it == key.end()) throw InputError(fmt::format("{}: {} is missing", source, name));
    return it->second;
  };
  if (need("kw.ssfk.unit") != 1.0)
    throw InputError(
        fmt::format("{}: kw.ssfk.unit {:g}: mtcal reads lists in 0.1 um (unit 1)", source, need("kw.ssfk.unit")));
  const double entries = need("kw.ssfk.kw_nr_max");
  if (!(entries >= 2.0 && entries <= static_cast<double>(kIsgMaxPoints)) || entries != std::floor(entries)) {
    throw InputError(
        fmt::format("{}: kw.ssfk.kw_nr_max {:g}: a list has 2 to {} entries", source, entries, kIsgMaxPoints));
  }
  const auto count = static_cast<std::size_t>(entries);
  const double interval = need("kw.ssfk.interval");
  if (interval <= 0.0)
    throw InputError(fmt::format("{}: kw.ssfk.interval {:g}: mtcal reads equidistant lists", source, interval));
  const bool bilateral = need("kw.ssfk.bilateral") != 0.0;
  const auto values = [&](const std::map<std::size_t, double>& side, const char* name) {
    if (side.size() != count || (count > 0 && side.rbegin()->first != count - 1))
      throw InputError(fmt::format("{}: {} {} values for kw_nr_max {}", source, side.size(), name, count));
    std::vector<double> um;
    for (const auto& [i, v] : side) um.push_back(-v * kIsgUnitUm + 0.0);
    return um;
  };
  CompensationTable t;
  t.position =
      gridPositions(need("kw.ssfk.kw_startpos") * kIsgUnitUm / kUmPerMm, interval * kIsgUnitUm / kUmPerMm, count);
  t.up_um = values(pos, "pos");
  t.down_um = bilateral ? values(neg, "neg") : t.up_um;
  if (!bilateral && !neg.empty())
    throw InputError(fmt::format("{}: neg values in a list that is not bilateral", source));
  checkTable(t, source.c_str());
  return t;
}

}  // namespace

ControllerFormat twincatPtpFormat() {
  return {"twincat-ptp",
          "TwinCAT NC PTP MC_TableBasedPositionCompensation tables (Structured Text): the additive compensation (mm), "
          "a table per direction",
          {true, true},
          0,
          0.0,
          writePtp,
          readPtp};
}

ControllerFormat twincatCncFormat() {
  return {
      "twincat-cnc", "TwinCAT CNC (ISG) leadscrew error compensation list kw.ssfk: the error (0.1 um) per direction",
      {true, true},  kIsgMaxPoints,
      kIsgUnitUm,    writeIsg,
      readIsg};
}

}  // namespace mtcal::processing::format_text
