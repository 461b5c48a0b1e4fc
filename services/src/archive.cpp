#include "mtcal/services/archive.h"

namespace mtcal::services {

nlohmann::json runDocument(const storage::RunInfo& run) {
  return {{"id", run.id},
          {"name", run.name},
          {"kind", run.kind},
          {"axis", run.axis},
          {"status", run.status},
          {"source", run.source},
          {"machine", run.machine_name},
          {"campaign", run.campaign_name},
          {"campaign_id", run.campaign_id},
          {"instrument_id", run.instrument_id ? nlohmann::json(*run.instrument_id) : nlohmann::json(nullptr)},
          {"targets", run.target_count},
          {"software_version", run.software_version},
          {"started_at", run.started_at},
          {"finished_at", run.finished_at ? nlohmann::json(*run.finished_at) : nlohmann::json(nullptr)}};
}

std::vector<storage::RunInfo> listRuns(Session& session) { return session.store().listRuns(); }

RunDetail showRun(Session& session, storage::Id run_id) {
  auto& store = session.store();
  RunDetail d;
  d.run = store.run(run_id);
  d.targets = store.targets(run_id);
  d.events = store.events(run_id);
  d.channels = store.channelNames(run_id);
  if (d.run.source == "acquired") d.raw_samples = store.sampleCount(run_id);
  if (d.run.kind == "gantry") d.tracker_points = store.trackerPointCount(run_id);
  if (d.run.kind == "thermal") {
    d.thermal_samples = store.thermalSampleCount(run_id);
    d.thermal_channels = store.thermalChannels(run_id);
  }
  return d;
}

nlohmann::json RunDetail::document() const {
  nlohmann::json j = runDocument(run);
  j["schema_version"] = 1;
  j["plan"] = nlohmann::json::parse(run.plan_json);
  j["channels"] = channels;
  nlohmann::json t = nlohmann::json::array();
  for (const auto& r : targets) {
    t.push_back({{"seq", r.seq},
                 {"target_mm", r.target_mm},
                 {"direction", r.direction > 0 ? "up" : "down"},
                 {"cycle", r.cycle},
                 {"measured_mm", r.measured_mm},
                 {"deviation_um", r.deviation_um},
                 {"samples", r.sample_count}});
  }
  j["target_values"] = t;
  if (run.kind == "gantry") j["tracker_points"] = tracker_points;
  if (run.kind == "thermal") {
    j["thermal_samples"] = thermal_samples;
    nlohmann::json c = nlohmann::json::array();
    for (const auto& ch : thermal_channels) c.push_back({{"name", ch.name}, {"kind", ch.kind}, {"unit", ch.unit}});
    j["thermal_channels"] = c;
  }
  nlohmann::json e = nlohmann::json::array();
  for (const auto& ev : events) e.push_back({{"level", ev.level}, {"message", ev.message}, {"time", ev.created_at}});
  j["events"] = e;
  return j;
}

}  // namespace mtcal::services
