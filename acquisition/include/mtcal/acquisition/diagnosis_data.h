#pragma once
// The data of a stored run as the diagnosis (processing/diagnosis.h) takes it,
// against a stored model or the run's own baseline, and the model versions the diagnosis
// makes: the base model with named extensions, stored with their provenance.
//
// Kinds: linear runs (acquired or imported: targets, approach direction, cycle, time, the
// environment unit's channels and any auxiliary channel), circular tests (acquired or
// imported), thermal runs (acquired or imported: one displacement, the temperatures) and
// probe stepping (EST) runs with three probes.

#include <optional>
#include <string>
#include <vector>

#include "mtcal/processing/diagnosis.h"
#include "mtcal/processing/error_model.h"
#include "mtcal/storage/store.h"

namespace mtcal::acquisition {

/// An extension of a stored model and the readings it applies to.
struct AppliedExtension {
  processing::ModelExtension extension;
  std::string kind;  ///< linear, circle, thermal, est
  /// What the readings measure: linear runs the error (EXX, EYX ...), circles the plane and
  /// radius ("XY R100 mm"), thermal runs the displacement; empty: every run of the kind
  std::string measures;
  storage::Id found_in_run = 0;  ///< the run whose diagnosis found it (0: not recorded)
};

/// The extensions recorded in a model's provenance ("extensions"). @throws InputError when damaged
std::vector<AppliedExtension> modelExtensions(const storage::ModelRecord& record);
/// Those of them that apply to readings of `kind` measuring `measures`.
std::vector<processing::ModelExtension> extensionsFor(const storage::ModelRecord& record, const std::string& kind,
                                                      const std::string& measures);

struct RunDiagnosisInput {
  processing::DiagnosisData data;
  std::string measures;  ///< what the run measures (AppliedExtension::measures)
  /// Extensions of the model that were added to its prediction, and those left out (a
  /// variable the run lacks), by effect.
  std::vector<std::string> applied, left_out;
  storage::RunInfo run;  ///< the run as stored (its status, machine ...)
};

struct RunDiagnosisOptions {
  /// Predict with this model: its geometry (linear runs; circles that record their centre) and
  /// its extensions for the kind of run.
  std::optional<storage::Id> model_id;
  std::string thermal_target;  ///< thermal runs: the displacement channel (default: the first)
  double min_knot_spacing_mm = 20.0;
};

/// @throws InputError naming the run and why (kind not diagnosable, too few points, a model
/// that cannot predict the run)
RunDiagnosisInput diagnosisInputOfRun(storage::Store& store, storage::Id run_id, const RunDiagnosisOptions& options);

/// Why a run's readings may not be its whole plan (stopped, failed, still being recorded), in
/// words; none for a completed or imported run.
std::optional<std::string> unfinishedRunWarning(const storage::RunInfo& info);

/// What the import of a run warned about (its plan's "import_warnings": times that cannot be one
/// clock's ...), each "run N was imported with a warning: ...".
std::vector<std::string> importWarnings(const storage::RunInfo& info);

/// A model version saveExtendedModel gave: its id, and whether the same version was stored already.
struct ExtendedModel {
  storage::Id id = 0;
  bool already_stored = false;
};

/// Stores a new model version: the base model's error functions and extensions plus `added`
/// (each for readings of its kind and measures, found in its run; several runs diagnosed in one
/// fit add the extensions of each), with the provenance (base model, the run diagnosed first,
/// software). A version the same in every respect already stored (the same diagnosis again) is
/// not stored twice.
ExtendedModel saveExtendedModel(storage::Store& store, storage::Id base_model, storage::Id run_id,
                                const std::vector<AppliedExtension>& added, const std::string& software_version);

}  // namespace mtcal::acquisition
