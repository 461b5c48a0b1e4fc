// SINUMERIK 840D sl compensation tables (Function Manual Extended Functions, K3 "Compensations"):
// leadscrew error compensation (%_N_AX_EEC_INI, one table for both directions) and
// direction-dependent compensation as a pair of CEC tables (%_N_NC_CEC_INI, one table per
// traversing direction of the axis itself). Sources and what is not verified: docs/compensation.md.

#include <fmt/format.h>

#include <cmath>
#include <map>
#include <optional>
#include <regex>

#include "compensation_text.h"
#include "mtcal/error.h"

namespace mtcal::processing::format_text {
namespace {

/// The general machine axis name of an axis (AX1 for the controller's first axis).
std::string machineAxis(const AxisOfTable& axis) { return fmt::format("AX{}", axis.index + 1); }

/// A Siemens INI file as the assignments it makes: `$NAME[i,j,AXn]=value` by name, with the
/// indices as written. Blank lines, `;` comments, the file's name line, CHANDATA and M17 pass.
struct Assignment {
  std::string name;
  std::vector<std::string> index;
  std::string value;
  std::size_t line = 0;
};

std::vector<Assignment> assignmentsOf(std::string_view text, const std::string& source, const std::string& header) {
  static const std::regex kAssign(R"(\s*\$(\w+)\[([^\]]*)\]\s*=\s*(.*?)\s*)");
  static const std::regex kPass(R"(\s*(CHANDATA\(\d+\)|M17|M30|M02)?\s*)");
  std::vector<Assignment> out;
  const auto lines = linesOf(text);
  if (lines.empty() || lines[0].rfind(header, 0) != 0)
    throw InputError(fmt::format("{}: line 1: a {} file starts with '{}'", source, header, header));
  for (std::size_t i = 1; i < lines.size(); ++i) {
    const std::string line = lines[i].substr(0, lines[i].find(';'));
    std::smatch m;
    if (std::regex_match(line, m, kAssign)) {
      Assignment a{m[1], {}, m[3], i + 1};
      std::string index = m[2];
      std::size_t from = 0;
      for (auto comma = index.find(',');; comma = index.find(',', from)) {
        auto part = index.substr(from, comma == std::string::npos ? std::string::npos : comma - from);
        part.erase(0, part.find_first_not_of(' '));
        part.erase(part.find_last_not_of(' ') + 1);
        a.index.push_back(part);
        if (comma == std::string::npos) break;
        from = comma + 1;
      }
      out.push_back(std::move(a));
    } else if (!std::regex_match(line, kPass)) {
      throw InputError(fmt::format("{}: line {}: '{}' is not an assignment the controller reads", source, i + 1, line));
    }
  }
  return out;
}

std::size_t indexOf(const Assignment& a, std::size_t k, const std::string& source) {
  const double v = numberOf(a.index.at(k), source, a.line);
  if (v < 0 || v != std::floor(v) || v > 1e6)
    throw InputError(fmt::format("{}: line {}: index '{}' is not a whole number", source, a.line, a.index.at(k)));
  return static_cast<std::size_t>(v);
}

/// One equidistant Siemens table as read: values by interpolation point, STEP, MIN, MAX, modulo.
struct GridTable {
  std::map<std::size_t, double> value_mm;
  std::optional<double> step, min, max;
  bool modulo = false;
  int direction = 0;
  std::string input_axis, output_axis;

