#include "mtcal/services/export.h"

#include <fmt/format.h>
#include <stdlib.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <optional>
#include <sstream>

#include "mtcal/acquisition/error_models.h"
#include "mtcal/acquisition/est_run.h"
#include "mtcal/error.h"
#include "mtcal/services/archive.h"
#include "mtcal/services/gantry.h"
#include "mtcal/services/thermal.h"
#include "mtcal/services/workshop.h"

namespace mtcal::services {

namespace {

/// A number as text that reads back to the same double; an empty cell for none.
std::string cell(const std::optional<double>& v) { return v ? fmt::format("{}", *v) : std::string(); }

/// The files of one export: written into a folder (each whole, all removed again when one
/// fails), or only listed, or one of them kept as text (the dashboard's downloads).
class ExportWriter {
 public:
  enum class Mode { kFolder, kList, kOne };
  ExportWriter(Mode mode, std::filesystem::path dir, storage::Id run_id, std::string only = "")
      : mode_(mode), dir_(std::move(dir)), run_id_(run_id), only_(std::move(only)) {
    if (mode_ != Mode::kFolder) return;
    std::error_code ec;
    // The outermost folder this export makes: taken away again if it fails.
    for (auto missing = dir_.lexically_normal(); !missing.empty() && !std::filesystem::exists(missing, ec);
         missing = missing.parent_path()) {
      made_ = missing;
      if (missing == missing.parent_path()) break;
    }
    std::filesystem::create_directories(dir_, ec);
    if (ec) throw InputError(fmt::format("export: cannot create the folder {}: {}", dir_.string(), ec.message()));
  }
  ~ExportWriter() {
    if (done_) return;
    std::error_code ec;
    for (const auto& f : files_) std::filesystem::remove(f.path, ec);
    if (mode_ == Mode::kOne) std::filesystem::remove_all(dir_, ec);
    if (!made_.empty()) std::filesystem::remove_all(made_, ec);
  }
  ExportWriter(const ExportWriter&) = delete;
  ExportWriter& operator=(const ExportWriter&) = delete;

  /// Whether the file `name` is written (in the other modes only its name is taken).
  bool writes(const std::string& name) const {
    return mode_ == Mode::kFolder || (mode_ == Mode::kOne && name == only_);
  }
  /// The path of run<ID>_<name>, which the export will write (removed again if it fails).
  std::string reserve(const std::string& name, const std::string& what) {
    const auto path = (dir_ / fmt::format("run{}_{}", run_id_, name)).string();
    if (mode_ == Mode::kFolder && std::filesystem::exists(path))
      throw InputError("export: " + path + " exists already: give another folder");
    files_.push_back({path, what});
    return path;
  }
  /// Writes run<ID>_<name> with `write`. @return its path
  std::string add(const std::string& name, const std::string& what, const std::function<void(std::ostream&)>& write) {
    const auto path = reserve(name, what);
    if (!writes(name)) return path;
    std::ofstream out(path);
    if (!out) throw InputError("export: cannot write " + path);
    write(out);
    if (!out.flush()) throw InputError("export: writing " + path + " failed (disk full?)");
    return path;
  }
  std::vector<ExportedFile> finish() {
    if (mode_ == Mode::kOne) return files_;  // the destructor removes the private folder
    done_ = true;
    return files_;
  }

