#pragma once
// A file imported again: the SHA-256 of its bytes is stored with each run imported from it (the
// plan's imported_sha256), and a later import of the same bytes is told, naming the runs that
// hold them already. Nothing is refused: a file may be imported again on purpose (under another
// machine or name).

#include <sstream>
#include <string>
#include <vector>

#include "mtcal/acquisition/store_when_needed.h"
#include "mtcal/services/session.h"
#include "mtcal/storage/store.h"

namespace mtcal::services::detail {

/// A file to import, read once: the import parses these bytes and stores their digest.
struct ImportedFile {
  std::istringstream bytes;
  std::string sha256;  ///< lowercase hex; empty for a pipe or a FIFO (read once, nothing to compare later)
};
/// @throws InputError where the file cannot be opened or read, saying why
ImportedFile readImportedFile(const std::string& path);

/// The session's store for an import, opened (created where missing) only when the file has
/// been read whole and found sound: a failed import leaves no store behind.
acquisition::StoreWhenNeeded storeWhenNeeded(Session& session);

/// Where runs other than `new_ids` (one import's, in a campaign of their own) hold the same
/// bytes: one warning naming them, or none. "x.csv: the same file was imported before, as run 3
/// ('X, vendor export'): run 7 holds it again (mtcal delete c7 removes this import)".
std::vector<std::string> importedBefore(storage::Store& store, const std::string& sha256, const std::string& path,
                                        const std::vector<storage::Id>& new_ids);

}  // namespace mtcal::services::detail
