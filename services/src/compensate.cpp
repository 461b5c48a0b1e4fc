#include "mtcal/services/compensate.h"

#include <fmt/format.h>
#include <fmt/ranges.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <filesystem>

#include "mtcal/error.h"
#include "mtcal/services/linear.h"
#include "mtcal/services/model.h"
#include "mtcal/services/workshop.h"

namespace mtcal::services {
namespace {

std::string upper(std::string s) {
  std::transform(s.begin(), s.end(), s.begin(), [](unsigned char c) { return static_cast<char>(std::toupper(c)); });
  return s;
}

/// An axis' number: X 0, Y 1, Z 2, A 3, B 4, C 5 (the controller's when the engineer does not
/// give it); `linear`: X, Y or Z only. @throws InputError naming `what`
int axisIndex(const std::string& axis, const std::string& what, bool linear = true) {
  static const std::string kOrder = "XYZABC";
  const auto a = upper(axis);
  const auto k = a.size() == 1 ? kOrder.find(a[0]) : std::string::npos;
  if (k == std::string::npos || (linear && k > 2))
    throw InputError(fmt::format("{}: axis '{}' is not {}", what, axis, linear ? "X, Y or Z" : "one of X Y Z A B C"));
  return static_cast<int>(k);
}

/// Corrections beyond this are no machine's positioning error but a file read as the wrong
/// format (a LinuxCNC trim file read as actual positions gives corrections of its positions).
constexpr double kLargestCorrectionUm = 1000.0;

double largestCorrectionUm(const processing::CompensationTable& t) {
  double largest = 0.0;
  for (const auto* v : {&t.up_um, &t.down_um})
    for (const double x : *v) largest = std::max(largest, std::abs(x));
  return largest;
}

/// The largest axis number a controller has (LinuxCNC: 16 joints).
constexpr int kMaxAxisIndex = 15;

Compensation tableFor(const processing::AxisError& error, const std::string& source, const std::string& axis,
                      const CompensateRequest& request, processing::TableOptions options,
                      const std::optional<AppliedTable>& ran = std::nullopt) {
  const auto& format = processing::controllerFormat(request.controller);
  if (options.modulo) {
    throw InputError(
        fmt::format("axis {} is a linear axis (mm): a modulo is for rotary axes, which mtcal does not "
                    "measure yet",
                    axis));
  }
  Compensation c;
  c.source = source;
  c.axis = axis;
  c.controller = format.name;
  c.controller_description = format.description;
  options.max_points = format.max_points;
  if (options.resolution_um == 0.0) options.resolution_um = format.resolution_um;
  std::optional<AppliedTable> existing = ran;
  if (!request.existing_path.empty()) {
    existing = AppliedTable{readCompensationFile(request.existing_path, request.controller), format.rules, format.name,
                            request.existing_path};
    const bool differs =
        ran && (ran->table.position != existing->table.position || ran->table.up_um != existing->table.up_um ||
                ran->table.down_um != existing->table.down_um);
    if (differs && ran->file == request.existing_path) {
      c.warnings.push_back(
          fmt::format("{} has changed since {} ran it (the run stored the table it ran): the new table "
                      "adds to the file as it is now",
                      request.existing_path, source));
    } else if (differs) {
      c.warnings.push_back(fmt::format("{} ran {}'s table (stored with it), not {}'s: the new table adds to {}'s",
                                       source, ran->file, request.existing_path, request.existing_path));
    } else if (!ran) {
      c.warnings.push_back(
          fmt::format("{} stored no table: --existing {} is taken as the table the machine ran while "
                      "measured (if it ran none, leave --existing out)",
                      source, request.existing_path));
    }
  }
  if (existing) c.existing_path = existing->file;
  c.table = processing::compensationTable(error, options, existing ? &existing->table : nullptr,
                                          existing ? existing->rules : format.rules);
  const int index = request.axis_index ? *request.axis_index : axisIndex(axis, "give --axis-index", false);
  if (index < 0 || index > kMaxAxisIndex)
    throw InputError(fmt::format("--axis-index {}: an axis' number is 0 to {}", index, kMaxAxisIndex));
  c.file = format.write(c.table, {axis, index, request.file_name});
  // The table as the controller reads the file: rounded to its resolution, shifted to its zero.
  const auto written = format.read(c.file.text, "the written table");
  // A file of another axis of the controller would add that axis' corrections to this one's.
  if (existing && !existing->table.axis_in_file.empty() && existing->table.axis_in_file != written.axis_in_file) {
    throw InputError(fmt::format(
        "--existing {} is a table of {}, and the table of {} is written for {} (--axis-index {}): give the table {} "
        "ran while measured, or --axis-index with {}'s number on the controller",
        existing->file, existing->table.axis_in_file, axis, written.axis_in_file, index, axis, axis));
  }
  // Its positions as made, to 0.1 um: a file that writes them in coarser units would move them.
  for (std::size_t i = 0; i < written.position.size() && i < c.table.position.size(); ++i) {
    if (std::abs(written.position[i] - c.table.position[i]) > 1e-4) {
      throw InputError(fmt::format(
          "{}: entry {} at {} mm is written at {} mm, the file's nearest position: give --start and --interval "
          "in whole units of the file",
          format.name, i + 1, c.table.position[i], written.position[i]));
    }
  }
  if (options.reference) {  // a controller that takes its own zero (Fanuc's reference position) moves it
    const double at_reference = (written.correctionUm(*options.reference, processing::Direction::kUp, format.rules) +
                                 written.correctionUm(*options.reference, processing::Direction::kDown, format.rules)) /
                                2.0;
    if (std::abs(at_reference) > std::max(options.resolution_um, 0.01)) {
      throw InputError(fmt::format(
          "--reference {:g}: the {} file's correction there is {:+.3f} um, not 0: the controller takes its own zero "
          "(leave --reference out)",
          *options.reference, format.name, at_reference));
    }
  }
  const double largest_written_um = largestCorrectionUm(written);
  if (largest_written_um > kLargestCorrectionUm) {
    throw InputError(fmt::format(
        "{}: corrections up to {:.1f} um: beyond {:g} um, no machine's positioning error (a wrong unit, datum or "
        "material temperature?)",
        c.source, largest_written_um, kLargestCorrectionUm));
  }
  if (largest_written_um == 0.0 && options.resolution_um > 0.0) {
    auto unrounded = options;
    unrounded.resolution_um = 0.0;
    const double largest = largestCorrectionUm(processing::compensationTable(
        error, unrounded, existing ? &existing->table : nullptr, existing ? existing->rules : format.rules));
    if (largest > 0.0) {
      c.warnings.push_back(
          fmt::format("every correction rounds to 0 at a resolution of {:g} um (the largest is {:.3f} um): the table "
                      "corrects nothing",
                      options.resolution_um, largest));
    }
  }
  c.table = written;
  return c;
}

}  // namespace

nlohmann::json Compensation::document() const {
  // The file's values without the binary conversion's noise (-2.3330000000001405): 1e-6 um.
  const auto tidy = [](double v) { return roundedTo(v, 6); };
  nlohmann::json rows = nlohmann::json::array();
  for (std::size_t i = 0; i < table.position.size(); ++i) {
    rows.push_back({{"position", tidy(table.position[i])},
                    {"correction_up_um", tidy(table.up_um[i])},
                    {"correction_down_um", tidy(table.down_um[i])}});
  }
  nlohmann::json d{{"schema_version", 1},
                   {"source", source},
                   {"axis", axis},
                   {"controller", controller},
                   {"controller_description", controller_description},
                   {"bidirectional", table.bidirectional()},
                   {"rows", rows},
                   {"file", file.text},
                   {"setup", file.setup}};
  if (table.modulo) d["modulo"] = *table.modulo;
  if (!existing_path.empty()) d["existing_table"] = existing_path;
  d["warnings"] = warnings;
  if (!extensions_applied.empty() || !extensions_left_out.empty()) {
    d["extensions_applied"] = extensions_applied;
    d["extensions_left_out"] = extensions_left_out;
  }
  return d;
}

processing::CompensationTable readCompensationFile(const std::string& path, const std::string& controller) {
  const auto& format = processing::controllerFormat(controller);
  if (std::filesystem::is_directory(path)) throw InputError(fmt::format("{}: a folder, not a table file", path));
  const auto text = readTextFile(path);
  // The controllers that read the file with corrections a machine could have: the hint when
  // the one named does not.
  const auto readers = [&] {
    std::vector<std::string> names;
    for (const auto& other : processing::controllerNames()) {
      if (other == format.name) continue;
      try {
        const auto t = processing::controllerFormat(other).read(text, path);
        if (largestCorrectionUm(t) <= kLargestCorrectionUm) names.push_back("--controller " + other);
      } catch (const InputError&) {
      }
    }
    if (!names.empty()) return fmt::format(" (the file reads as a table of {})", fmt::join(names, " or "));
    try {
      processing::readIsgVolumetricCsv(text, path);
      return std::string(" (the file is a volumetric compensation, isg-volumetric, which runs do not load yet)");
    } catch (const InputError&) {
      return std::string();
    }
  };
  processing::CompensationTable table;
  try {
    table = format.read(text, path);
  } catch (const InputError& e) {
    throw InputError(e.what() + readers());
  }
  // A LinuxCNC file of the other type reads as corrections of the size of its positions.
  if (const double largest = largestCorrectionUm(table); largest > kLargestCorrectionUm) {
    throw InputError(
        fmt::format("{}: a correction of {:.1f} um, more than any axis' error ({:.0f} um): a file of "
                    "another format?{}",
                    path, largest, kLargestCorrectionUm, readers()));
  }
  return table;
}

std::vector<std::string> compensationControllers() { return processing::controllerNames(); }

Compensation compensateRun(Session& session, storage::Id run_id, const CompensateRequest& request) {
  const auto run = session.store().run(run_id);
  if (run.kind == storage::run_kind::kLinear && run.status != storage::run_status::kCompleted &&
      run.status != storage::run_status::kImported) {
    throw InputError(
        fmt::format("run {} is {}: a table from part of the travel would be wrong; resume it first "
                    "(mtcal resume {})",
                    run_id, run.status, run_id));
  }
  const auto analysis = analyzeIso230_2(session, run_id);
  if (!request.axis.empty() && upper(request.axis) != upper(run.axis)) {
    throw InputError(fmt::format("run {} measured axis {}, not {}", run_id, run.axis, request.axis));
  }
  const auto ran = appliedTables(run.compensation_json)[static_cast<std::size_t>(axisIndex(run.axis, "run"))];
  auto c = tableFor(processing::axisErrorOf(analysis.result), fmt::format("run {}", run_id), upper(run.axis), request,
                    request.table, ran);
  // A direction never measured takes the other's error: a reversal there is not corrected.
  for (const auto& [name, measured] : {std::pair{"+", &processing::Iso230Position::mean_up_um},
                                       std::pair{"-", &processing::Iso230Position::mean_down_um}}) {
    const bool none = std::none_of(analysis.result.positions.begin(), analysis.result.positions.end(),
                                   [&](const auto& p) { return (p.*measured).has_value(); });
    if (none) {
      c.warnings.push_back(fmt::format(
          "run {} measured no target in the {} direction: the table's {} direction takes the other's correction, and "
          "a reversal (backlash) is not corrected",
          run_id, name, name));
    }
  }
  return c;
}

Compensation compensateModel(Session& session, storage::Id model_id, const CompensateRequest& request) {
  if (request.axis.empty()) throw InputError("a table from a model needs the axis (--axis X, Y or Z)");
  processing::checkTableOptions(request.table);
  // The model is read on the table's own grid (10 mm when not given).
  ModelAxisRequest at;
  at.axis = request.axis;
  at.from_mm = request.table.start;
  at.to_mm = request.table.end;
  at.step_mm = request.table.interval.value_or(10.0);
  at.at = request.at;
  const auto error = modelAxisError(session, model_id, at);
  processing::TableOptions options = request.table;
  options.interval.reset();
  auto c = tableFor(error.error, fmt::format("model {}", model_id), upper(request.axis), request, options);
  c.extensions_applied = error.applied;
  c.extensions_left_out = error.left_out;
  c.outside = error.outside;
  return c;
}

std::string compensationRecord(const std::vector<ControllerTable>& tables) {
  nlohmann::json record = nlohmann::json::object();
  for (const auto& t : tables) {
    const std::string axis = upper(t.axis);
    axisIndex(axis, t.path);
    if (record.contains(axis)) throw InputError(fmt::format("two compensation tables for axis {}", axis));
    const auto table = readCompensationFile(t.path, t.controller);
    record[axis] = {{"controller", processing::controllerFormat(t.controller).name},
                    {"file", t.path},
                    {"position", table.position},
                    {"correction_up_um", table.up_um},
                    {"correction_down_um", table.down_um}};
    if (table.modulo) record[axis]["modulo"] = *table.modulo;
  }
  return record.dump();
}

std::array<std::optional<AppliedTable>, 3> appliedTables(const std::string& compensation_json) {
  std::array<std::optional<AppliedTable>, 3> out;
  const auto record = nlohmann::json::parse(compensation_json, nullptr, false);
  if (!record.is_object()) throw InputError("stored compensation: not a JSON object");
  try {
    for (const auto& [axis, t] : record.items()) {
      AppliedTable a;
      a.controller = t.at("controller").get<std::string>();
      a.file = t.at("file").get<std::string>();
      a.rules = processing::controllerFormat(a.controller).rules;
      a.table.position = t.at("position").get<std::vector<double>>();
      a.table.up_um = t.at("correction_up_um").get<std::vector<double>>();
      a.table.down_um = t.at("correction_down_um").get<std::vector<double>>();
      if (t.contains("modulo")) a.table.modulo = t["modulo"].get<double>();
      processing::checkTable(a.table, "stored compensation");
      out[static_cast<std::size_t>(axisIndex(axis, "stored compensation"))] = std::move(a);
    }
  } catch (const nlohmann::json::exception& e) {
    throw InputError(std::string("stored compensation: ") + e.what());
  }
  return out;
}

void applyCompensation(const std::string& compensation_json, mocks::VirtualMachineConfig& machine) {
  const auto tables = appliedTables(compensation_json);
  for (std::size_t a = 0; a < 3; ++a) {
    machine.compensation[a].reset();
    if (tables[a])
      machine.compensation[a] = mocks::VirtualMachineConfig::AxisCompensation{tables[a]->table, tables[a]->rules};
  }
}

}  // namespace mtcal::services
