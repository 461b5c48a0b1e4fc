#include "mtcal/acquisition/thermal_data.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <limits>
#include <map>
#include <nlohmann/json.hpp>

#include "mtcal/acquisition/csv.h"
#include "mtcal/error.h"

namespace mtcal::acquisition {
namespace {

constexpr double kMinTemperatureC = -60.0, kMaxTemperatureC = 300.0;
/// The fastest spindle's speed, either way (a PCB drill's turns at up to 300 000 rpm; a
/// controller may log a reversed spindle as negative).
constexpr double kFastestSpindleRpm = 300000.0;

bool endsWith(const std::string& s, const std::string& suffix) {
  return s.size() >= suffix.size() && s.compare(s.size() - suffix.size(), suffix.size(), suffix) == 0;
}

}  // namespace

void checkThermalImportOptions(const ThermalImportOptions& options) {
  if (options.interval_s && !(*options.interval_s > 0.0 && *options.interval_s <= kLongestRowIntervalS))
    throw InputError(fmt::format("--interval-s must be > 0 and at most {:.0f} s (a day), got {:g}",
                                 kLongestRowIntervalS, *options.interval_s));
}

ParsedThermalCsv parseThermalCsv(std::istream& in, const std::string& source, const ThermalImportOptions& options) {
  checkThermalImportOptions(options);
  CsvReader reader(in, source, options.csv);
  const auto time = reader.find("time_s");
  const auto segment = reader.find("segment");  // a run resumed after gaps: the samples after each gap
  reader.refuseUnusedMappings();
  if (time && options.interval_s) {
    throw InputError(fmt::format("{}:{}: --interval-s {:g}: the file's column '{}' gives each row's time", source,
                                 reader.headerLine(), *options.interval_s, time->header));
  }
  ParsedThermalCsv out;
  std::vector<CsvColumn> channel_columns;
  bool target_found = options.target.empty(), target_without_unit = false;
  std::vector<std::string> displacements_by_unit;  // headers whose unit is a length's
  for (const auto i : reader.unclaimed()) {
    const std::string& header = reader.header()[i];
    const CsvName name = csvName(header);
    const bool bracketed = !name.unit_text.empty() && !endsWith(header, "_" + name.unit_text);
    const bool is_target = !options.target.empty() && csvName(options.target).base == name.base;
    target_found = target_found || is_target;
    target_without_unit = target_without_unit || (is_target && !name.unit);
    if (name.unit && name.unit->quantity == "length") displacements_by_unit.push_back(header);
    // The target is the displacement the temperatures explain: a header whose unit says it is
    // a temperature or a speed is named by mistake.
    if (is_target && name.unit && name.unit->quantity != "length") {
      throw InputError(
          fmt::format("{}:{}: --target {}: its header says a {} ({}); the target is the displacement "
                      "the temperatures explain (a column in um or mm)",
                      source, reader.headerLine(), options.target, name.unit->quantity, name.unit_text));
    }
    // Kind and unit by the header's unit: a length is a displacement (um), rpm a speed, and
    // anything else a temperature (degC); a header without a unit keeps its name.
    storage::ThermalChannel c{header, "temperature", "degC"};
    double factor = 1.0;
    if ((name.unit && name.unit->quantity == "length") || is_target) {
      c = {bracketed ? name.base + "_um" : header, "displacement", "um"};
      if (name.unit && name.unit->quantity == "length") factor = name.unit->si / 1e-6;
    } else if (name.unit && name.unit->quantity == "speed") {
      c = {bracketed ? name.base + "_rpm" : header, "speed", "rpm"};
    } else if (name.unit && name.unit->quantity == "temperature") {
      if (bracketed) c.name = name.base;
    }  // a bracket that is no unit ("T1 (front bearing)") is part of a temperature's name
    channel_columns.push_back({i, header, factor, c.kind == "displacement" ? kLargestDeviationUm : 0.0});
    out.channels.push_back(c);
  }
  if (!target_found) {
    throw InputError(fmt::format("{}:{}: no column '{}' (--target)", source, reader.headerLine(), options.target));
  }
  // A target without a unit beside a displacement the file names by its unit: both are taken as
  // displacements, which a temperature given by mistake is not.
  if (target_without_unit && !displacements_by_unit.empty()) {
    out.warnings.push_back(fmt::format(
        "--target {}: taken as a displacement in um beside the one{} the file names by its unit ({}); if it is a "
        "temperature, import without --target: {} is the file's displacement by its unit",
        options.target, displacements_by_unit.size() > 1 ? "s" : "", fmt::join(displacements_by_unit, ", "),
        displacements_by_unit.front()));
  }
  const auto count = [&](const char* kind) {
    return std::count_if(out.channels.begin(), out.channels.end(), [&](const auto& c) { return c.kind == kind; });
  };
  if (count("displacement") == 0) {
    throw InputError(
        fmt::format("{}:{}: no displacement column (a name ending in _um, a length unit like "
                    "'drift [um]', or --target COLUMN)",
                    source, reader.headerLine()));
  }
  if (count("temperature") == 0)
    throw InputError(fmt::format("{}:{}: no temperature column", source, reader.headerLine()));

  while (const auto row = reader.row()) {
    const auto& cells = *row;
    storage::ThermalSample s;
    s.index = static_cast<std::int64_t>(out.samples.size());
    s.time_s = static_cast<double>(s.index) * options.interval_s.value_or(kRowIntervalS);
    s.values.resize(out.channels.size());
    if (time) {
      const double t = reader.required(cells, *time);
      if (!out.samples.empty() && !(t > out.samples.back().time_s)) {
        throw reader.error(time->header, fmt::format("{} does not follow {}", t, out.samples.back().time_s));
      }
      s.time_s = t;
    }
    if (segment) {
      const auto v = reader.number(cells, *segment);
      const int before = out.samples.empty() ? 0 : out.samples.back().segment;
      if (!v || *v != std::floor(*v) || *v < before || *v > 1e6) {
        throw reader.error(segment->header,
                           fmt::format("'{}' is not a whole number from {} on", cells[segment->index], before));
      }
      s.segment = static_cast<int>(*v);
    }
    for (std::size_t c = 0; c < channel_columns.size(); ++c) {
      const auto v = reader.number(cells, channel_columns[c]);
      if (!v) continue;  // missing
      if (out.channels[c].kind == "temperature" && (*v < kMinTemperatureC || *v > kMaxTemperatureC)) {
        throw reader.error(channel_columns[c].header,
                           fmt::format("{} degC is outside {}..{} degC (a sensor fault? leave the cell empty){}", *v,
                                       kMinTemperatureC, kMaxTemperatureC,
                                       time ? ""
                                            : "; a column that is not a length or a speed is a temperature: a "
                                              "time column is time_s, or --columns time_s=HEADER"));
      }
      if (out.channels[c].kind == "speed" && !(std::abs(*v) <= kFastestSpindleRpm)) {
        throw reader.error(channel_columns[c].header,
                           fmt::format("{:g} rpm is beyond +-{:.0f} rpm, a spindle's fastest (leave the cell empty "
                                       "where it was not read)",
                                       *v, kFastestSpindleRpm));
      }
      s.values[c] = *v;
    }
    out.samples.push_back(std::move(s));
  }
  if (out.samples.empty()) throw InputError(source + ": no data rows");
  return out;
}

ThermalCsvImport importThermalCsv(const StoreWhenNeeded& store_when_needed, std::istream& in, const std::string& path,
                                  const ThermalImportOptions& options) {
  const ParsedThermalCsv parsed = parseThermalCsv(in, path, options);
  const std::string file_name = std::filesystem::path(path).filename().string();
  auto& store = store_when_needed();
  storage::Transaction tx(store.database());
  storage::NewRun run;
  run.campaign_id = store.addCampaign(store.ensureMachine(options.machine, "", "{}"), "import " + file_name);
  run.kind = storage::run_kind::kThermal;
  run.name = options.name.empty() ? file_name : options.name;
  nlohmann::json plan = {
      {"type", "thermal"}, {"imported_from", file_name}, {"interval_s", options.interval_s.value_or(kRowIntervalS)}};
  if (!options.source_sha256.empty()) plan["imported_sha256"] = options.source_sha256;
  if (!parsed.warnings.empty()) plan["import_warnings"] = parsed.warnings;  // said again where the run is used
  run.plan_json = plan.dump();
  run.status = storage::run_status::kImported;
  run.source = "imported";
  run.software_version = options.software_version;
  const storage::Id id = store.addRun(run);
  store.addThermalChannels(id, parsed.channels);
  store.addThermalSamples(id, parsed.samples);
  tx.commit();
  return {id, parsed.warnings};
}

void writeThermalCsv(storage::Store& store, storage::Id run_id, std::ostream& out) {
  const auto info = store.run(run_id);
  if (info.kind != storage::run_kind::kThermal)
    throw InputError(fmt::format("run {} is {}, not a thermal one", run_id, storage::run_kind::aRunOf(info.kind)));
  const auto channels = store.thermalChannels(run_id);
  const auto samples = store.thermalSamples(run_id);
  // A run resumed after gaps holds segments: the column keeps them (the import reads it).
  const bool segments = std::any_of(samples.begin(), samples.end(), [](const auto& s) { return s.segment != 0; });
  out << fmt::format("# mtcal thermal run {}: {}\ntime_s{}", run_id, info.name, segments ? ",segment" : "");
  for (const auto& c : channels) {
    // The import tells kinds by the name's suffix: give displacement and speed columns theirs.
    std::string name = c.name;
    if (c.kind == "displacement" && !endsWith(name, "_um")) name += "_um";
    if (c.kind == "speed" && !endsWith(name, "_rpm")) name += "_rpm";
    out << "," << name;
  }
  out << "\n";
  for (const auto& s : samples) {
    out << fmt::format("{}", s.time_s);
    if (segments) out << "," << s.segment;
    for (const auto& v : s.values) out << "," << (v ? fmt::format("{}", *v) : std::string());
    out << "\n";
  }
}

processing::ThermalData thermalDataOfRun(storage::Store& store, storage::Id run_id, const std::string& target,
                                         bool with_speed) {
  const auto info = store.run(run_id);
  if (info.kind != storage::run_kind::kThermal)
    throw InputError(fmt::format("run {} is {}, not a thermal one", run_id, storage::run_kind::aRunOf(info.kind)));
  const auto channels = store.thermalChannels(run_id);
  const auto samples = store.thermalSamples(run_id);
  std::vector<std::string> displacements;
  int target_channel = -1;
  std::vector<int> temperature_channels;
  processing::ThermalData d;
  for (std::size_t c = 0; c < channels.size(); ++c) {
    if (channels[c].kind == "displacement") displacements.push_back(channels[c].name);
    if (channels[c].name == target) target_channel = static_cast<int>(c);
    if (channels[c].kind == "temperature" || (with_speed && channels[c].kind == "speed")) {
      temperature_channels.push_back(static_cast<int>(c));
      d.sensors.push_back(channels[c].name);
    }
  }
  if (target_channel < 0) {
    throw InputError(fmt::format("run {} has no channel '{}' (its displacements: {})", run_id, target,
                                 fmt::join(displacements, ", ")));
  }
  // The target is what the sensors explain, in um: a temperature or a speed is an input.
  if (const auto& kind = channels[static_cast<std::size_t>(target_channel)].kind; kind != "displacement") {
    throw InputError(fmt::format("run {}: '{}' is a {} channel, not a displacement (its displacements: {})", run_id,
                                 target, kind, fmt::join(displacements, ", ")));
  }
  const auto n = static_cast<Eigen::Index>(samples.size());
  const double nan = std::numeric_limits<double>::quiet_NaN();
  d.temperature_c.resize(n, static_cast<Eigen::Index>(temperature_channels.size()));
  d.target_um.resize(n);
  d.time_s.resize(n);
  for (Eigen::Index i = 0; i < n; ++i) {
    const auto& s = samples[static_cast<std::size_t>(i)];
    d.time_s(i) = s.time_s;
    d.segment.push_back(s.segment);
    d.target_um(i) = s.values[static_cast<std::size_t>(target_channel)].value_or(nan);
    for (std::size_t c = 0; c < temperature_channels.size(); ++c) {
      d.temperature_c(i, static_cast<Eigen::Index>(c)) =
          s.values[static_cast<std::size_t>(temperature_channels[c])].value_or(nan);
    }
  }
  return d;
}

}  // namespace mtcal::acquisition
