#pragma once
// Thin RAII layer over the SQLite C API: a connection, prepared statements and a
// transaction guard. SQLite result codes become mtcal::StorageError here and nowhere else.
//
// Thread-safety: a Database (and every Statement prepared on it) belongs to one thread.
// Open one Database per thread; WAL mode lets readers and one writer work concurrently.

#include <cstdint>
#include <optional>
#include <string>
#include <string_view>

struct sqlite3;
struct sqlite3_stmt;

namespace mtcal::storage {

class Database;

/// A prepared statement. Bind indices are 1-based like SQLite's; column indices 0-based.
class Statement {
 public:
  Statement(Database& db, std::string_view sql);
  ~Statement();
  Statement(const Statement&) = delete;
  Statement& operator=(const Statement&) = delete;
  Statement(Statement&& other) noexcept;

  Statement& bind(int index, std::int64_t value);
  Statement& bind(int index, int value) { return bind(index, static_cast<std::int64_t>(value)); }
  Statement& bind(int index, double value);
  Statement& bind(int index, std::string_view value);
  Statement& bind(int index, const char* value) { return bind(index, std::string_view(value)); }
  Statement& bindNull(int index);
  template <typename T>
  Statement& bind(int index, const std::optional<T>& value) {
    return value ? bind(index, *value) : bindNull(index);
  }

  /// Executes one step. @return true while a row is available. @throws StorageError
  bool step();
  /// Steps a statement that returns no row, then resets it for reuse. @throws StorageError
  void run();
  /// Resets for re-execution; bindings are kept until rebound.
  void reset();

  bool isNull(int column) const;
  std::int64_t getInt(int column) const;
  double getDouble(int column) const;
  std::string getText(int column) const;
  std::optional<double> getOptionalDouble(int column) const;
  std::optional<std::int64_t> getOptionalInt(int column) const;
  std::optional<std::string> getOptionalText(int column) const;

 private:
  [[noreturn]] void fail(int rc, const char* what) const;
  Database* db_;
  sqlite3_stmt* stmt_ = nullptr;
};

/// How a database file is opened.
enum class Open {
  kCreate,    ///< read-write, created when missing
  kExisting,  ///< must exist; read-only when the file or its folder is not writable
  kReadOnly,  ///< must exist; never written
  /// Must exist; never written; sees what writers commit while it is open (a dashboard that
  /// stays open while runs are recorded). Shares the write-ahead log's index with them,
  /// creating it when nobody writes (read immutable where it cannot).
  kReadOnlyFollowing,
};

/// A connection to one database file, opened with WAL journaling and foreign keys on.
/// A read-only archive (a write-protected file or folder, a quality department's copy) is read
/// without any file being created next to it.
class Database {
 public:
  /// How long a statement waits for another process's lock before it fails.
  static constexpr int kBusyTimeoutMs = 30'000;
  /// @throws StorageError naming the file when it is missing (kExisting, kReadOnly) or cannot be opened
  explicit Database(const std::string& path, Open open = Open::kCreate);
  ~Database();
  Database(const Database&) = delete;
  Database& operator=(const Database&) = delete;

  /// Runs SQL without parameters (schema, pragmas). @throws StorageError
  void exec(std::string_view sql);
  /// Copies the whole database to a new file at `path` by SQLite's online backup (consistent
  /// while others write). @throws StorageError, InputError when `path` exists
  void backupTo(const std::string& path);
  std::int64_t lastInsertId() const;
  int changes() const;
  const std::string& path() const { return path_; }
  sqlite3* handle() const { return db_; }
  bool readOnly() const { return read_only_; }
  /// The tables the database holds, comma separated (empty: none).
  std::string tableNames();
  /// Its schema version (PRAGMA user_version; 0: not an mtcal archive yet).
  int userVersion();
  /// The error of a failed SQLite call, in words that name the archive and what to do
  /// (read-only, disk full, I/O error, busy). @return StorageError's message
  std::string describe(int rc, std::string_view what) const;

 private:
  friend class Transaction;
  void openReadOnly(bool follow_writers);
  std::string path_;
  sqlite3* db_ = nullptr;
  bool read_only_ = false;
  int transaction_depth_ = 0;
};

/// Transaction guard: rolls back on destruction unless commit() ran. The outermost guard
/// is BEGIN IMMEDIATE ... COMMIT; a guard inside another is a SAVEPOINT, so functions that
/// write atomically compose into larger atomic units.
class Transaction {
 public:
  explicit Transaction(Database& db);
  ~Transaction();
  Transaction(const Transaction&) = delete;
  Transaction& operator=(const Transaction&) = delete;
  /// @throws StorageError; after a failed commit the destructor rolls back.
  void commit();

 private:
  Database& db_;
  int depth_;
  bool done_ = false;
};

}  // namespace mtcal::storage
