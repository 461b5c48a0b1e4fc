#pragma once
// Schema versions and migrations. The version lives in PRAGMA user_version.

#include "mtcal/storage/sqlite.h"

namespace mtcal::storage {

/// The schema version this build writes.
int currentSchemaVersion();

/// Brings a database to currentSchemaVersion(), each migration in its own transaction.
/// @throws StorageError when the file was written by a newer mtcal (higher version).
void migrate(Database& db);

}  // namespace mtcal::storage
