#pragma once
// A run written out as files another program (or a spreadsheet) reads: its measurements in
// the format of mtcal's own import for its kind, so that importing them again gives the same
// values; the raw samples and environment of an acquired run; its stored results; the run
// itself (what `mtcal show --json` prints).

#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "mtcal/services/session.h"

namespace mtcal::services {

struct ExportedFile {
  std::string path;
  std::string what;  ///< for people: "targets (the import linear format)" ...
};

struct RunExport {
  storage::Id run_id = 0;
  std::vector<ExportedFile> files;
  /// The command that reads the measurements back into an archive (empty: none for this kind).
  std::string import_command;
  nlohmann::json document() const;
};

/// Writes run `run_id` into the folder `dir` (created when missing) as run<ID>_*.csv/json.
/// @throws InputError when a file to write exists already or cannot be written (nothing of
/// the export is left then)
RunExport exportRun(Session& session, storage::Id run_id, const std::string& dir);
/// A campaign written out: every run as exportRun writes it, and a manifest of its linear runs
/// (campaign<ID>.json: file, axis, measures, line position, reflector offset) that
/// `mtcal import campaign` reads back as one campaign.
struct CampaignExport {
  storage::Id campaign_id = 0;
  std::string manifest;
  std::vector<RunExport> runs;
  std::string import_command;
  nlohmann::json document() const;
};
/// @throws InputError when the campaign has no linear run, or a file exists already or cannot
/// be written (nothing of the export is left then)
CampaignExport exportCampaign(Session& session, storage::Id campaign_id, const std::string& dir);

/// The files exportRun writes for a run, without writing them: each path is the file's name
/// (run<ID>_targets.csv ...).
std::vector<ExportedFile> exportedFiles(Session& session, storage::Id run_id);
/// One file of a run's export as text (`name` without the run<ID>_ prefix: targets.csv ...),
/// written in a private temporary folder and removed. @throws InputError for a name the run's
/// export does not have, naming those it has
std::string exportedFile(Session& session, storage::Id run_id, const std::string& name);

}  // namespace mtcal::services
