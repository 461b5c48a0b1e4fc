#include "mtcal/acquisition/import_linear.h"

#include <fmt/format.h>

#include <algorithm>
#include <charconv>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <optional>
#include <tuple>

#include "csv.h"
#include "mtcal/error.h"

namespace mtcal::acquisition {
namespace {

std::string lower(std::string s) {
  std::transform(s.begin(), s.end(), s.begin(), [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return s;
}

}  // namespace

ParsedLinearCsv parseLinearCsv(std::istream& in, const std::string& source, const LinearImportOptions& options) {
  csv::Reader reader(in, source);
  const std::vector<std::string> header = reader.next().value_or(std::vector<std::string>{});
  if (header.empty()) throw InputError(source + ": empty file, expected a header line");
  const int header_line = reader.line();

  std::map<std::string, std::size_t> col;
  for (std::size_t i = 0; i < header.size(); ++i) {
    if (header[i].empty()) throw InputError(fmt::format("{}:{}: column {} has no name", source, header_line, i + 1));
    if (!col.emplace(header[i], i).second) {
      throw InputError(fmt::format("{}:{}: column '{}' appears twice", source, header_line, header[i]));
    }
  }
  for (const char* required : {"target_mm", "direction", "cycle"}) {
    if (!col.count(required)) {
      throw InputError(
          fmt::format("{}:{}: missing column '{}' (need target_mm, direction, cycle and measured_mm or "
                      "deviation_um)",
                      source, header_line, required));
    }
  }
  const bool has_measured = col.count("measured_mm") > 0;
  const bool has_deviation = col.count("deviation_um") > 0;
  if (has_measured == has_deviation) {
    throw InputError(
        fmt::format("{}:{}: give exactly one of the columns measured_mm and deviation_um", source, header_line));
  }
  if (options.raw && !has_measured) {
    throw InputError(fmt::format("{}:{}: --raw needs a measured_mm column (raw laser readings)", source, header_line));
  }
  static const std::vector<std::string> kKnown = {"target_mm",    "direction",      "cycle",      "measured_mm",
                                                  "deviation_um", "time_s",         "air_temp_c", "air_pressure_pa",
                                                  "humidity_pct", "material_temp_c"};
  ParsedLinearCsv out;
  std::vector<std::size_t> channel_cols;
  for (std::size_t i = 0; i < header.size(); ++i) {
    if (std::find(kKnown.begin(), kKnown.end(), header[i]) == kKnown.end()) {
      out.channel_names.push_back(header[i]);
      channel_cols.push_back(i);
    }
  }

  std::map<std::tuple<long long, int, int>, int> seen;  // (target nm, direction, cycle) -> line
  while (const auto row = reader.row(header)) {
    const auto& cells = *row;
    const int line_no = reader.line();
    auto fail = [&](const std::string& column, const std::string& why) -> InputError {
      return InputError(fmt::format("{}:{}: column '{}': {}", source, line_no, column, why));
    };
    auto number = [&](const std::string& name) -> std::optional<double> {
      auto it = col.find(name);
      if (it == col.end() || cells[it->second].empty()) return std::nullopt;
      auto v = csv::number(cells[it->second]);
      if (!v) throw fail(name, "'" + cells[it->second] + "' is not a number");
      return v;
    };
    auto required = [&](const std::string& name) {
      auto v = number(name);
      if (!v) throw fail(name, "value missing");
      return *v;
    };

    storage::TargetRecord r;
    r.seq = static_cast<std::int64_t>(out.targets.size());
    r.target_mm = required("target_mm");
    const std::string dir = lower(cells[col["direction"]]);
    if (dir == "+" || dir == "up" || dir == "fwd" || dir == "forward") {
      r.direction = 1;
    } else if (dir == "-" || dir == "down" || dir == "bwd" || dir == "backward") {
      r.direction = -1;
    } else {
      throw fail("direction", "'" + cells[col["direction"]] + "' is not one of +, -, up, down, fwd, bwd");
    }
    const double cycle = required("cycle");
    if (cycle < 1 || cycle != std::floor(cycle) || cycle > 1e6) throw fail("cycle", "must be a whole number >= 1");
    r.cycle = static_cast<int>(cycle);
    r.time_s = number("time_s");
    r.air_temp_c = number("air_temp_c");
    r.air_pressure_pa = number("air_pressure_pa");
    r.humidity_pct = number("humidity_pct");
    r.material_temp_c = number("material_temp_c");

    if (has_deviation) {
      const double dev = required("deviation_um");
      r.deviation_um = dev;
      r.measured_mm = r.target_mm + dev / 1000.0;
    } else if (!options.raw) {
      r.measured_mm = required("measured_mm");
      r.deviation_um = (r.measured_mm - r.target_mm) * 1000.0;
    } else {
      const double raw_mm = required("measured_mm");
      if (!r.air_temp_c || !r.air_pressure_pa || !r.humidity_pct) {
        throw fail(!r.air_temp_c        ? "air_temp_c"
                   : !r.air_pressure_pa ? "air_pressure_pa"
                                        : "humidity_pct",
                   "--raw needs air_temp_c, air_pressure_pa and humidity_pct on every row");
      }
      double n;
      try {
        n = processing::airIndex(options.model, {*r.air_temp_c, *r.air_pressure_pa, *r.humidity_pct, options.co2_ppm},
                                 options.wavelength_nm);
      } catch (const InputError& e) {
        throw fail("air_temp_c/air_pressure_pa/humidity_pct", e.what());
      }
      double length_mm = processing::compensateWavelength(raw_mm, n);
      if (r.material_temp_c)
        length_mm = processing::normaliseTo20C(length_mm, *r.material_temp_c, options.expansion_per_k);
      r.air_index = n;
      r.measured_mm = options.datum_mm + length_mm;
      r.deviation_um = (r.measured_mm - r.target_mm) * 1000.0;
    }
    const auto key = std::tuple{std::llround(r.target_mm * 1e6), r.direction, r.cycle};
    if (auto [it, inserted] = seen.emplace(key, line_no); !inserted) {
      throw InputError(fmt::format("{}:{}: target {} mm, direction {}, cycle {} was already given on line {}", source,
                                   line_no, r.target_mm, r.direction > 0 ? "+" : "-", r.cycle, it->second));
    }
    storage::ChannelRow channels;
    for (std::size_t c = 0; c < channel_cols.size(); ++c) channels.push_back(number(header[channel_cols[c]]));
    out.targets.push_back(r);
    out.channel_rows.push_back(std::move(channels));
  }
  if (out.targets.empty()) throw InputError(source + ": no data rows after the header");
  return out;
}

storage::Id importLinearCsv(storage::Store& store, const std::string& path, const LinearImportOptions& options) {
  if (options.axis != "X" && options.axis != "Y" && options.axis != "Z") {
    throw InputError("--axis must be X, Y or Z, got '" + options.axis + "'");
  }
  std::ifstream in(path);
  if (!in) throw InputError(path + ": cannot open file");
  const ParsedLinearCsv parsed = parseLinearCsv(in, path, options);

  const std::string file_name = std::filesystem::path(path).filename().string();
  nlohmann::json plan = {{"type", "linear"},
                         {"axis", options.axis},
                         {"imported_from", file_name},
                         {"compensated_by", options.raw ? "mtcal" : "exporting software"}};
  if (options.raw) {
    plan["air_index_model"] = options.model == processing::AirIndexModel::kEdlen ? "edlen" : "ciddor";
    plan["wavelength_nm"] = options.wavelength_nm;
    plan["co2_ppm"] = options.co2_ppm;
    plan["expansion_per_k"] = options.expansion_per_k;
    plan["datum_mm"] = options.datum_mm;
  }
  // One transaction for everything, the machine and campaign rows included.
  storage::Transaction tx(store.database());
  storage::NewRun run;
  run.campaign_id = store.addCampaign(store.ensureMachine(options.machine, "", "{}"), "import " + file_name);
  run.kind = storage::run_kind::kLinear;
  run.axis = options.axis;
  run.name = options.name.empty() ? file_name : options.name;
  run.plan_json = plan.dump();
  run.status = storage::run_status::kImported;
  run.source = "imported";
  run.software_version = options.software_version;
  const storage::Id id = store.importRun(run, parsed.targets, parsed.channel_names, parsed.channel_rows);
  tx.commit();
  return id;
}

}  // namespace mtcal::acquisition
