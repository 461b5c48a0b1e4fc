#pragma once
// The plant archive's schema on PostgreSQL, versioned like the local store's: migration k
// brings it from version k to k + 1, in one transaction, by one client at a time.

#include "mtcal/archive/postgres.h"

namespace mtcal::archive {

/// The schema version this mtcal writes and reads.
int plantSchemaVersion();
/// Creates or migrates the archive's schema. @throws StorageError when the archive is newer
/// than this mtcal, or the role may not create it (an administrator migrates, docs/archive.md)
/// @return the version it was at before (0: there was no archive)
int migratePlant(Connection& c);
/// The archive's identity (made with its schema).
std::string archiveUuid(Connection& c);
/// Refuses an archive that is not at this mtcal's version (a reader never migrates).
void requirePlantSchema(Connection& c);

}  // namespace mtcal::archive
