#include "mtcal/storage/sqlite.h"

#include <sqlite3.h>

#include "mtcal/error.h"

namespace mtcal::storage {

namespace {
[[noreturn]] void throwSqlite(sqlite3* db, int rc, std::string_view what) {
  std::string message = "SQLite: " + std::string(what) + ": ";
  message += db ? sqlite3_errmsg(db) : sqlite3_errstr(rc);
  throw StorageError(message);
}
}  // namespace

Database::Database(const std::string& path) : path_(path) {
  int rc =
      sqlite3_open_v2(path.c_str(), &db_, SQLITE_OPEN_READWRITE | SQLITE_OPEN_CREATE | SQLITE_OPEN_NOMUTEX, nullptr);
  if (rc != SQLITE_OK) {
    std::string message = "cannot open database '" + path + "': " + (db_ ? sqlite3_errmsg(db_) : sqlite3_errstr(rc));
    sqlite3_close(db_);
    db_ = nullptr;
    throw StorageError(message);
  }
  // A concurrent reader (mtcal show while a run records) may hold a lock for a moment.
  sqlite3_busy_timeout(db_, 5000);
  // 8 KiB pages (only takes effect when the file is created) and a 64 MiB page cache per
  // connection: streaming inserts then rarely spill mid-transaction (docs/performance.md).
  exec("PRAGMA page_size = 8192");
  exec("PRAGMA cache_size = -65536");
  exec("PRAGMA foreign_keys = ON");
  // WAL: readers never block the writer; NORMAL sync is durable at checkpoints and
  // loses at most the last transactions on power loss, never corrupts.
  exec("PRAGMA journal_mode = WAL");
  exec("PRAGMA synchronous = NORMAL");
}

Database::~Database() { sqlite3_close_v2(db_); }

void Database::exec(std::string_view sql) {
  char* error = nullptr;
  int rc = sqlite3_exec(db_, std::string(sql).c_str(), nullptr, nullptr, &error);
  if (rc != SQLITE_OK) {
    std::string message =
        "SQLite: " + std::string(error ? error : sqlite3_errstr(rc)) + " in: " + std::string(sql.substr(0, 120));
    sqlite3_free(error);
    throw StorageError(message);
  }
}

std::int64_t Database::lastInsertId() const { return sqlite3_last_insert_rowid(db_); }
int Database::changes() const { return sqlite3_changes(db_); }

Statement::Statement(Database& db, std::string_view sql) : db_(&db) {
  int rc = sqlite3_prepare_v2(db.handle(), sql.data(), static_cast<int>(sql.size()), &stmt_, nullptr);
  if (rc != SQLITE_OK) throwSqlite(db.handle(), rc, "prepare '" + std::string(sql.substr(0, 80)) + "'");
}

Statement::~Statement() { sqlite3_finalize(stmt_); }

Statement::Statement(Statement&& other) noexcept : db_(other.db_), stmt_(other.stmt_) { other.stmt_ = nullptr; }

void Statement::fail(int rc, const char* what) const { throwSqlite(db_->handle(), rc, what); }

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
