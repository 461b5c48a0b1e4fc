#include "mtcal/storage/sqlite.h"

#include <fmt/format.h>
#include <sqlite3.h>
#include <unistd.h>

#include <array>
#include <chrono>
#include <filesystem>
#include <span>
#include <thread>

#include "mtcal/error.h"

namespace mtcal::storage {

namespace {
[[noreturn]] void throwSqlite(const Database& db, int rc, std::string_view what) {
  throw StorageError(db.describe(rc, what));
}

void enableWal(Database& db);

/// Whether SQLite could write the file and create its journals next to it.
bool writable(const std::filesystem::path& path) {
  const auto folder = path.has_parent_path() ? path.parent_path() : std::filesystem::path(".");
  return ::access(path.c_str(), W_OK) == 0 && ::access(folder.c_str(), W_OK) == 0;
}

/// A file name as an SQLite URI (its %, ? and # escaped) with `query`.
std::string uriOf(const std::string& path, const char* query) {
  std::string uri = "file:";
  for (const char c : path) {
    if (c == '%' || c == '?' || c == '#') {
      uri += fmt::format("%{:02X}", static_cast<unsigned char>(c));
    } else {
      uri += c;
    }
  }
  return uri + query;
}
}  // namespace

Database::Database(const std::string& path, Open open) : path_(path) {
  std::error_code ec;
  const bool exists = std::filesystem::exists(path, ec);
  if (!exists && open != Open::kCreate) throw StorageError("no store '" + path + "': the file does not exist");
  // A path mistyped (bad input), not a store that fails.
  if (std::filesystem::is_directory(path, ec)) throw InputError("'" + path + "' is a folder, not a store file");
  if (const auto folder = std::filesystem::path(path).parent_path();
      !exists && !folder.empty() && !std::filesystem::is_directory(folder, ec))
    throw InputError("cannot make store '" + path + "': its folder '" + folder.string() + "' does not exist");
  if (open == Open::kReadOnly || open == Open::kReadOnlyFollowing || (exists && !writable(path))) {
    openReadOnly(open == Open::kReadOnlyFollowing);
  } else {
    const int flags = SQLITE_OPEN_READWRITE | SQLITE_OPEN_NOMUTEX | (open == Open::kCreate ? SQLITE_OPEN_CREATE : 0);
    if (int rc = sqlite3_open_v2(path.c_str(), &db_, flags, nullptr); rc != SQLITE_OK) {
      std::string message = "cannot open store '" + path + "': " + (db_ ? sqlite3_errmsg(db_) : sqlite3_errstr(rc));
      sqlite3_close(db_);
      db_ = nullptr;
      throw StorageError(message);
    }
  }
  // Another process (a reader, a second station, a migration) may hold a lock for a while:
  // wait for it rather than fail.
  sqlite3_busy_timeout(db_, kBusyTimeoutMs);
  // A 64 MiB page cache per connection: streaming inserts then rarely spill mid-transaction
  // (docs/performance.md).
  exec("PRAGMA cache_size = -65536");
  exec("PRAGMA foreign_keys = ON");
  // Another program's database, or an empty file a reading command was pointed at: not a byte
  // written (migrate refuses both).
  if (read_only_) return;
  if (userVersion() == 0 && (open != Open::kCreate || !tableNames().empty())) return;
  // 8 KiB pages (only takes effect when the file is created).
  exec("PRAGMA page_size = 8192");
  // WAL: readers never block the writer; NORMAL sync is durable at checkpoints and
  // loses at most the last transactions on power loss, never corrupts.
  enableWal(*this);
  exec("PRAGMA synchronous = NORMAL");
}

namespace {
void enableWal(Database& db) {
  // Switching a new file to WAL needs it to itself: SQLite answers busy at once, without
  // waiting, while another process opening the same new archive holds a lock. Retry until the
  // busy timeout; once one process has switched, the file says WAL for all.
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::milliseconds(Database::kBusyTimeoutMs);
  for (auto pause = std::chrono::milliseconds(1);; pause = std::min(pause * 2, std::chrono::milliseconds(100))) {
    const int rc = sqlite3_exec(db.handle(), "PRAGMA journal_mode = WAL", nullptr, nullptr, nullptr);
    if (rc == SQLITE_OK) return;
    if ((rc & 0xff) != SQLITE_BUSY || std::chrono::steady_clock::now() > deadline)
      throwSqlite(db, rc, "PRAGMA journal_mode = WAL");
    std::this_thread::sleep_for(pause);
  }
}
}  // namespace

std::string Database::tableNames() {
  Statement st(*this, "SELECT group_concat(name, ', ') FROM sqlite_master WHERE type = 'table'");
  st.step();
  return st.isNull(0) ? std::string() : st.getText(0);
}

int Database::userVersion() {
  Statement st(*this, "PRAGMA user_version");
  st.step();
  return static_cast<int>(st.getInt(0));
}

void Database::openReadOnly(bool follow_writers) {
  read_only_ = true;
  // mode=ro shares the write-ahead log's index with a writer, and creates it (owned by this
  // reader, which would then lock the archive's owner out) when nobody is writing. So: with a
  // write-ahead log beside the file (a writer has it open, or one ended without closing it)
  // mode=ro; without, the file is complete as it is and read immutable: nothing created.
  // A reader that must see later writers (a dashboard) takes mode=ro in any case.
  std::error_code ec;
  const bool log_beside = std::filesystem::exists(path_ + "-wal", ec);
  std::string last_error;
  static constexpr std::array<const char*, 2> kQueries{"?mode=ro", "?immutable=1"};
  for (const char* query : std::span(kQueries).subspan(log_beside || follow_writers ? 0 : 1)) {
    const std::string uri = uriOf(path_, query);
    int rc = sqlite3_open_v2(uri.c_str(), &db_, SQLITE_OPEN_READONLY | SQLITE_OPEN_URI | SQLITE_OPEN_NOMUTEX, nullptr);
    if (rc == SQLITE_OK) rc = sqlite3_exec(db_, "SELECT count(*) FROM sqlite_master", nullptr, nullptr, nullptr);
    if (rc == SQLITE_OK) return;
    last_error = db_ ? sqlite3_errmsg(db_) : sqlite3_errstr(rc);
    sqlite3_close(db_);
    db_ = nullptr;
  }
  throw StorageError("cannot read store '" + path_ + "': " + last_error);
}

std::string Database::describe(int rc, std::string_view what) const {
  const std::string detail = db_ ? sqlite3_errmsg(db_) : sqlite3_errstr(rc);
  switch (rc & 0xff) {
    case SQLITE_READONLY:
      return "store '" + path_ + "' is read-only" +
             (read_only_ ? std::string(" (the file or its folder is not writable)") : std::string()) +
             ": this command writes to it; work on a writable copy (mtcal backup makes one)";
    case SQLITE_FULL:
      return "the disk holding store '" + path_ + "' is full (" + std::string(what) +
             "): nothing of that write was stored; everything committed before is kept. Free space, then continue "
             "(mtcal resume RUN)";
    case SQLITE_IOERR:
      return "I/O error on store '" + path_ + "' (" + detail + ") during " + std::string(what) +
             ": nothing of it was stored; everything committed before is kept";
    case SQLITE_BUSY:
    case SQLITE_LOCKED:
      return "store '" + path_ + "' is locked by another process (waited up to " +
             std::to_string(kBusyTimeoutMs / 1000) + " s at " + std::string(what) + "): try again when it has finished";
    case SQLITE_CORRUPT:
    case SQLITE_NOTADB:
      return "'" + path_ + "' is damaged or not an mtcal store (" + detail +
             "): mtcal check lists what SQLite finds; restore the store from a copy mtcal backup made";
    default:
      return "SQLite: " + std::string(what) + ": " + detail;
  }
}

Database::~Database() { sqlite3_close_v2(db_); }

void Database::exec(std::string_view sql) {
  int rc = sqlite3_exec(db_, std::string(sql).c_str(), nullptr, nullptr, nullptr);
  if (rc != SQLITE_OK) throwSqlite(*this, rc, sql.substr(0, 120));
}

void Database::backupTo(const std::string& path) {
  std::error_code ec;
  if (std::filesystem::exists(path, ec)) throw InputError("backup: '" + path + "' exists: give a new file");
  const auto folder = std::filesystem::path(path).parent_path();
  if (!folder.empty() && !std::filesystem::is_directory(folder, ec))
    throw InputError("backup: '" + path + "': there is no folder '" + folder.string() + "'");
  sqlite3* target = nullptr;
  int rc = sqlite3_open_v2(path.c_str(), &target, SQLITE_OPEN_READWRITE | SQLITE_OPEN_CREATE, nullptr);
  const auto fail = [&](const std::string& why) {
    sqlite3_close(target);
    std::filesystem::remove(path, ec);  // no half-written copy
    throw StorageError("backup of '" + path_ + "' to '" + path + "': " + why);
  };
  if (rc != SQLITE_OK) fail(target ? sqlite3_errmsg(target) : sqlite3_errstr(rc));
  sqlite3_backup* backup = sqlite3_backup_init(target, "main", db_, "main");
  if (!backup) fail(sqlite3_errmsg(target));
  // All pages in one step where possible; a writer elsewhere makes the step busy for a moment.
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::milliseconds(kBusyTimeoutMs);
  do {
    rc = sqlite3_backup_step(backup, -1);
    if (rc == SQLITE_BUSY || rc == SQLITE_LOCKED) std::this_thread::sleep_for(std::chrono::milliseconds(20));
  } while ((rc == SQLITE_OK || rc == SQLITE_BUSY || rc == SQLITE_LOCKED) &&
           std::chrono::steady_clock::now() < deadline);
  sqlite3_backup_finish(backup);
  if (rc != SQLITE_DONE) fail(rc == SQLITE_OK ? "timed out" : sqlite3_errstr(rc));
  if (sqlite3_close(target) != SQLITE_OK) fail("closing the copy failed");
}

std::int64_t Database::lastInsertId() const { return sqlite3_last_insert_rowid(db_); }
int Database::changes() const { return sqlite3_changes(db_); }

Statement::Statement(Database& db, std::string_view sql) : db_(&db) {
  int rc = sqlite3_prepare_v2(db.handle(), sql.data(), static_cast<int>(sql.size()), &stmt_, nullptr);
  if (rc != SQLITE_OK) throwSqlite(db, rc, "prepare '" + std::string(sql.substr(0, 80)) + "'");
}

Statement::~Statement() { sqlite3_finalize(stmt_); }

Statement::Statement(Statement&& other) noexcept : db_(other.db_), stmt_(other.stmt_) { other.stmt_ = nullptr; }

void Statement::fail(int rc, const char* what) const {
  const char* sql = sqlite3_sql(stmt_);
  throwSqlite(*db_, rc, std::string(what) + " of '" + std::string(sql ? sql : "").substr(0, 80) + "'");
}

Statement& Statement::bind(int index, std::int64_t value) {
  if (int rc = sqlite3_bind_int64(stmt_, index, value); rc != SQLITE_OK) fail(rc, "bind");
  return *this;
}
Statement& Statement::bind(int index, double value) {
  if (int rc = sqlite3_bind_double(stmt_, index, value); rc != SQLITE_OK) fail(rc, "bind");
  return *this;
}
Statement& Statement::bind(int index, std::string_view value) {
  if (int rc = sqlite3_bind_text(stmt_, index, value.data(), static_cast<int>(value.size()), SQLITE_TRANSIENT);
      rc != SQLITE_OK) {
    fail(rc, "bind");
  }
  return *this;
}
Statement& Statement::bindNull(int index) {
  if (int rc = sqlite3_bind_null(stmt_, index); rc != SQLITE_OK) fail(rc, "bind");
  return *this;
}

bool Statement::step() {
  int rc = sqlite3_step(stmt_);
  if (rc == SQLITE_ROW) return true;
  if (rc == SQLITE_DONE) return false;
  sqlite3_reset(stmt_);
  fail(rc, "step");
}

void Statement::run() {
  step();
  reset();
}

void Statement::reset() { sqlite3_reset(stmt_); }

bool Statement::isNull(int column) const { return sqlite3_column_type(stmt_, column) == SQLITE_NULL; }
std::int64_t Statement::getInt(int column) const { return sqlite3_column_int64(stmt_, column); }
double Statement::getDouble(int column) const { return sqlite3_column_double(stmt_, column); }
std::string Statement::getText(int column) const {
  const auto* text = sqlite3_column_text(stmt_, column);
  return text ? std::string(reinterpret_cast<const char*>(text)) : std::string();
}
std::optional<double> Statement::getOptionalDouble(int column) const {
  return isNull(column) ? std::nullopt : std::optional<double>(getDouble(column));
}
std::optional<std::int64_t> Statement::getOptionalInt(int column) const {
  return isNull(column) ? std::nullopt : std::optional<std::int64_t>(getInt(column));
}
std::optional<std::string> Statement::getOptionalText(int column) const {
  return isNull(column) ? std::nullopt : std::optional<std::string>(getText(column));
}

Transaction::Transaction(Database& db) : db_(db), depth_(db.transaction_depth_) {
  db_.exec(depth_ == 0 ? std::string("BEGIN IMMEDIATE") : "SAVEPOINT mtcal_" + std::to_string(depth_));
  ++db_.transaction_depth_;
}

Transaction::~Transaction() {
  if (!done_) {
    try {
      db_.exec(depth_ == 0
                   ? std::string("ROLLBACK")
                   : "ROLLBACK TO mtcal_" + std::to_string(depth_) + "; RELEASE mtcal_" + std::to_string(depth_));
    } catch (...) {  // NOLINT(bugprone-empty-catch): a destructor must not throw; the data stays as before
    }
    --db_.transaction_depth_;
  }
}

void Transaction::commit() {
  db_.exec(depth_ == 0 ? std::string("COMMIT") : "RELEASE mtcal_" + std::to_string(depth_));
  done_ = true;
  --db_.transaction_depth_;
}

}  // namespace mtcal::storage
