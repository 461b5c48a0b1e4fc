#include "mtcal/acquisition/import_linear.h"

#include <fmt/format.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <functional>
#include <map>
#include <nlohmann/json.hpp>
#include <optional>
#include <set>
#include <sstream>
#include <tuple>

#include "mtcal/acquisition/linear_plan.h"
#include "mtcal/error.h"
#include "mtcal/processing/air_index.h"
#include "mtcal/processing/diagnosis.h"

namespace mtcal::acquisition {
namespace {

constexpr const char* kErrorLetters = "XYZABC";

std::string lower(std::string s) {
  std::transform(s.begin(), s.end(), s.begin(), [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return s;
}

/// The setup of the measured line as a plan checks it: the axis, its error, the line and the optic.
/// The name a line setup's plan key (and its entry: an axis of the line's position) was given
/// by, for its refusals; empty: the key itself.
using SetupNames = std::function<std::string(const std::string& key, const std::string& entry)>;

/// The line's setup read as a plan reads it. The setup comes from the command's options or a
/// manifest's entry, whose names differ from the plan's keys: a refusal "SOURCE: key 'k.E': why"
/// is said with the name given (nameOf(k, E)), as "SOURCE: the error measured: 'EQX' is not
/// one of the errors of axis X ..." rather than "key 'measures'".
LinearPlan setupAsGiven(const nlohmann::json& setup, const std::string& source, const SetupNames& nameOf) {
  try {
    return LinearPlan::fromJson(setup, source);
  } catch (const InputError& e) {
    std::string message = e.what();
    const std::string prefix = source + ": key '";
    const auto end = message.find("': ", prefix.size());
    if (message.rfind(prefix, 0) != 0 || end == std::string::npos) throw;
    const std::string key_and_entry = message.substr(prefix.size(), end - prefix.size());
    const auto dot = key_and_entry.find('.');
    const std::string name =
        nameOf(key_and_entry.substr(0, dot), dot == std::string::npos ? std::string() : key_and_entry.substr(dot + 1));
    if (name.empty()) throw;
    throw InputError(source + ": " + name + ": " + message.substr(end + 3));
  }
}

/// Some of the units a value column's header or --units may give (csvUnit knows more).
constexpr const char* kKnownUnits = "um, mm, urad, arcsec, mm/m ...";

/// Its refusals name the command's options that gave it.
LinearPlan lineSetup(const LinearImportOptions& options, const std::string& measures, const std::string& source) {
  nlohmann::json setup = {{"axis", options.axis}};
  if (!measures.empty()) setup["measures"] = measures;
  if (!options.line_position_mm.empty()) setup["line_position_mm"] = options.line_position_mm;
  if (options.reflector_offset_mm) setup["reflector_offset_mm"] = *options.reflector_offset_mm;
  if (options.raw) {  // what mtcal compensates the readings with
    setup["co2_ppm"] = options.co2_ppm;
    setup["expansion_per_k"] = options.expansion_per_k;
    setup["datum_mm"] = options.datum_mm;
  }
  return setupAsGiven(setup, source, [](const std::string& key, const std::string& entry) -> std::string {
    static const std::map<std::string, std::string> kWords = {{"axis", "--axis"},
                                                              {"measures", "--measures (the error measured)"},
                                                              {"line_position_mm", "--line-position-mm"},
                                                              {"reflector_offset_mm", "--reflector-offset-mm"},
                                                              {"co2_ppm", "--co2-ppm"},
                                                              {"expansion_per_k", "--expansion-per-k"},
                                                              {"datum_mm", "--datum-mm"}};
    const auto it = kWords.find(key);
    if (it == kWords.end()) return {};
    return entry.empty() ? it->second : it->second + " " + entry;
  });
}

bool isAngle(const std::string& measures) { return processing::linearErrorKind(measures).angle; }

/// A value column of the file and the error it measures.
struct ValueColumn {
  std::string measures;
  CsvColumn column;
  bool measured_mm = false;  ///< a position, not a deviation
};

/// When a row was read, as far as the order of a measurement goes.
struct RowTime {
  int line = 0, cycle = 0, direction = 0;
  double target_mm = 0.0, time_s = 0.0;
};

/// Where the times of a file cannot be one clock's: a pass listed in its order of approach
/// whose time goes back, two passes beginning at the same instant and overlapping (each pass's
/// clock from zero), or a cycle beginning no later than the cycle numbered before it and before it
/// ended (its first reading taken no later than that cycle's first); a time the same on every row
/// is said as such. A file listed in another order (by target) goes back in time
/// at many rows and is not judged by that; nor is a pilgrim-step plan, whose cycles interleave
/// but still begin one after another. At most one warning of each kind (a cycle's beginning only
/// where no two passes begin together), one a line, in the order of lines.
std::vector<std::string> timesNotOfOneClock(const std::vector<RowTime>& rows, const std::string& source,
                                            const CsvColumn& column_read) {
  const std::string& column = column_read.header;
  // A time as the file writes it, and in seconds where its unit is another ("0.05 (3.000 s)").
  const auto when = [&](double time_s) {
    return column_read.factor == 1.0 ? fmt::format("{:.3f} s", time_s)
                                     : fmt::format("{:g} ({:.3f} s)", time_s / column_read.factor, time_s);
  };
  std::vector<std::pair<int, std::string>> found;  // line, why
  if (std::all_of(rows.begin(), rows.end(), [&](const RowTime& r) { return r.time_s == rows.front().time_s; })) {
    return {fmt::format("{}: column '{}' holds the same time, {}, on every row: nothing is read in time from it",
                        source, column, when(rows.front().time_s))};
  }
  const std::string consequence = fmt::format(
      "the times are imported as given, and a drift or growth in time read from them is wrong; correct them, or "
      "leave the column '{}' out (then nothing is read in time)",
      column);
  const auto direction = [](const RowTime& r) { return r.direction > 0 ? "+" : "-"; };
  for (std::size_t i = 1; i < rows.size(); ++i) {
    const RowTime &a = rows[i - 1], &b = rows[i];
    if (a.cycle == b.cycle && a.direction == b.direction && (b.target_mm - a.target_mm) * b.direction > 0.0 &&
        b.time_s < a.time_s) {
      found.emplace_back(b.line, fmt::format("{}:{}: column '{}': {} is earlier than the reading before it in "
                                             "the same pass (line {}, {}; cycle {}, direction {}): the clock "
                                             "went back (was it reset?); {}",
                                             source, b.line, column, when(b.time_s), a.line, when(a.time_s), b.cycle,
                                             direction(b), consequence));
      break;
    }
  }
  // Each pass's and each cycle's first reading in time, and its last time.
  std::map<std::pair<int, int>, const RowTime*> first_of_pass;
  std::map<int, const RowTime*> first_of_cycle;
  std::map<std::pair<int, int>, double> end_of_pass;
  std::map<int, double> end_of_cycle;
  for (const auto& r : rows) {
    for (double* end : {&end_of_pass.try_emplace({r.cycle, r.direction}, r.time_s).first->second,
                        &end_of_cycle.try_emplace(r.cycle, r.time_s).first->second})
      *end = std::max(*end, r.time_s);
    if (auto [it, inserted] = first_of_pass.emplace(std::pair{r.cycle, r.direction}, &r);
        !inserted && r.time_s < it->second->time_s)
      it->second = &r;
    if (auto [it, inserted] = first_of_cycle.emplace(r.cycle, &r); !inserted && r.time_s < it->second->time_s)
      it->second = &r;
  }
  std::vector<const RowTime*> starts;
  for (const auto& [pass, r] : first_of_pass) starts.push_back(r);
  std::sort(starts.begin(), starts.end(), [](const RowTime* a, const RowTime* b) {
    return std::tie(a->time_s, a->line) < std::tie(b->time_s, b->line);
  });
  bool passes_restarted = false;
  for (std::size_t k = 1; k < starts.size() && !passes_restarted; ++k) {
    const RowTime &a = *starts[k - 1], &b = *starts[k];
    // Together, and overlapping (a coarse clock can give two short passes one start).
    if (b.time_s == a.time_s && b.time_s < end_of_pass.at({a.cycle, a.direction})) {
      passes_restarted = true;
      found.emplace_back(b.line, fmt::format("{}:{}: column '{}': the pass of cycle {}, direction {} begins at {}, "
                                             "the instant the pass of cycle {}, direction {} begins (line {}): the "
                                             "times look restarted (a clock reset, or runs each timed from its own "
                                             "start joined into one file); {}",
                                             source, b.line, column, b.cycle, direction(b), when(b.time_s), a.cycle,
                                             direction(a), a.line, consequence));
    }
  }
  for (auto it = first_of_cycle.begin();
       !passes_restarted && it != first_of_cycle.end() && std::next(it) != first_of_cycle.end(); ++it) {
    const RowTime &a = *it->second, &b = *std::next(it)->second;
    if (b.time_s <= a.time_s && b.time_s < end_of_cycle.at(a.cycle)) {
      found.emplace_back(b.line, fmt::format("{}:{}: column '{}': cycle {} begins at {}, no later than cycle {} "
                                             "(line {}, {}): the times look restarted (a clock reset, or runs "
                                             "each timed from its own start joined into one file); {}",
                                             source, b.line, column, b.cycle, when(b.time_s), a.cycle, a.line,
                                             when(a.time_s), consequence));
      break;
    }
  }
  // One warning a line (a clock that went back within a pass also begins that pass early).
  std::stable_sort(found.begin(), found.end(), [](const auto& a, const auto& b) { return a.first < b.first; });
  std::vector<std::string> out;
  for (std::size_t k = 0; k < found.size(); ++k)
    if (k == 0 || found[k].first != found[k - 1].first) out.push_back(std::move(found[k].second));
  return out;
}

}  // namespace

LinearPlan checkLinearImportOptions(const LinearImportOptions& options, const std::string& source) {
  if (options.axis != "X" && options.axis != "Y" && options.axis != "Z") {
    throw InputError("--axis must be X, Y or Z, got '" + options.axis + "'");
  }
  if (!options.value_unit.empty() && !csvUnit(options.value_unit)) {
    throw InputError(fmt::format("--units '{}': not a unit mtcal knows ({})", options.value_unit, kKnownUnits));
  }
  if (options.raw && !(options.wavelength_nm >= processing::kMinVacuumWavelengthNm &&
                       options.wavelength_nm <= processing::kMaxVacuumWavelengthNm)) {
    throw InputError(fmt::format(
        "--wavelength-nm must be a laser's vacuum wavelength from {:g} to {:g} nm (where the air's index equations "
        "hold), got {}",
        processing::kMinVacuumWavelengthNm, processing::kMaxVacuumWavelengthNm, options.wavelength_nm));
  }
  return lineSetup(options, options.measures, source);
}

ParsedLinearCsv parseLinearCsv(std::istream& in, const std::string& source, const LinearImportOptions& options) {
  const LinearPlan setup = checkLinearImportOptions(options, source);
  const std::string measures = measuredError(setup);
  CsvReader reader(in, source, options.csv);
  const std::string need =
      "target_mm, direction, cycle and a value: deviation_um, measured_mm, deviation_urad or error columns like E" +
      options.axis + options.axis + "_um";
  const CsvColumn target = reader.require("target_mm", need);
  const CsvColumn direction = reader.require("direction", need);
  const CsvColumn cycle = reader.require("cycle", need);

  std::vector<ValueColumn> values;
  for (const char* l = kErrorLetters; *l; ++l) {
    const std::string error = std::string("E") + *l + options.axis;
    if (auto c = reader.find(error + (isAngle(error) ? "_urad" : "_um"))) values.push_back({error, *c});
  }
  const bool angle = isAngle(measures);
  const std::string value_name = angle ? "deviation_urad" : "deviation_um";
  const auto deviation = reader.find(value_name, options.value_unit);
  const auto measured =
      measuresPositioning(setup) ? reader.find("measured_mm", options.value_unit.empty() ? "" : "mm") : std::nullopt;
  const int header_line = reader.headerLine();
  if (!values.empty()) {
    if (deviation || measured || !options.measures.empty()) {
      throw InputError(
          fmt::format("{}:{}: the file has error columns ('{}' ...), one run each: a deviation column or "
                      "the error measured (--measures, a manifest's measures) does not apply to it",
                      source, header_line, values.front().column.header));
    }
  } else if (deviation && measured) {
    throw InputError(
        fmt::format("{}:{}: give exactly one of the columns measured_mm and deviation_um", source, header_line));
  } else if (deviation || measured) {
    values.push_back({measures, deviation ? *deviation : *measured, measured.has_value()});
  } else {
    // What the file has instead, said in the error.
    if (const auto other = reader.find(angle ? "deviation_um" : "deviation_urad")) {
      throw InputError(
          fmt::format("{}:{}: {} is {}, but column '{}' is {} (the error measured is named by "
                      "--measures, or a manifest's measures)",
                      source, header_line, measures, angle ? "an angle" : "a length", other->header,
                      angle ? "a length" : "an angle"));
    }
    reader.require(value_name, need, options.value_unit);
  }
  if (options.raw && !(values.size() == 1 && values[0].measured_mm)) {
    throw InputError(fmt::format("{}:{}: --raw needs a measured_mm column (raw laser readings)", source, header_line));
  }
  std::map<std::string, std::optional<CsvColumn>> environment;
  for (const char* name : {"time_s", "air_temp_c", "air_pressure_pa", "humidity_pct", "material_temp_c"})
    environment[name] = reader.find(name);
  reader.refuseUnusedMappings();

  ParsedLinearCsv out;
  for (const auto& v : values) out.runs.push_back({v.measures, isAngle(v.measures) ? "urad" : "um", {}, {}});
  const auto channel_columns = reader.unclaimed();
  for (const auto i : channel_columns) out.channel_names.push_back(reader.header()[i]);

  std::map<std::tuple<long long, int, int>, int> seen;  // (target nm, direction, cycle) -> line
  std::size_t rows = 0;
  std::vector<RowTime> row_times;
  bool timed = true;
  while (const auto row = reader.row()) {
    const auto& cells = *row;
    const int line_no = reader.line();
    auto number = [&](const std::string& name) {
      const auto& c = environment.at(name);
      return c ? reader.number(cells, *c) : std::nullopt;
    };
    storage::TargetRecord r;
    r.target_mm = reader.required(cells, target);
    const std::string dir = lower(cells[direction.index]);
    if (dir == "+" || dir == "up" || dir == "fwd" || dir == "forward") {
      r.direction = 1;
    } else if (dir == "-" || dir == "down" || dir == "bwd" || dir == "backward") {
      r.direction = -1;
    } else {
      throw reader.error(direction.header, "'" + cells[direction.index] + "' is not one of +, -, up, down, fwd, bwd");
    }
    const double cycle_number = reader.required(cells, cycle);
    if (cycle_number < 1 || cycle_number != std::floor(cycle_number) || cycle_number > 1e6)
      throw reader.error(cycle.header, "must be a whole number >= 1");
    r.cycle = static_cast<int>(cycle_number);
    r.time_s = number("time_s");
    // The environment where a machine is measured: the air in the range its index is taken
    // in, a part at a shop's temperatures (as the air's).
    const auto within = [&](const char* name, double least, double greatest, const char* unit) {
      const auto v = number(name);
      if (v && !(*v >= least && *v <= greatest))
        throw reader.error(environment.at(name)->header,
                           fmt::format("{:g} {} is outside {:g}..{:g} {} (a sensor fault? leave the cell empty)", *v,
                                       unit, least, greatest, unit));
      return v;
    };
    r.air_temp_c = within("air_temp_c", processing::kMinAirTemperatureC, processing::kMaxAirTemperatureC, "degC");
    r.air_pressure_pa = within("air_pressure_pa", processing::kMinAirPressurePa, processing::kMaxAirPressurePa, "Pa");
    r.humidity_pct = within("humidity_pct", processing::kMinHumidityPct, processing::kMaxHumidityPct, "%");
    r.material_temp_c =
        within("material_temp_c", processing::kMinAirTemperatureC, processing::kMaxAirTemperatureC, "degC");
    const auto key = std::tuple{std::llround(r.target_mm * 1e6), r.direction, r.cycle};
    if (auto [it, inserted] = seen.emplace(key, line_no); !inserted) {
      throw InputError(fmt::format("{}:{}: target {} mm, direction {}, cycle {} was already given on line {}", source,
                                   line_no, r.target_mm, r.direction > 0 ? "+" : "-", r.cycle, it->second));
    }

    timed = timed && r.time_s.has_value();
    if (timed) row_times.push_back({line_no, r.cycle, r.direction, r.target_mm, *r.time_s});

    storage::ChannelRow channels;
    for (const auto c : channel_columns)
      channels.push_back(reader.number(cells, CsvColumn{c, reader.header()[c], 1.0}));
    ++rows;
    for (std::size_t v = 0; v < values.size(); ++v) {
      const ValueColumn& value = values[v];
      storage::TargetRecord t = r;
      if (!value.measured_mm) {
        // Several error columns: a cell left empty is a target that error was not measured at.
        const auto dev = values.size() > 1 ? reader.number(cells, value.column)
                                           : std::optional<double>(reader.required(cells, value.column));
        if (!dev) continue;
        t.deviation_um = *dev;
        t.measured_mm = value.measures[1] == options.axis[0] ? t.target_mm + *dev / 1000.0 : t.target_mm;
      } else if (!options.raw) {
        t.measured_mm = reader.required(cells, value.column);
        t.deviation_um = (t.measured_mm - t.target_mm) * 1000.0;
      } else {
        const double raw_mm = reader.required(cells, value.column);
        if (!t.air_temp_c || !t.air_pressure_pa || !t.humidity_pct) {
          throw reader.error(!t.air_temp_c        ? "air_temp_c"
                             : !t.air_pressure_pa ? "air_pressure_pa"
                                                  : "humidity_pct",
                             "--raw needs air_temp_c, air_pressure_pa and humidity_pct on every row");
        }
        double n;
        try {
          n = processing::airIndex(options.model, {*t.air_temp_c, *t.air_pressure_pa, *t.humidity_pct, options.co2_ppm},
                                   options.wavelength_nm);
        } catch (const InputError& e) {
          throw reader.error("air_temp_c/air_pressure_pa/humidity_pct", e.what());
        }
        double length_mm = processing::compensateWavelength(raw_mm, n);
        if (t.material_temp_c)
          length_mm = processing::normaliseTo20C(length_mm, *t.material_temp_c, options.expansion_per_k);
        t.air_index = n;
        t.measured_mm = options.datum_mm + length_mm;
        t.deviation_um = (t.measured_mm - t.target_mm) * 1000.0;
      }
      if (value.measured_mm && !(std::abs(t.deviation_um) <= kLargestDeviationUm)) {
        throw reader.error(
            value.column.header,
            fmt::format("the position reached, {:g} mm, is {:g} mm from its target {:g} mm: beyond "
                        "+-{:g} mm, not a machine's error (a mistyped or shifted cell?)",
                        t.measured_mm, t.measured_mm - t.target_mm, t.target_mm, kLargestDeviationUm / 1000.0));
      }
      auto& run = out.runs[v];
      t.seq = static_cast<std::int64_t>(run.targets.size());
      run.targets.push_back(t);
      run.channel_rows.push_back(channels);
    }
  }
  if (rows == 0) throw InputError(source + ": no data rows after the header");
  if (timed && environment.at("time_s"))
    out.warnings = timesNotOfOneClock(row_times, source, *environment.at("time_s"));
  for (const auto& run : out.runs) {
    if (run.targets.empty()) throw InputError(fmt::format("{}: column for {} has no values", source, run.measures));
    std::set<int> cycles;
    for (const auto& t : run.targets) cycles.insert(t.cycle);
    if (cycles.size() == 1) {
      throw InputError(
          fmt::format("{}: {} has one cycle ({}) only: analyze linear (ISO 230-2) and model identify estimate the "
                      "repeatability from at least 2 cycles at each target; export at least 2 runs over the axis",
                      source, run.measures, *cycles.begin()));
    }
  }
  return out;
}

namespace {

/// A file's runs as they are stored: each along the axis, at 2 targets at least (one target is
/// no axis' error: analyze and model identify would refuse it). @throws InputError naming the file
ParsedLinearCsv parseStorableLinearCsv(std::istream& in, const std::string& path, const LinearImportOptions& options) {
  ParsedLinearCsv parsed = parseLinearCsv(in, path, options);
  for (const auto& run : parsed.runs) {
    const bool one_target = std::all_of(run.targets.begin(), run.targets.end(), [&](const storage::TargetRecord& t) {
      return std::abs(t.target_mm - run.targets.front().target_mm) < 1e-6;
    });
    if (one_target) {
      throw InputError(
          fmt::format("{}: {} has one target ({:g} mm) only: an axis' error is read along it, from at "
                      "least 2 targets (ISO 230-2)",
                      path, run.measures, run.targets.front().target_mm));
    }
  }
  return parsed;
}

/// Stores the parsed runs of one file in `campaign_id`. @return their ids
std::vector<storage::Id> storeRuns(storage::Store& store, storage::Id campaign_id, const ParsedLinearCsv& parsed,
                                   const std::string& file_name, const LinearImportOptions& options) {
  std::vector<storage::Id> ids;
  for (const auto& run : parsed.runs) {
    nlohmann::json plan = {{"type", "linear"},
                           {"axis", options.axis},
                           {"measures", run.measures},
                           {"imported_from", file_name},
                           {"compensated_by", options.raw ? "mtcal" : "exporting software"}};
    if (!options.line_position_mm.empty()) plan["line_position_mm"] = options.line_position_mm;
    if (!options.source_sha256.empty()) plan["imported_sha256"] = options.source_sha256;
    if (!parsed.warnings.empty()) plan["import_warnings"] = parsed.warnings;  // said again where the run is used
    if (options.reflector_offset_mm) plan["reflector_offset_mm"] = *options.reflector_offset_mm;
    if (options.raw) {
      plan["air_index_model"] = options.model == processing::AirIndexModel::kEdlen ? "edlen" : "ciddor";
      plan["wavelength_nm"] = options.wavelength_nm;
      plan["co2_ppm"] = options.co2_ppm;
      plan["expansion_per_k"] = options.expansion_per_k;
      plan["datum_mm"] = options.datum_mm;
    }
    storage::NewRun r;
    r.campaign_id = campaign_id;
    r.kind = storage::run_kind::kLinear;
    r.axis = options.axis;
    const std::string name = options.name.empty() ? file_name : options.name;
    r.name = parsed.runs.size() > 1 ? name + " " + run.measures : name;
    r.plan_json = plan.dump();
    r.status = storage::run_status::kImported;
    r.source = "imported";
    r.software_version = options.software_version;
    r.value_unit = run.value_unit;
    ids.push_back(store.importRun(r, run.targets, parsed.channel_names, run.channel_rows));
  }
  return ids;
}

/// A manifest's entry (a JSON manifest's object, or a CSV manifest's row as one); `nameOf` the
/// names its setup was given by (a CSV manifest's columns), empty: the keys (a JSON manifest).
LinearImportOptions parsedOptions(const nlohmann::json& entry, const std::string& where,
                                  const SetupNames& nameOf = {}) {
  LinearImportOptions o;
  static const std::set<std::string> kKeys = {"file",  "axis", "measures", "line_position_mm", "reflector_offset_mm",
                                              "units", "name"};
  for (const auto& [key, value] : entry.items()) {
    if (!kKeys.count(key))
      throw InputError(
          fmt::format("{}: unknown key '{}' (file, axis, measures, line_position_mm, "
                      "reflector_offset_mm, units, name)",
                      where, key));
  }
  auto text = [&](const char* key) -> std::string {
    if (!entry.contains(key)) return "";
    if (!entry[key].is_string()) throw InputError(fmt::format("{}: '{}' must be a string", where, key));
    return entry[key].get<std::string>();
  };
  o.axis = text("axis");
  o.measures = text("measures");
  o.value_unit = text("units");
  if (!o.value_unit.empty() && !csvUnit(o.value_unit))
    throw InputError(fmt::format("{}: {}: '{}' is not a unit mtcal knows ({})", where,
                                 nameOf ? nameOf("units", "") : "key 'units'", o.value_unit, kKnownUnits));
  o.name = text("name");
  nlohmann::json setup = {{"axis", o.axis}};
  if (!o.measures.empty()) setup["measures"] = o.measures;
  for (const char* key : {"line_position_mm", "reflector_offset_mm"})
    if (entry.contains(key)) setup[key] = entry[key];
  const auto plan = nameOf ? setupAsGiven(setup, where, nameOf) : LinearPlan::fromJson(setup, where);
  o.line_position_mm = plan.line_position_mm;
  if (entry.contains("reflector_offset_mm")) o.reflector_offset_mm = plan.reflector_offset_mm;
  return o;
}

struct Manifest {
  struct Run {
    std::string file;  ///< relative to the manifest
    LinearImportOptions options;
    std::string where;  ///< the entry in the manifest: "m.csv:3", "m.json: runs[1]"
  };
  std::string name, machine;
  std::vector<Run> runs;
};

/// The column of a CSV manifest that gave a line setup's plan key (and entry).
std::string csvManifestColumn(const std::string& key, const std::string& entry) {
  std::string axis = entry;
  for (auto& ch : axis) ch = static_cast<char>(std::tolower(static_cast<unsigned char>(ch)));
  if (key == "axis" || key == "measures" || key == "units") return "column '" + key + "'";
  if (key == "line_position_mm")
    return entry.empty() ? "columns line_x_mm, line_y_mm, line_z_mm" : "column 'line_" + axis + "_mm'";
  if (key == "reflector_offset_mm") return "columns reflector_x_mm, reflector_y_mm, reflector_z_mm";
  return {};
}

Manifest readManifest(const std::string& path, const CsvDialect& dialect) {
  std::ifstream in = openInputFile(path);
  std::stringstream text;
  text << in.rdbuf();
  const std::string content = text.str();
  const auto first = content.find_first_not_of(" \t\r\n\xEF\xBB\xBF");
  Manifest m;
  const bool json = first != std::string::npos && (content[first] == '{' || content[first] == '[');
  if (first == std::string::npos && std::filesystem::path(path).extension() == ".json")
    throw InputError(path + ": empty file: a manifest is {\"runs\": [{\"file\": ..., \"axis\": ...}, ...]}");
  if (json) {
    const auto j = parseJsonText(content.substr(first), path);
    if (!j.is_object()) throw InputError(path + ": not a JSON object: a manifest is {\"runs\": [...]}");
    for (const auto& [key, value] : j.items()) {
      if (key != "name" && key != "machine" && key != "runs")
        throw InputError(fmt::format("{}: unknown key '{}' (name, machine, runs)", path, key));
    }
    if (j.contains("name") && j["name"].is_string()) m.name = j["name"];
    if (j.contains("machine") && j["machine"].is_string()) m.machine = j["machine"];
    if (!j.contains("runs") || !j["runs"].is_array())
      throw InputError(path + ": 'runs' must be a list of {file, axis, measures, ...}");
    if (j["runs"].empty()) throw InputError(path + ": 'runs' is empty: list the runs to import");
    for (std::size_t i = 0; i < j["runs"].size(); ++i) {
      const auto& entry = j["runs"][i];
      const std::string where = fmt::format("{}: runs[{}]", path, i);
      if (!entry.is_object() || !entry.contains("file") || !entry["file"].is_string())
        throw InputError(where + ": needs 'file' (a CSV beside the manifest)");
      if (entry["file"].get<std::string>().empty()) throw InputError(where + ": key 'file': empty");
      m.runs.push_back({entry["file"].get<std::string>(), parsedOptions(entry, where), where});
    }
    return m;
  }
  std::istringstream csv_text(content);
  CsvReader reader(csv_text, path, dialect);
  const std::string need = "file, axis";
  const auto file = reader.require("file", need);
  const auto axis = reader.require("axis", need);
  std::map<std::string, std::optional<CsvColumn>> optional;
  for (const char* name : {"measures", "units", "name", "line_x_mm", "line_y_mm", "line_z_mm", "reflector_x_mm",
                           "reflector_y_mm", "reflector_z_mm"})
    optional[name] = reader.find(name);
  reader.refuseUnusedMappings();
  if (const auto other = reader.unclaimed(); !other.empty()) {
    throw InputError(
        fmt::format("{}:{}: unknown column '{}' (file, axis, measures, units, name, line_x_mm, "
                    "line_y_mm, line_z_mm, reflector_x_mm, reflector_y_mm, reflector_z_mm)",
                    path, reader.headerLine(), reader.header()[other.front()]));
  }
  while (const auto row = reader.row()) {
    nlohmann::json entry = {{"axis", (*row)[axis.index]}};
    for (const char* key : {"measures", "units", "name"})
      if (optional[key] && !(*row)[optional[key]->index].empty()) entry[key] = (*row)[optional[key]->index];
    nlohmann::json line = nlohmann::json::object();
    for (const char* a : {"x", "y", "z"}) {
      const auto& c = optional[fmt::format("line_{}_mm", a)];
      if (const auto v = c ? reader.number(*row, *c) : std::nullopt) line[std::string(1, std::toupper(*a))] = *v;
    }
    if (!line.empty()) entry["line_position_mm"] = line;
    std::vector<std::optional<double>> reflector;
    for (const char* a : {"x", "y", "z"}) {
      const auto& c = optional[fmt::format("reflector_{}_mm", a)];
      reflector.push_back(c ? reader.number(*row, *c) : std::nullopt);
    }
    const auto given = std::count_if(reflector.begin(), reflector.end(), [](auto& v) { return v.has_value(); });
    if (given > 0 && given < 3) {
      throw InputError(fmt::format(
          "{}:{}: columns reflector_x_mm, reflector_y_mm, reflector_z_mm: {} of the three given: give all three, or "
          "none (no offset)",
          path, reader.line(), given));
    }
    if (given == 3) entry["reflector_offset_mm"] = {*reflector[0], *reflector[1], *reflector[2]};
    if ((*row)[file.index].empty()) throw reader.error(file.header, "empty");
    const std::string where = fmt::format("{}:{}", path, reader.line());
    m.runs.push_back({(*row)[file.index], parsedOptions(entry, where, csvManifestColumn), where});
  }
  if (m.runs.empty()) throw InputError(path + ": no runs listed");
  return m;
}

}  // namespace

LinearImport importLinearCsv(const StoreWhenNeeded& store, const std::string& path,
                             const LinearImportOptions& options) {
  std::ifstream in = openInputFile(path);
  return importLinearCsv(store, in, path, options);
}

LinearImport importLinearCsv(const StoreWhenNeeded& store_when_needed, std::istream& in, const std::string& path,
                             const LinearImportOptions& options) {
  const ParsedLinearCsv parsed = parseStorableLinearCsv(in, path, options);
  const std::string file_name = std::filesystem::path(path).filename().string();
  auto& store = store_when_needed();
  // One transaction for everything, the machine and campaign rows included.
  storage::Transaction tx(store.database());
  const auto campaign = store.addCampaign(store.ensureMachine(options.machine, "", "{}"), "import " + file_name);
  LinearImport out{storeRuns(store, campaign, parsed, file_name, options), {}, {}, parsed.warnings};
  for (const auto& run : parsed.runs) {
    out.measures.push_back(run.measures);
    out.readings.push_back(run.targets.size());
  }
  tx.commit();
  return out;
}

CampaignImport importLinearCampaign(const StoreWhenNeeded& store_when_needed, const std::string& manifest_path,
                                    const CampaignImportOptions& options) {
  const Manifest manifest = readManifest(manifest_path, options.csv);
  const auto dir = std::filesystem::path(manifest_path).parent_path();
  std::vector<std::tuple<std::string, ParsedLinearCsv, LinearImportOptions>> parsed;
  // A file named by two entries: its readings stored twice, under two setups (an axis' file
  // given for another axis, as likely as a file of several errors read once per error).
  std::vector<std::string> files_named_twice;
  std::map<std::string, std::string> entry_of_file;
  for (const auto& run : manifest.runs) {
    const auto file = (dir / run.file).lexically_normal().string();
    if (const auto [it, first] = entry_of_file.emplace(file, run.where); !first)
      files_named_twice.push_back(fmt::format("{} and {} name the same file '{}': its readings are stored for both",
                                              it->second, run.where, run.file));
  }
  for (auto [file, run_options, where] : manifest.runs) {
    // What is wrong with a run file is said with the manifest's entry that names it.
    try {
      const auto path = (dir / file).string();
      std::ifstream in = openInputFile(path);
      run_options.csv = options.csv;
      run_options.software_version = options.software_version;
      if (run_options.name.empty()) run_options.name = std::filesystem::path(file).filename().string();
      parsed.emplace_back(std::filesystem::path(file).filename().string(),
                          parseStorableLinearCsv(in, path, run_options), run_options);
    } catch (const InputError& e) {
      throw InputError(fmt::format("{}: run file '{}': {}", where, file, e.what()));
    }
  }
  const std::string machine = !options.machine.empty()    ? options.machine
                              : !manifest.machine.empty() ? manifest.machine
                                                          : storage::kImportedMachine;
  const std::string name = !options.name.empty() ? options.name
                           : !manifest.name.empty()
                               ? manifest.name
                               : "import " + std::filesystem::path(manifest_path).filename().string();
  auto& store = store_when_needed();
  storage::Transaction tx(store.database());
  CampaignImport out;
  out.warnings = files_named_twice;
  out.campaign_id = store.addCampaign(store.ensureMachine(machine, "", "{}"), name);
  for (const auto& [file, p, o] : parsed) {
    for (const auto id : storeRuns(store, out.campaign_id, p, file, o)) out.run_ids.push_back(id);
    out.warnings.insert(out.warnings.end(), p.warnings.begin(), p.warnings.end());
  }
  tx.commit();
  return out;
}

}  // namespace mtcal::acquisition
