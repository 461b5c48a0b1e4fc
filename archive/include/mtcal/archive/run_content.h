#pragma once
// What a run holds, as the plant archive stores it: its metadata and its parts (samples,
// targets, points ...), each part's rows in a canonical order and text, free of the local
// store's row ids, so that the same run gives the same rows and the same SHA-256 in every
// store it is copied to.

#include <cstdint>
#include <functional>
#include <string>
#include <string_view>
#include <vector>

#include "mtcal/archive/postgres.h"
#include "mtcal/storage/store.h"

namespace mtcal::archive {

/// One table of a run's data, in the local store and in the archive.
struct RunPart {
  const char* name;     ///< the archive's table
  const char* columns;  ///< its columns after (run_uuid, version), in order
  /// One letter per column: i integer, r real, t text; n the row's number within the run (from
  /// 0, not selected: counted); k a sample's row id in the store, sent as its order in the run.
  const char* types;
  const char* select;  ///< local store: the run's rows (?1 run id), columns but n in order, canonical order
  const char* insert;  ///< local store: one row back (?1 new run id, ?2 first sample rowid, ?3... the columns)
  bool by_month;       ///< the archive's table is partitioned by the run's month (a run_month column first)
};
/// Every part, in the order a pulled run's rows are inserted (rows that others point at first).
const std::vector<RunPart>& runParts();

/// SHA-256 of bytes fed in pieces, as lowercase hex.
class Sha256 {
 public:
  Sha256();
  ~Sha256();
  Sha256(const Sha256&) = delete;
  Sha256& operator=(const Sha256&) = delete;
  void update(std::string_view data);
  std::string hex();  ///< once

 private:
  void* ctx_;
};

/// A part's digest and size.
struct PartDigest {
  std::string sha256;
  std::int64_t rows = 0;
};

/// The run's metadata as the archive stores it: its identity, its campaign's, and the values of
/// run_versions' columns that describe it (kRunColumns), in text. Instruments are named by
/// kind, model and serial: two stores that met the same instrument gave it different uuids.
struct RunMetadata {
  std::string uuid, campaign_uuid;
  std::string status;  ///< as stored; a stale running run reads interrupted
  Row values;          ///< one per kRunColumns
};
/// run_versions' columns that describe the run, in RunMetadata::values' order.
inline constexpr const char* kRunColumns =
    "instrument_kind, instrument_model, instrument_serial, kind, axis, name, plan_json, status, source, "
    "software_version, started_at, finished_at,"
    " value_unit, operator_name, compensation_json";
/// The metadata of a local run. @throws InputError when there is no such run
RunMetadata runMetadata(storage::Store& store, storage::Id run_id);

/// Each row of a part of a local run, as one COPY text line (with '\n'), in canonical order.
/// @return the part's digest
PartDigest forEachPartLine(storage::Database& db, const RunPart& part, storage::Id run_id,
                           const std::function<void(std::string_view line)>& line);
/// The digest of a whole run: its metadata and every part's digest.
std::string runDigest(const RunMetadata& metadata, const std::vector<PartDigest>& parts);

}  // namespace mtcal::archive
