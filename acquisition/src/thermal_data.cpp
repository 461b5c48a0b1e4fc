#include "mtcal/acquisition/thermal_data.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <limits>
#include <map>
#include <nlohmann/json.hpp>

#include "csv.h"
#include "mtcal/error.h"

namespace mtcal::acquisition {
namespace {

constexpr double kMinTemperatureC = -60.0, kMaxTemperatureC = 300.0;

bool endsWith(const std::string& s, const std::string& suffix) {
  return s.size() >= suffix.size() && s.compare(s.size() - suffix.size(), suffix.size(), suffix) == 0;
}

}  // namespace

ParsedThermalCsv parseThermalCsv(std::istream& in, const std::string& source, const ThermalImportOptions& options) {
  if (!(options.interval_s > 0.0))
    throw InputError(fmt::format("--interval-s must be > 0, got {}", options.interval_s));
  csv::Reader reader(in, source);
  const std::vector<std::string> header = reader.next().value_or(std::vector<std::string>{});
  if (header.empty()) throw InputError(source + ": empty file, expected a header line");
  const int header_line = reader.line();
  ParsedThermalCsv out;
  std::map<std::string, int> seen;
  int time_column = -1, segment_column = -1;
  std::vector<int> channel_of_column(header.size(), -1);
  for (std::size_t i = 0; i < header.size(); ++i) {
    const std::string& name = header[i];
    if (name.empty()) throw InputError(fmt::format("{}:{}: column {} has no name", source, header_line, i + 1));
    if (seen[name]++) throw InputError(fmt::format("{}:{}: column '{}' appears twice", source, header_line, name));
    if (name == "time_s") {
      time_column = static_cast<int>(i);
      continue;
    }
    if (name == "segment") {  // a run resumed after gaps: the samples after each gap
      segment_column = static_cast<int>(i);
      continue;
    }
    storage::ThermalChannel c{name, "temperature", "degC"};
    if (endsWith(name, "_um") || name == options.target) c = {name, "displacement", "um"};
    if (endsWith(name, "_rpm")) c = {name, "speed", "rpm"};
    channel_of_column[i] = static_cast<int>(out.channels.size());
    out.channels.push_back(c);
  }
  if (!options.target.empty() && !seen.count(options.target)) {
    throw InputError(fmt::format("{}:{}: no column '{}' (--target)", source, header_line, options.target));
  }
  const auto count = [&](const char* kind) {
    return std::count_if(out.channels.begin(), out.channels.end(), [&](const auto& c) { return c.kind == kind; });
  };
  if (count("displacement") == 0) {
    throw InputError(
        fmt::format("{}:{}: no displacement column (a name ending in _um, or --target COLUMN)", source, header_line));
  }
  if (count("temperature") == 0) throw InputError(fmt::format("{}:{}: no temperature column", source, header_line));

  while (const auto row = reader.row(header)) {
    const auto& cells = *row;
    const int line_no = reader.line();
    storage::ThermalSample s;
    s.index = static_cast<std::int64_t>(out.samples.size());
    s.time_s = static_cast<double>(s.index) * options.interval_s;
    s.values.resize(out.channels.size());
    for (std::size_t i = 0; i < cells.size(); ++i) {
      const std::string& cell = cells[i];
      if (static_cast<int>(i) == time_column) {
        const auto v = csv::number(cell);
        if (!v) throw InputError(fmt::format("{}:{}: column 'time_s': '{}' is not a number", source, line_no, cell));
        if (!out.samples.empty() && !(*v > out.samples.back().time_s)) {
          throw InputError(fmt::format("{}:{}: column 'time_s': {} does not follow {}", source, line_no, *v,
                                       out.samples.back().time_s));
        }
        s.time_s = *v;
        continue;
      }
      if (static_cast<int>(i) == segment_column) {
        const auto v = csv::number(cell);
        const int before = out.samples.empty() ? 0 : out.samples.back().segment;
        if (!v || *v != std::floor(*v) || *v < before || *v > 1e6) {
          throw InputError(fmt::format("{}:{}: column 'segment': '{}' is not a whole number from {} on", source,
                                       line_no, cell, before));
        }
        s.segment = static_cast<int>(*v);
        continue;
      }
      if (cell.empty()) continue;  // missing
      const auto v = csv::number(cell);
      if (!v)
        throw InputError(fmt::format("{}:{}: column '{}': '{}' is not a number", source, line_no, header[i], cell));
      const auto& channel = out.channels[static_cast<std::size_t>(channel_of_column[i])];
      if (channel.kind == "temperature" && (*v < kMinTemperatureC || *v > kMaxTemperatureC)) {
        throw InputError(
            fmt::format("{}:{}: column '{}': {} degC is outside {}..{} degC (a sensor fault? leave the cell empty)",
                        source, line_no, header[i], *v, kMinTemperatureC, kMaxTemperatureC));
      }
      s.values[static_cast<std::size_t>(channel_of_column[i])] = *v;
    }
    out.samples.push_back(std::move(s));
  }
  if (out.samples.empty()) throw InputError(source + ": no data rows");
  return out;
}

storage::Id importThermalCsv(storage::Store& store, const std::string& path, const ThermalImportOptions& options) {
  std::ifstream in(path);
  if (!in) throw InputError(path + ": cannot open file");
  const ParsedThermalCsv parsed = parseThermalCsv(in, path, options);
  const std::string file_name = std::filesystem::path(path).filename().string();
  storage::Transaction tx(store.database());
  storage::NewRun run;
  run.campaign_id = store.addCampaign(store.ensureMachine(options.machine, "", "{}"), "import " + file_name);
  run.kind = storage::run_kind::kThermal;
  run.name = options.name.empty() ? file_name : options.name;
  run.plan_json =
      nlohmann::json{{"type", "thermal"}, {"imported_from", file_name}, {"interval_s", options.interval_s}}.dump();
  run.status = storage::run_status::kImported;
  run.source = "imported";
  run.software_version = options.software_version;
  const storage::Id id = store.addRun(run);
  store.addThermalChannels(id, parsed.channels);
  store.addThermalSamples(id, parsed.samples);
  tx.commit();
  return id;
}

void writeThermalCsv(storage::Store& store, storage::Id run_id, std::ostream& out) {
  const auto info = store.run(run_id);
  if (info.kind != storage::run_kind::kThermal)
    throw InputError(fmt::format("run {} is a {} run, not a thermal one", run_id, info.kind));
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
    throw InputError(fmt::format("run {} is a {} run, not a thermal one", run_id, info.kind));
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