 private:
  Mode mode_;
  std::filesystem::path dir_;
  storage::Id run_id_;
  std::string only_;
  std::vector<ExportedFile> files_;
  bool done_ = false;
  std::filesystem::path made_;  ///< the outermost folder made (kFolder), empty: none
};

std::string shellQuoted(const std::string& path) { return "'" + path + "'"; }

/// A linear run's measured line as the campaign manifest gives it: axis, measures, the line
/// position and the reflector offset.
nlohmann::json lineSetupOf(const storage::RunInfo& run) {
  const auto plan = acquisition::lineSetupOf(run);
  return {{"axis", plan.axis},
          {"measures", acquisition::measuredError(plan)},
          {"line_position_mm", plan.line_position_mm},
          {"reflector_offset_mm", plan.reflector_offset_mm}};
}

}  // namespace

nlohmann::json RunExport::document() const {
  nlohmann::json files_json = nlohmann::json::array();
  for (const auto& f : files) files_json.push_back({{"path", f.path}, {"what", f.what}});
  return {{"schema_version", 1}, {"run_id", run_id}, {"files", files_json}, {"import_command", import_command}};
}

namespace {

/// The export of a run through `writer`.
RunExport exportWith(Session& session, storage::Id run_id, ExportWriter& writer) {
  auto& store = session.store();
  const auto detail = showRun(session, run_id);
  const auto& run = detail.run;
  RunExport r;
  r.run_id = run_id;
  if (run.kind == storage::run_kind::kLinear) {
    const auto& targets = detail.targets;
    const auto& channels = detail.channels;
    const auto channel_rows = store.channelRows(run_id);
    const std::string value = run.value_unit == "urad" ? "deviation_urad" : "deviation_um";
    const auto path = writer.add("targets.csv", "targets (the import linear format)", [&](std::ostream& out) {
      out << "target_mm,direction,cycle," << value << ",time_s,air_temp_c,air_pressure_pa,humidity_pct,material_temp_c";
      for (const auto& c : channels) out << "," << c;
      out << "\n";
      for (std::size_t i = 0; i < targets.size(); ++i) {
        const auto& t = targets[i];
        out << fmt::format("{},{},{},{},{},{},{},{},{}", t.target_mm, t.direction > 0 ? "+" : "-", t.cycle,
                           t.deviation_um, cell(t.time_s), cell(t.air_temp_c), cell(t.air_pressure_pa),
                           cell(t.humidity_pct), cell(t.material_temp_c));
        for (std::size_t c = 0; c < channels.size(); ++c)
          out << "," << (i < channel_rows.size() && c < channel_rows[i].size() ? cell(channel_rows[i][c]) : "");
        out << "\n";
      }
    });
    const auto setup = lineSetupOf(run);
    std::string options = fmt::format("--axis {} --measures {}", run.axis, setup.at("measures").get<std::string>());
    std::vector<std::string> line;
    for (const auto& [axis, mm] : setup["line_position_mm"].items())
      line.push_back(fmt::format("{}={}", axis, mm.get<double>()));
    if (!line.empty()) options += fmt::format(" --line-position-mm {}", fmt::join(line, ","));
    const auto& o = setup["reflector_offset_mm"];
    options +=
        fmt::format(" --reflector-offset-mm {},{},{}", o[0].get<double>(), o[1].get<double>(), o[2].get<double>());
    r.import_command =
        fmt::format("mtcal import linear {} {} --name {}", shellQuoted(path), options, shellQuoted(run.name));
    if (run.source == "acquired") {
      writer.add("samples.csv", "raw samples (device sequence, device time, uncompensated reading mm, signal %)",
                 [&](std::ostream& out) {
                   out << "device_seq,device_time_ns,value_mm,signal_pct\n";
                   store.forEachSample(run_id, [&](const storage::SampleRecord& s) {
                     out << fmt::format("{},{},{},{}\n", s.device_seq, s.device_time_ns, s.value, s.signal_pct);
                   });
                 });
      const auto environment = store.environment(run_id);
      writer.add("environment.csv", "environment unit readings", [&](std::ostream& out) {
        out << "device_time_ns,air_temp_c,air_pressure_pa,humidity_pct,material_temp1_c,material_temp2_c,"
               "material_temp3_c\n";
        for (const auto& e : environment) {
          out << fmt::format("{},{},{},{},{},{},{}\n", e.device_time_ns ? std::to_string(*e.device_time_ns) : "",
                             cell(e.air_temp_c), cell(e.air_pressure_pa), cell(e.humidity_pct),
                             cell(e.material_temp1_c), cell(e.material_temp2_c), cell(e.material_temp3_c));
        }
      });
    }
  } else if (run.kind == storage::run_kind::kCircle) {
    const auto points = store.circlePoints(run_id);
    const auto plan = nlohmann::json::parse(run.plan_json);
    const auto path = writer.add("points.csv", "circle points (the import circle format)", [&](std::ostream& out) {
      out << "direction,angle_deg,deviation_um,time_s\n";
      for (const auto& p : points)
        out << fmt::format("{},{},{},{}\n", p.direction, p.angle_deg, p.deviation_um, cell(p.time_s));
    });
    // The centre where the plan has it: a model predicts a circle about its centre on the machine.
    std::string centre;
    if (const auto c = plan.find("centre_mm"); c != plan.end() && c->is_array() && c->size() == 3)
      centre =
          fmt::format(" --centre-mm {},{},{}", (*c)[0].get<double>(), (*c)[1].get<double>(), (*c)[2].get<double>());
    r.import_command = fmt::format("mtcal import circle {} --radius-mm {} --plane {} --feed-mm-min {}{} --name {}",
                                   shellQuoted(path), plan.at("radius_mm").get<double>(), run.axis,
                                   plan.value("feed_mm_per_min", 1000.0), centre, shellQuoted(run.name));
  } else if (run.kind == storage::run_kind::kEst) {
    const auto est = acquisition::storedEstRun(store, run);
    const std::size_t probes = est.v3_um.empty() ? 2 : 3;
    // The probes' scatter at each step, where the run has it: the noise the diagnosis is told.
    const bool scatter = processing::pooledProbeScatter(est).known();
    const auto path = writer.add("steps.csv", "probe readings (the import est format)", [&](std::ostream& out) {
      out << "x_mm";
      for (std::size_t p = 1; p <= probes; ++p) out << ",v" << p << "_um";
      if (scatter) {
        for (std::size_t p = 1; p <= probes; ++p) out << ",s" << p << "_um";
        out << ",readings";
      }
      out << "\n";
      for (std::size_t k = 0; k < est.position_mm.size(); ++k) {
        out << fmt::format("{}", est.position_mm[k]);
        for (std::size_t p = 0; p < probes; ++p) out << fmt::format(",{}", est.probeUm(p)[k]);
        if (scatter) {
          for (std::size_t p = 0; p < probes; ++p)
            out << "," << (std::isnan(est.scatter_um[p][k]) ? std::string() : fmt::format("{}", est.scatter_um[p][k]));
          out << "," << est.readings[k];
        }
        out << "\n";
      }
    });
    r.import_command = fmt::format("mtcal import est {} --spacing-mm {} --name {}", shellQuoted(path), est.spacing_mm,
                                   shellQuoted(run.name));
    if (const auto zeroing = acquisition::storedZeroing(store, run_id))  // the probes' readings on the flat
      r.import_command += fmt::format(" --zero-readings-um {}", fmt::join(zeroing->zero_um, ","));
  } else if (run.kind == storage::run_kind::kThermal) {
    const auto path = writer.add("samples.csv", "thermal samples (the import thermal format)",
                                 [&](std::ostream& out) { exportThermal(session, run_id, out); });
    r.import_command = fmt::format("mtcal import thermal {}", shellQuoted(path));
  } else if (run.kind == storage::run_kind::kGantry) {
    // The measurement file is JSON (docs/gantry.md): written by the gantry export itself.
    const auto path = writer.reserve("measurements.json", "tracker measurements (the gantry measurement file)");
    if (writer.writes("measurements.json")) exportGantry(session, run_id, path);
    r.import_command = fmt::format("mtcal gantry evaluate {}", shellQuoted(path));
  }
  writer.add("results.json", "stored results (processor, version, parameters, output)", [&](std::ostream& out) {
    nlohmann::json results = nlohmann::json::array();
    for (const auto& res : detail.results) {
      results.push_back({{"id", res.id},
                         {"processor", res.processor},
                         {"version", res.processor_version},
                         {"parameters", nlohmann::json::parse(res.parameters_json, nullptr, false)},
                         {"output", nlohmann::json::parse(res.output_json, nullptr, false)},
                         {"created_at", res.created_at}});
    }
    out << results.dump(1) << "\n";
  });
  writer.add("run.json", "the run: machine, campaign, instruments, plan, notes, events (mtcal show --json)",
             [&](std::ostream& out) { out << detail.document().dump(1) << "\n"; });
  r.files = writer.finish();
  return r;
}

}  // namespace

RunExport exportRun(Session& session, storage::Id run_id, const std::string& dir) {
  ExportWriter writer(ExportWriter::Mode::kFolder, dir, run_id);
  return exportWith(session, run_id, writer);
}

nlohmann::json CampaignExport::document() const {
  nlohmann::json run_documents = nlohmann::json::array();
  for (const auto& r : runs) run_documents.push_back(r.document());
  return {{"schema_version", 1},
          {"campaign_id", campaign_id},
          {"manifest", manifest},
          {"runs", run_documents},
          {"import_command", import_command}};
}

CampaignExport exportCampaign(Session& session, storage::Id campaign_id, const std::string& dir) {
  RunFilter filter;
  filter.campaign = campaign_id;
  const auto runs = listRuns(session, filter);
  if (runs.empty()) throw InputError(fmt::format("campaign {} has no runs", campaign_id));
  CampaignExport out;
  out.campaign_id = campaign_id;
  out.manifest = (std::filesystem::path(dir) / fmt::format("campaign{}.json", campaign_id)).string();
  if (std::filesystem::exists(out.manifest))
    throw InputError("export: " + out.manifest + " exists already: give another folder");
  nlohmann::json manifest = {
      {"name", runs.front().campaign_name}, {"machine", runs.front().machine_name}, {"runs", nlohmann::json::array()}};
  try {
    for (const auto& run : runs) {
      out.runs.push_back(exportRun(session, run.id, dir));
      if (run.kind != storage::run_kind::kLinear) continue;
      nlohmann::json entry = lineSetupOf(run);
      entry["file"] = fmt::format("run{}_targets.csv", run.id);
      entry["name"] = run.name;
      manifest["runs"].push_back(entry);
    }
    if (manifest["runs"].empty())
      throw InputError(fmt::format("campaign {} has no linear run: nothing for a campaign manifest", campaign_id));
    writeTextFile(out.manifest, manifest.dump(1) + "\n");
  } catch (...) {
    std::error_code ec;
    for (const auto& r : out.runs)
      for (const auto& f : r.files) std::filesystem::remove(f.path, ec);
    throw;
  }
  out.import_command = fmt::format("mtcal import campaign {}", shellQuoted(out.manifest));
  return out;
}

std::vector<ExportedFile> exportedFiles(Session& session, storage::Id run_id) {
  ExportWriter writer(ExportWriter::Mode::kList, "", run_id);
  auto files = exportWith(session, run_id, writer).files;
  for (auto& f : files) f.path = std::filesystem::path(f.path).filename().string();
  return files;
}

std::string exportedFile(Session& session, storage::Id run_id, const std::string& name) {
  // One pass in a private folder: the export names all its files and writes only `name`, which
  // is read back; the folder is removed with the writer.
  std::string dir = (std::filesystem::temp_directory_path() / "mtcal-export-XXXXXX").string();
  if (!::mkdtemp(dir.data()))
    throw InputError(fmt::format("export: cannot make a temporary folder: {}", std::strerror(errno)));
  ExportWriter writer(ExportWriter::Mode::kOne, dir, run_id, name);
  const auto files = exportWith(session, run_id, writer).files;
  const auto path = (std::filesystem::path(dir) / fmt::format("run{}_{}", run_id, name)).string();
  if (std::none_of(files.begin(), files.end(), [&](const ExportedFile& f) { return f.path == path; })) {
    std::string names;
    for (const auto& f : files) {
      const auto file = std::filesystem::path(f.path).filename().string();
      names += (names.empty() ? "" : ", ") + file.substr(file.find('_') + 1);
    }
    throw InputError(fmt::format("run {} exports no file '{}' (its files: {})", run_id, name, names));
  }
  return readTextFile(path);
}

}  // namespace mtcal::services
