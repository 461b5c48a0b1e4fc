#pragma once
// Schema versions and migrations. The version lives in PRAGMA user_version.

#include "mtcal/storage/sqlite.h"

namespace mtcal::storage {

/// The schema version this build writes.
int currentSchemaVersion();

/// Brings a database to currentSchemaVersion() in one transaction that holds the write lock:
/// processes opening a new archive at once wait for the first one's migration.
/// @throws StorageError when the file was written by a newer mtcal (higher version), or is
/// read-only and older than this mtcal, or is not an mtcal archive: an SQLite database with
/// other tables (never written to), or an empty one when `create` is false (a reading command
/// pointed at the wrong file).
void migrate(Database& db, bool create);

}  // namespace mtcal::storage