  /// The values at MIN, MIN + STEP, ..., MAX, each point given once. @throws InputError
  std::vector<double> values(const std::string& source, const std::string& what) const {
    if (!step || !min || !max)
      throw InputError(fmt::format("{}: {}: _STEP, _MIN and _MAX are all needed", source, what));
    if (!(*step > 0.0)) throw InputError(fmt::format("{}: {}: _STEP {:g} is not positive", source, what, *step));
    const double intervals = (*max - *min) / *step;
    if (std::abs(intervals - std::round(intervals)) > 1e-6 || intervals < 1.0) {
      throw InputError(fmt::format("{}: {}: _MIN {:g} to _MAX {:g} is not a whole number of steps of {:g}", source,
                                   what, *min, *max, *step));
    }
    if (intervals + 1.0 > static_cast<double>(value_mm.size())) {
      throw InputError(
          fmt::format("{}: {}: _MIN {:g} to _MAX {:g} in steps of {:g} needs {:g} points, the table gives {}", source,
                      what, *min, *max, *step, std::round(intervals) + 1.0, value_mm.size()));
    }
    const auto count = static_cast<std::size_t>(std::round(intervals)) + 1;
    std::vector<double> v;
    for (std::size_t n = 0; n < count; ++n) {
      const auto it = value_mm.find(n);
      if (it == value_mm.end())
        throw InputError(
            fmt::format("{}: {}: no value for interpolation point {} (of 0 to {})", source, what, n, count - 1));
      v.push_back(it->second);
    }
    if (value_mm.size() > count)
      throw InputError(
          fmt::format("{}: {}: values beyond interpolation point {} (_MAX {:g})", source, what, count - 1, *max));
    return v;
  }
};

void readGridField(GridTable& g, const std::string& field, const Assignment& a, const std::string& source) {
  if (field.empty()) {
    const auto n = indexOf(a, 1, source);
    if (!g.value_mm.emplace(n, numberOf(a.value, source, a.line)).second)
      throw InputError(fmt::format("{}: line {}: interpolation point {} given twice", source, a.line, n));
  } else if (field == "_STEP") {
    g.step = numberOf(a.value, source, a.line);
  } else if (field == "_MIN") {
    g.min = numberOf(a.value, source, a.line);
  } else if (field == "_MAX") {
    g.max = numberOf(a.value, source, a.line);
  } else if (field == "_IS_MODULO") {
    g.modulo = numberOf(a.value, source, a.line) != 0.0;
  } else if (field == "_DIRECTION") {
    const double direction = numberOf(a.value, source, a.line);
    if (direction != -1.0 && direction != 0.0 && direction != 1.0)
      throw InputError(fmt::format("{}: line {}: _DIRECTION {}: 1, -1 or 0 (both)", source, a.line, a.value));
    g.direction = static_cast<int>(direction);
  } else if (field == "_INPUT_AXIS") {
    g.input_axis = a.value;
  } else if (field == "_OUTPUT_AXIS") {
    g.output_axis = a.value;
  } else if (field != "_MULT_BY_TABLE") {
    throw InputError(fmt::format("{}: line {}: unknown variable", source, a.line));
  }
}

// --- Leadscrew error compensation: $AA_ENC_COMP[e,N,AXn], the measured error in mm ------------

ControllerFile writeEec(const CompensationTable& table, const AxisOfTable& axis) {
  requireOneTable(table, "Siemens EEC (leadscrew error compensation)",
                  "--controller siemens-cec for a table per direction");
  const double step = equidistantStep(table, "Siemens EEC");
  const auto t = withPeriodEnd(table);
  const std::string ax = machineAxis(axis);
  ControllerFile f;
  f.extension = ".ini";
  f.text = fmt::format(
      "%_N_AX_EEC_INI\n"
      "; axis {} ({}): the measured error (actual - nominal position), mm; a positive value moves the axis "
      "negative\n"
      "CHANDATA(1)\n",
      axis.name, ax);
  for (std::size_t n = 0; n < t.position.size(); ++n)
    f.text += fmt::format("$AA_ENC_COMP[0,{},{}]={:.6f}\n", n, ax, -t.up_um[n] / kUmPerMm + 0.0);
  f.text += fmt::format(
      "$AA_ENC_COMP_STEP[0,{0}]={1:.6f}\n$AA_ENC_COMP_MIN[0,{0}]={2:.6f}\n$AA_ENC_COMP_MAX[0,{0}]={3:.6f}\n"
      "$AA_ENC_COMP_IS_MODULO[0,{0}]={4}\nM17\n",
      ax, step, t.position.front(), t.position.back(), t.modulo ? 1 : 0);
  f.setup = fmt::format(
      "; machine data of axis {0} ({1}), measuring system 1:\n"
      "; MD38000 $MA_MM_ENC_COMP_MAX_POINTS[0,{1}] >= {2} (then POWER ON: the memory is formatted)\n"
      "; MD32700 $MA_ENC_COMP_ENABLE[0,{1}] = 0 while the table is loaded, then 1; active once the axis is "
      "referenced\n",
      axis.name, ax, t.position.size());
  return f;
}

CompensationTable readEec(std::string_view text, const std::string& source) {
  GridTable g;
  std::string axis;
  for (const auto& a : assignmentsOf(text, source, "%_N_AX_EEC_INI")) {
    static const std::string kPrefix = "AA_ENC_COMP";
    if (a.name.rfind(kPrefix, 0) != 0)
      throw InputError(
          fmt::format("{}: line {}: ${} is not a leadscrew compensation variable", source, a.line, a.name));
    const std::string field = a.name.substr(kPrefix.size());
    const std::size_t axis_at = field.empty() ? 2 : 1;
    if (a.index.size() != axis_at + 1)
      throw InputError(fmt::format("{}: line {}: ${} takes {} indices", source, a.line, a.name, axis_at + 1));
    if (a.index[0] != "0") {
      throw InputError(
          fmt::format("{}: line {}: measuring system {} (index {}): mtcal reads measuring system 1's table", source,
                      a.line, indexOf(a, 0, source) + 1, a.index[0]));
    }
    if (axis.empty()) axis = a.index[axis_at];
    if (a.index[axis_at] != axis)
      throw InputError(
          fmt::format("{}: line {}: axis {} in a table of axis {}", source, a.line, a.index[axis_at], axis));
    readGridField(g, field, a, source);
  }
  const auto values = g.values(source, "the table");
  CompensationTable t;
  t.axis_in_file = axis;
  t.position = gridPositions(*g.min, *g.step, values.size());
  for (double v : values) t.up_um.push_back(-v * kUmPerMm + 0.0);
  t.down_um = t.up_um;
  return closedTable(t, g.modulo, source);
}

// --- Direction-dependent compensation: two CEC tables of the axis on itself, mm added ---------

ControllerFile writeCec(const CompensationTable& table, const AxisOfTable& axis) {
  const double step = equidistantStep(table, "Siemens CEC");
  const auto t = withPeriodEnd(table);
  const std::string ax = machineAxis(axis);
  const bool both = !t.bidirectional();
  const std::size_t first_table = static_cast<std::size_t>(axis.index) * 2;
  ControllerFile f;
  f.extension = ".ini";
  f.text = fmt::format(
      "%_N_NC_CEC_INI\n"
      "; axis {} ({}) on itself: the correction added to its position, mm; {}\n"
      "CHANDATA(1)\n",
      axis.name, ax,
      both ? "one table for both directions"
           : fmt::format("table {} moving positive, table {} moving negative", first_table, first_table + 1));
  std::vector<std::pair<int, const std::vector<double>*>> tables{{both ? 0 : 1, &t.up_um}};
  if (!both) tables.push_back({-1, &t.down_um});
  std::string enable;
  for (std::size_t k = 0; k < tables.size(); ++k) {
    const std::size_t number = first_table + k;
    for (std::size_t n = 0; n < t.position.size(); ++n)
      f.text += fmt::format("$AN_CEC[{},{}]={:.6f}\n", number, n, (*tables[k].second)[n] / kUmPerMm + 0.0);
    f.text += fmt::format(
        "$AN_CEC_INPUT_AXIS[{0}]=({1})\n$AN_CEC_OUTPUT_AXIS[{0}]=({1})\n$AN_CEC_STEP[{0}]={2:.6f}\n"
        "$AN_CEC_MIN[{0}]={3:.6f}\n$AN_CEC_MAX[{0}]={4:.6f}\n$AN_CEC_DIRECTION[{0}]={5}\n"
        "$AN_CEC_MULT_BY_TABLE[{0}]=0\n$AN_CEC_IS_MODULO[{0}]={6}\n",
        number, ax, step, t.position.front(), t.position.back(), tables[k].first, t.modulo ? 1 : 0);
    enable += fmt::format(
        "; MD18342 $MN_MM_CEC_MAX_POINTS[{0}] >= {1} (then POWER ON); SD41300 $SN_CEC_TABLE_ENABLE[{0}] = 1\n", number,
        t.position.size());
  }
  f.text += "M17\n";
  f.setup = fmt::format(
      "; machine data for the CEC tables of axis {0} ({1}):\n{2}"
      "; MD32710 $MA_CEC_ENABLE[{1}] = 0 while the tables are loaded, then 1; active once the axis is referenced\n",
      axis.name, ax, enable);
  return f;
}

CompensationTable readCec(std::string_view text, const std::string& source) {
  std::map<std::size_t, GridTable> tables;
  for (const auto& a : assignmentsOf(text, source, "%_N_NC_CEC_INI")) {
    static const std::string kPrefix = "AN_CEC";
    if (a.name.rfind(kPrefix, 0) != 0)
      throw InputError(fmt::format("{}: line {}: ${} is not a CEC table variable", source, a.line, a.name));
    const std::string field = a.name.substr(kPrefix.size());
    if (a.index.size() != (field.empty() ? 2u : 1u))
      throw InputError(fmt::format("{}: line {}: ${} takes {} indices", source, a.line, a.name, field.empty() ? 2 : 1));
    readGridField(tables[indexOf(a, 0, source)], field, a, source);
  }
  if (tables.empty() || tables.size() > 2)
    throw InputError(fmt::format("{}: {} tables: mtcal reads one axis' table or its pair (one per direction)", source,
                                 tables.size()));
  CompensationTable t;
  bool up = false, down = false;
  std::string axis;
  for (const auto& [number, g] : tables) {
    const std::string what = fmt::format("table {}", number);
    if (g.input_axis != g.output_axis || (!axis.empty() && g.input_axis != axis)) {
      throw InputError(fmt::format("{}: {}: input axis {} and output axis {}: mtcal reads an axis' table on itself",
                                   source, what, g.input_axis, g.output_axis));
    }
    axis = g.input_axis;
    t.axis_in_file =
        axis.size() > 2 && axis.front() == '(' && axis.back() == ')' ? axis.substr(1, axis.size() - 2) : axis;
    const auto values = g.values(source, what);
    const auto position = gridPositions(*g.min, *g.step, values.size());
    if (!t.position.empty() && position != t.position)
      throw InputError(fmt::format("{}: {}: not the same interpolation points as the other table", source, what));
    t.position = position;
    std::vector<double> um;
    for (double v : values) um.push_back(v * kUmPerMm);
    if (g.direction >= 0) {
      if (up) throw InputError(fmt::format("{}: {}: a second table for the positive direction", source, what));
      t.up_um = um, up = true;
    }
    if (g.direction <= 0) {
      if (down) throw InputError(fmt::format("{}: {}: a second table for the negative direction", source, what));
      t.down_um = um, down = true;
    }
    if (g.modulo != tables.begin()->second.modulo)
      throw InputError(fmt::format("{}: {}: modulo in one table and not in the other", source, what));
  }
  if (!up || !down)
    throw InputError(fmt::format("{}: no table for the {} direction", source, up ? "negative" : "positive"));
  return closedTable(t, tables.begin()->second.modulo, source);
}

}  // namespace

ControllerFormat siemensEecFormat() {
  return {"siemens-eec",
          "SINUMERIK 840D sl leadscrew error compensation %_N_AX_EEC_INI: the error (mm), one table for both "
          "directions",
          {true, true},
          0,
          0.0,
          writeEec,
          readEec};
}

ControllerFormat siemensCecFormat() {
  return {"siemens-cec",
          "SINUMERIK 840D sl CEC tables %_N_NC_CEC_INI of the axis on itself: the correction (mm), a table per "
          "direction",
          {true, true},
          0,
          0.0,
          writeCec,
          readCec};
}

}  // namespace mtcal::processing::format_text
