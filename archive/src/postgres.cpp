#include "mtcal/archive/postgres.h"

#include <libpq-fe.h>

#include <memory>

#include "mtcal/error.h"

namespace mtcal::archive {
namespace {

using ResultPtr = std::unique_ptr<PGresult, decltype(&PQclear)>;

ResultPtr owned(PGresult* r) { return ResultPtr(r, &PQclear); }

std::string trimmed(std::string text) {
  while (!text.empty() && (text.back() == '\n' || text.back() == ' ')) text.pop_back();
  return text;
}

/// The server's message for people: without its "ERROR:" and without the lines for developers
/// (the statement's text, the PL/pgSQL function it came from); DETAIL and HINT kept.
std::string serverMessage(const std::string& text) {
  std::string out;
  std::size_t at = 0;
  while (at < text.size()) {
    const auto end = std::min(text.find('\n', at), text.size());
    std::string line = text.substr(at, end - at);
    at = end + 1;
    if (line.starts_with("CONTEXT:")) break;  // the rest is where in the server it came from
    const bool caret = line.find_first_not_of(" ^") == std::string::npos;  // under the statement's text
    if (line.starts_with("LINE ") || caret) continue;
    if (line.starts_with("ERROR:")) line = line.substr(line.find_first_not_of(' ', 6));
    if (line.empty()) continue;
    out += (out.empty() ? "" : "; ") + line;
  }
  return trimmed(out);
}

/// Refuses a connection string that holds a password, naming it without the password.
void refusePassword(const std::string& uri) {
  if (uri.empty()) throw InputError("no archive address: give one (postgresql://HOST/DB, service=NAME)");
  char* error = nullptr;
  PQconninfoOption* options = PQconninfoParse(uri.c_str(), &error);
  if (options == nullptr) {
    const std::string why = error != nullptr ? trimmed(error) : "out of memory";
    PQfreemem(error);
    throw InputError("the archive's address is not a PostgreSQL connection string (postgresql://HOST/DB?...): " + why);
  }
  bool has_password = false;
  for (auto* o = options; o->keyword != nullptr; ++o)
    if (std::string_view(o->keyword) == "password" && o->val != nullptr && *o->val != '\0') has_password = true;
  PQconninfoFree(options);
  if (has_password)
    throw InputError(
        "the archive's address holds a password: a password never goes on a command line (it shows in the process "
        "list and the shell's history); put it in ~/.pgpass or the file PGPASSFILE names, in a service file "
        "(service=NAME), or in PGPASSWORD");
}

}  // namespace

Connection::Connection(const std::string& uri, const std::string& application) {
  refusePassword(uri);
  // Later keywords override earlier ones; the address's own keywords override the timeout.
  const char* keywords[] = {"connect_timeout", "dbname", "fallback_application_name", nullptr};
  const char* values[] = {"10", uri.c_str(), application.c_str(), nullptr};
  conn_ = PQconnectdbParams(keywords, values, 1);
  if (conn_ == nullptr) throw StorageError("cannot connect to the archive: out of memory");
  if (PQstatus(conn_) != CONNECTION_OK) {
    const std::string why = trimmed(PQerrorMessage(conn_));
    PQfinish(conn_);
    conn_ = nullptr;
    throw StorageError("cannot connect to the archive: " + why);
  }
  const std::string host = PQhost(conn_) != nullptr ? PQhost(conn_) : "";
  where_ = std::string(PQuser(conn_)) + "@" + host + ":" + PQport(conn_) + "/" + PQdb(conn_);
  exec("SET client_min_messages = warning");
}

Connection::~Connection() {
  if (conn_ != nullptr) PQfinish(conn_);
}

int Connection::backendPid() const { return PQbackendPID(conn_); }

void Connection::fail(std::string_view what) const {
  throw StorageError("archive " + where_ + ": " + std::string(what) + ": " + serverMessage(PQerrorMessage(conn_)));
}

void Connection::exec(std::string_view sql) {
  const std::string text(sql);
  auto r = owned(PQexec(conn_, text.c_str()));
  const auto status = PQresultStatus(r.get());
  if (status != PGRES_COMMAND_OK && status != PGRES_TUPLES_OK) fail("statement failed");
}

std::vector<Row> Connection::query(std::string_view sql, const std::vector<Value>& params) {
  const std::string text(sql);
  std::vector<const char*> values;
  values.reserve(params.size());
  for (const auto& p : params) values.push_back(p ? p->c_str() : nullptr);
  auto r = owned(
      PQexecParams(conn_, text.c_str(), static_cast<int>(values.size()), nullptr, values.data(), nullptr, nullptr, 0));
  const auto status = PQresultStatus(r.get());
  if (status != PGRES_COMMAND_OK && status != PGRES_TUPLES_OK) fail("statement failed");
  std::vector<Row> rows(static_cast<std::size_t>(PQntuples(r.get())));
  const int columns = PQnfields(r.get());
  for (int i = 0; i < static_cast<int>(rows.size()); ++i) {
    auto& row = rows[static_cast<std::size_t>(i)];
    row.reserve(static_cast<std::size_t>(columns));
    for (int j = 0; j < columns; ++j)
      row.push_back(PQgetisnull(r.get(), i, j) != 0 ? Value{} : Value{PQgetvalue(r.get(), i, j)});
  }
  return rows;
}

Value Connection::scalar(std::string_view sql, const std::vector<Value>& params) {
  auto rows = query(sql, params);
  if (rows.empty() || rows.front().empty())
    throw StorageError("archive " + where_ + ": no value from: " + std::string(sql));
  return rows.front().front();
}

void Connection::CopyIn::write(std::string_view data) {
  buffer_.append(data);
  if (buffer_.size() >= (1U << 18)) flush();
}

void Connection::CopyIn::flush() {
  if (buffer_.empty()) return;
  if (PQputCopyData(c_.conn_, buffer_.data(), static_cast<int>(buffer_.size())) != 1) c_.fail("sending rows failed");
  buffer_.clear();
}

void Connection::copyIn(std::string_view copy_sql, const std::function<void(CopyIn&)>& produce) {
  const std::string text(copy_sql);
  {
    auto r = owned(PQexec(conn_, text.c_str()));
    if (PQresultStatus(r.get()) != PGRES_COPY_IN) fail("COPY did not start");
  }
  CopyIn sink(*this);
  try {
    produce(sink);
    sink.flush();
  } catch (const std::exception& e) {
    PQputCopyEnd(conn_, e.what());
    while (PGresult* r = PQgetResult(conn_)) PQclear(r);
    throw;
  }
  if (PQputCopyEnd(conn_, nullptr) != 1) fail("ending COPY failed");
  bool ok = true;
  while (PGresult* r = PQgetResult(conn_)) {
    if (PQresultStatus(r) != PGRES_COMMAND_OK) ok = false;
    PQclear(r);
  }
  if (!ok) fail("COPY failed");
}

void Connection::copyOut(std::string_view copy_sql, const std::function<void(std::string_view line)>& consume) {
  const std::string text(copy_sql);
  {
    auto r = owned(PQexec(conn_, text.c_str()));
    if (PQresultStatus(r.get()) != PGRES_COPY_OUT) fail("COPY did not start");
  }
  for (;;) {
    char* buffer = nullptr;
    const int n = PQgetCopyData(conn_, &buffer, 0);
    if (n == -1) break;
    if (n < 0) fail("receiving rows failed");
    std::unique_ptr<char, decltype(&PQfreemem)> line(buffer, &PQfreemem);
    std::string_view view(buffer, static_cast<std::size_t>(n));
    if (!view.empty() && view.back() == '\n') view.remove_suffix(1);
    consume(view);
  }
  bool ok = true;
  while (PGresult* r = PQgetResult(conn_)) {
    if (PQresultStatus(r) != PGRES_COMMAND_OK) ok = false;
    PQclear(r);
  }
  if (!ok) fail("COPY failed");
}

PgTransaction::PgTransaction(Connection& c) : c_(c) { c_.exec("BEGIN"); }

PgTransaction::~PgTransaction() {
  if (done_) return;
  try {
    c_.exec("ROLLBACK");
  } catch (...) {  // the connection is gone: the server rolled back
  }
}

void PgTransaction::commit() {
  c_.exec("COMMIT");
  done_ = true;
}

void appendCopyField(std::string& line, const Value& value) {
  if (!value) {
    line += "\\N";
    return;
  }
  for (char ch : *value) {
    switch (ch) {
      case '\\':
        line += "\\\\";
        break;
      case '\t':
        line += "\\t";
        break;
      case '\n':
        line += "\\n";
        break;
      case '\r':
        line += "\\r";
        break;
      default:
        line += ch;
    }
  }
}

Row splitCopyLine(std::string_view line) {
  Row row;
  std::size_t start = 0;
  for (;;) {
    const auto end = line.find('\t', start);
    const auto field = line.substr(start, end == std::string_view::npos ? std::string_view::npos : end - start);
    if (field == "\\N") {
      row.emplace_back();
    } else {
      std::string value;
      value.reserve(field.size());
      for (std::size_t i = 0; i < field.size(); ++i) {
        if (field[i] != '\\') {
          value += field[i];
          continue;
        }
        if (++i == field.size()) throw StorageError("archive: a COPY line ends in a lone backslash");
        switch (field[i]) {
          case 'n':
            value += '\n';
            break;
          case 't':
            value += '\t';
            break;
          case 'r':
            value += '\r';
            break;
          case 'b':
            value += '\b';
            break;
          case 'f':
            value += '\f';
            break;
          case 'v':
            value += '\v';
            break;
          default:
            value += field[i];
        }
      }
      row.emplace_back(std::move(value));
    }
    if (end == std::string_view::npos) break;
    start = end + 1;
  }
  return row;
}

}  // namespace mtcal::archive
