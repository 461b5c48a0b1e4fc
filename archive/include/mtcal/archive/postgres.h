#pragma once
// Thin RAII layer over libpq: a connection to a PostgreSQL server, statements with
// parameters, COPY in and out, a transaction guard. libpq's errors become StorageError here
// and nowhere else, naming the server (never a password).
//
// Thread-safety: a Connection belongs to one thread.

#include <functional>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

struct pg_conn;

namespace mtcal::archive {

/// A value as PostgreSQL's text format gives it; nullopt: NULL.
using Value = std::optional<std::string>;
using Row = std::vector<Value>;

class Connection {
 public:
  /// `uri`: a libpq connection URI or key=value string (postgresql://host/db?sslmode=require,
  /// service=plant). A password in it is refused: it belongs in ~/.pgpass, PGPASSFILE, a
  /// service file or PGPASSWORD, never on a command line or in a log.
  /// @throws InputError for a malformed URI or one with a password, StorageError when the
  /// server cannot be reached or refuses
  explicit Connection(const std::string& uri, const std::string& application = "mtcal");
  ~Connection();
  Connection(const Connection&) = delete;
  Connection& operator=(const Connection&) = delete;

  /// Where it is connected: user@host:port/database (a socket's folder for the host).
  const std::string& where() const { return where_; }
  /// The server's process serving this connection.
  int backendPid() const;
  /// Runs SQL without parameters (may be several statements). @throws StorageError
  void exec(std::string_view sql);
  /// Runs one statement with text parameters; returns its rows. @throws StorageError
  std::vector<Row> query(std::string_view sql, const std::vector<Value>& params = {});
  /// One value of a statement that returns one row of one column. @throws StorageError when it returns none
  Value scalar(std::string_view sql, const std::vector<Value>& params = {});

  /// Sends data to `COPY ... FROM STDIN` (text format) as `produce` writes it.
  class CopyIn {
   public:
    /// Appends bytes (whole lines end with '\n'); sent in large chunks.
    void write(std::string_view data);

   private:
    friend class Connection;
    explicit CopyIn(Connection& c) : c_(c) {}
    void flush();
    Connection& c_;
    std::string buffer_;
  };
  /// Runs `copy_sql` (COPY table (columns) FROM STDIN) and sends what `produce` writes.
  /// @throws StorageError (the COPY is aborted when `produce` throws)
  void copyIn(std::string_view copy_sql, const std::function<void(CopyIn&)>& produce);
  /// Runs `copy_sql` (COPY (SELECT ...) TO STDOUT) and hands each line, without its '\n', to `consume`.
  void copyOut(std::string_view copy_sql, const std::function<void(std::string_view line)>& consume);

 private:
  [[noreturn]] void fail(std::string_view what) const;
  pg_conn* conn_ = nullptr;
  std::string where_;
};

/// BEGIN ... COMMIT; rolls back on destruction unless commit() ran.
class PgTransaction {
 public:
  explicit PgTransaction(Connection& c);
  ~PgTransaction();
  PgTransaction(const PgTransaction&) = delete;
  PgTransaction& operator=(const PgTransaction&) = delete;
  void commit();

 private:
  Connection& c_;
  bool done_ = false;
};

/// COPY's text format: a value escaped (\\, \t, \n, \r) or \N for NULL.
void appendCopyField(std::string& line, const Value& value);
/// One line of COPY's text format split into its values (escapes undone).
/// @throws StorageError for a malformed escape
Row splitCopyLine(std::string_view line);

}  // namespace mtcal::archive
