#include "mtcal/archive/run_content.h"

#include <fmt/format.h>
#include <openssl/evp.h>

#include <cmath>
#include <map>
#include <set>
#include <stdexcept>

#include "mtcal/error.h"

namespace mtcal::archive {

const std::vector<RunPart>& runParts() {
  // Local row ids never leave the store: rows are numbered within their run (idx, type n), a
  // target's samples by their order in the run (type k), a channel value by its channel's name
  // and target's seq.
  static const std::vector<RunPart> kParts = {
      {"samples", "idx, device_seq, device_time_ns, value, signal_pct", "niiri",
       "SELECT device_seq, device_time_ns, value, signal_pct FROM samples WHERE run_id = ?1 ORDER BY rowid",
       "INSERT INTO samples(run_id, device_seq, device_time_ns, value, signal_pct) VALUES (?1, ?4, ?5, ?6, ?7)", true},
      {"targets",
       "seq, target_mm, direction, cycle, measured_mm, deviation_um, time_s, sample_count, sample_stddev_um,"
       " air_temp_c, air_pressure_pa, humidity_pct, material_temp_c, air_index, first_sample, last_sample, captured_at",
       "iriirrrirrrrrrkkt",
       "SELECT seq, target_mm, direction, cycle, measured_mm, deviation_um, time_s, sample_count, sample_stddev_um,"
       " air_temp_c, air_pressure_pa, humidity_pct, material_temp_c, air_index, first_sample_rowid,"
       " last_sample_rowid, captured_at FROM targets WHERE run_id = ?1 ORDER BY seq",
       "INSERT INTO targets(run_id, seq, target_mm, direction, cycle, measured_mm, deviation_um, time_s, sample_count,"
       " sample_stddev_um, air_temp_c, air_pressure_pa, humidity_pct, material_temp_c, air_index, first_sample_rowid,"
       " last_sample_rowid, captured_at) VALUES (?1, ?3, ?4, ?5, ?6, ?7, ?8, ?9, ?10, ?11, ?12, ?13, ?14, ?15, ?16,"
       " ?2 + ?17, ?2 + ?18, ?19)",
       false},
      {"environment",
       "idx, device_time_ns, air_temp_c, air_pressure_pa, humidity_pct, material_temp1_c, material_temp2_c,"
       " material_temp3_c, recorded_at",
       "nirrrrrrt",
       "SELECT device_time_ns, air_temp_c, air_pressure_pa, humidity_pct,"
       " material_temp1_c, material_temp2_c, material_temp3_c, recorded_at FROM environment WHERE run_id = ?1"
       " ORDER BY id",
       "INSERT INTO environment(run_id, device_time_ns, air_temp_c, air_pressure_pa, humidity_pct, material_temp1_c,"
       " material_temp2_c, material_temp3_c, recorded_at) VALUES (?1, ?4, ?5, ?6, ?7, ?8, ?9, ?10, ?11)",
       false},
      {"channels", "idx, name", "nt", "SELECT name FROM channels WHERE run_id = ?1 ORDER BY id",
       "INSERT INTO channels(run_id, name) VALUES (?1, ?4)", false},
      {"channel_values", "channel, target_seq, value", "tir",
       "SELECT c.name, t.seq, v.value FROM channel_values v JOIN channels c ON c.id = v.channel_id"
       " JOIN targets t ON t.id = v.target_id WHERE c.run_id = ?1 ORDER BY c.id, t.seq",
       "INSERT INTO channel_values(channel_id, target_id, value) VALUES ((SELECT id FROM channels WHERE run_id = ?1"
       " AND name = ?3), (SELECT id FROM targets WHERE run_id = ?1 AND seq = ?4), ?5)",
       false},
      {"results", "idx, processor, processor_version, parameters_json, output_json, created_at", "nttttt",
       "SELECT processor, processor_version, parameters_json, output_json,"
       " created_at FROM results WHERE run_id = ?1 ORDER BY id",
       "INSERT INTO results(run_id, processor, processor_version, parameters_json, output_json, created_at)"
       " VALUES (?1, ?4, ?5, ?6, ?7, ?8)",
       false},
      {"events", "idx, level, message, created_at", "nttt",
       "SELECT level, message, created_at FROM events WHERE run_id = ?1"
       " ORDER BY id",
       "INSERT INTO events(run_id, level, message, created_at) VALUES (?1, ?4, ?5, ?6)", false},
      {"run_notes", "idx, author, text, created_at", "nttt",
       "SELECT author, text, created_at FROM run_notes WHERE run_id = ?1"
       " ORDER BY id",
       "INSERT INTO run_notes(run_id, author, text, created_at) VALUES (?1, ?4, ?5, ?6)", false},
      {"run_instruments", "instrument_kind, instrument_model, instrument_serial, role", "tttt",
       "SELECT i.kind, i.model, i.serial, ri.role FROM run_instruments ri JOIN instruments i"
       " ON i.id = ri.instrument_id WHERE ri.run_id = ?1 ORDER BY i.kind, i.model, i.serial",
       "INSERT INTO run_instruments(run_id, instrument_id, role) VALUES (?1, (SELECT id FROM instruments"
       " WHERE kind = ?3 AND model = ?4 AND serial = ?5), ?6)",
       false},
      {"probe_steps", "step, position_mm, channel, value_um, s_um, readings", "iririi",
       "SELECT step, position_mm, channel, value_um, s_um, readings FROM probe_steps WHERE run_id = ?1"
       " ORDER BY step, channel",
       "INSERT INTO probe_steps(run_id, step, position_mm, channel, value_um, s_um, readings)"
       " VALUES (?1, ?3, ?4, ?5, ?6, ?7, ?8)",
       false},
      {"circle_points", "direction, idx, angle_deg, deviation_um, time_s", "tirrr",
       "SELECT direction, idx, angle_deg, deviation_um, time_s FROM circle_points WHERE run_id = ?1"
       " ORDER BY direction, idx",
       "INSERT INTO circle_points(run_id, direction, idx, angle_deg, deviation_um, time_s)"
       " VALUES (?1, ?3, ?4, ?5, ?6, ?7)",
       false},
      {"tracker_points", "idx, feature, place, x_mm, y_mm, z_mm, time_s, integration_ms", "ittrrrri",
       "SELECT idx, feature, place, x_mm, y_mm, z_mm, time_s, integration_ms FROM tracker_points WHERE run_id = ?1"
       " ORDER BY idx",
       "INSERT INTO tracker_points(run_id, idx, feature, place, x_mm, y_mm, z_mm, time_s, integration_ms)"
       " VALUES (?1, ?3, ?4, ?5, ?6, ?7, ?8, ?9, ?10)",
       false},
      {"thermal_channels", "idx, name, kind, unit", "ittt",
       "SELECT idx, name, kind, unit FROM thermal_channels WHERE run_id = ?1 ORDER BY idx",
       "INSERT INTO thermal_channels(run_id, idx, name, kind, unit) VALUES (?1, ?3, ?4, ?5, ?6)", false},
      {"thermal_samples", "idx, time_s, segment", "iri",
       "SELECT idx, time_s, segment FROM thermal_samples WHERE run_id = ?1 ORDER BY idx",
       "INSERT INTO thermal_samples(run_id, idx, time_s, segment) VALUES (?1, ?3, ?4, ?5)", false},
      {"thermal_values", "sample, channel, value", "iir",
       "SELECT sample, channel, value FROM thermal_values WHERE run_id = ?1 ORDER BY sample, channel",
       "INSERT INTO thermal_values(run_id, sample, channel, value) VALUES (?1, ?3, ?4, ?5)", false},
  };
  return kParts;
}

Sha256::Sha256() : ctx_(EVP_MD_CTX_new()) {
  if (ctx_ == nullptr || EVP_DigestInit_ex(static_cast<EVP_MD_CTX*>(ctx_), EVP_sha256(), nullptr) != 1)
    throw std::runtime_error("SHA-256 is not available (OpenSSL)");
}

Sha256::~Sha256() { EVP_MD_CTX_free(static_cast<EVP_MD_CTX*>(ctx_)); }

void Sha256::update(std::string_view data) {
  EVP_DigestUpdate(static_cast<EVP_MD_CTX*>(ctx_), data.data(), data.size());
}

std::string Sha256::hex() {
  unsigned char digest[EVP_MAX_MD_SIZE];
  unsigned int size = 0;
  EVP_DigestFinal_ex(static_cast<EVP_MD_CTX*>(ctx_), digest, &size);
  std::string out;
  for (unsigned int i = 0; i < size; ++i) out += fmt::format("{:02x}", digest[i]);
  return out;
}

RunMetadata runMetadata(storage::Store& store, storage::Id run_id) {
  const auto run = store.run(run_id);
  storage::Statement st(store.database(),
                        "SELECT c.uuid, i.kind, i.model, i.serial FROM runs r JOIN campaigns c ON c.id = r.campaign_id"
                        " LEFT JOIN instruments i ON i.id = r.instrument_id WHERE r.id = ?");
  st.bind(1, run_id);
  if (!st.step()) throw InputError("run " + std::to_string(run_id) + " does not exist");
  RunMetadata m;
  m.uuid = run.uuid;
  m.campaign_uuid = st.getText(0);
  m.status = run.status;
  m.values = {st.getOptionalText(1),
              st.getOptionalText(2),
              st.getOptionalText(3),
              run.kind,
              run.axis,
              run.name,
              run.plan_json,
              run.status,
              run.source,
              run.software_version,
              run.started_at,
              run.finished_at,
              run.value_unit,
              run.operator_name,
              run.compensation_json};
  return m;
}

namespace {

/// The order (from 0) within the run's samples of each of `rowids`: one pass over the run's
/// sample row ids.
std::map<std::int64_t, std::int64_t> sampleRanks(storage::Database& db, storage::Id run_id,
                                                 std::set<std::int64_t> rowids) {
  std::map<std::int64_t, std::int64_t> ranks;
  if (rowids.empty()) return ranks;
  storage::Statement st(db, "SELECT rowid FROM samples WHERE run_id = ? ORDER BY rowid");
  st.bind(1, run_id);
  for (std::int64_t rank = 0; st.step() && !rowids.empty(); ++rank) {
    const auto found = rowids.find(st.getInt(0));
    if (found == rowids.end()) continue;
    ranks[*found] = rank;
    rowids.erase(found);
  }
  return ranks;
}

}  // namespace

PartDigest forEachPartLine(storage::Database& db, const RunPart& part, storage::Id run_id,
                           const std::function<void(std::string_view line)>& line) {
  const std::string_view types(part.types);
  // Samples a row points at (type k), by their order in the run.
  std::map<std::int64_t, std::int64_t> ranks;
  if (types.find('k') != std::string_view::npos) {
    std::set<std::int64_t> rowids;
    storage::Statement st(db, part.select);
    st.bind(1, run_id);
    while (st.step()) {
      for (std::size_t i = 0, column = 0; i < types.size(); ++i) {
        if (types[i] == 'n') continue;
        if (types[i] == 'k' && !st.isNull(static_cast<int>(column))) rowids.insert(st.getInt(static_cast<int>(column)));
        ++column;
      }
    }
    ranks = sampleRanks(db, run_id, std::move(rowids));
  }
  storage::Statement st(db, part.select);
  st.bind(1, run_id);
  Sha256 sha;
  PartDigest digest;
  std::string text;
  while (st.step()) {
    text.clear();
    for (std::size_t i = 0, column = 0; i < types.size(); ++i) {
      if (i > 0) text += '\t';
      if (types[i] == 'n') {  // the row's number in the run
        text += std::to_string(digest.rows);
        continue;
      }
      const int c = static_cast<int>(column++);
      if (st.isNull(c)) {
        appendCopyField(text, std::nullopt);
      } else if (types[i] == 'i') {
        text += std::to_string(st.getInt(c));
      } else if (types[i] == 'k') {
        const auto rank = ranks.find(st.getInt(c));
        appendCopyField(text, rank == ranks.end() ? std::nullopt : std::optional(std::to_string(rank->second)));
      } else if (types[i] == 'r') {
        const double value = st.getDouble(c);
        // The shortest text that reads back the same double; PostgreSQL's words otherwise.
        text += std::isfinite(value) ? fmt::format("{}", value)
                : std::isnan(value)  ? "NaN"
                                     : (value > 0 ? "Infinity" : "-Infinity");
      } else {
        appendCopyField(text, st.getText(c));
      }
    }
    text += '\n';
    sha.update(text);
    ++digest.rows;
    line(text);
  }
  digest.sha256 = sha.hex();
  return digest;
}

std::string runDigest(const RunMetadata& metadata, const std::vector<PartDigest>& parts) {
  Sha256 sha;
  std::string text = metadata.uuid + '\t' + metadata.campaign_uuid;
  for (const auto& v : metadata.values) {
    text += '\t';
    appendCopyField(text, v);
  }
  text += '\n';
  for (std::size_t i = 0; i < parts.size(); ++i)
    text += fmt::format("{}\t{}\t{}\n", runParts()[i].name, parts[i].rows, parts[i].sha256);
  sha.update(text);
  return sha.hex();
}

}  // namespace mtcal::archive
