#pragma once
// A session: the archive a front end works on, who works in it, and whom long work reports
// to. Every user-level operation of services takes one; the command line, the web server and
// programs using mtcal as a library each make their own (docs/architecture.md, "Services").
//
// Thread-safety: a session belongs to one thread at a time (its store is one SQLite
// connection); observers are called on that thread.

#include <atomic>
#include <chrono>
#include <cstddef>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "mtcal/drivers/instrument.h"
#include "mtcal/storage/heartbeat.h"
#include "mtcal/storage/store.h"

namespace mtcal::services {

/// How far a long operation is.
struct Progress {
  std::size_t done = 0, total = 0;  ///< in the operation's own steps: targets, steps, samples, features
  std::string what;                 ///< the step just done, for people
  std::optional<double> eta_s;      ///< wall seconds left at the pace so far (none before the first step)
};

/// Receives what long work reports. Every method has a default that ignores it.
class Observer {
 public:
  virtual ~Observer() = default;
  virtual void onProgress(const Progress& /*progress*/) {}
  /// Something to tell people while the work goes on (levels: info, warning).
  virtual void onMessage(const std::string& /*level*/, const std::string& /*text*/) {}
};

/// The person at the machine: what mtcal needs done by hand.
class Operator {
 public:
  virtual ~Operator() = default;
  /// Shows `request` and returns once it is done (the reflector placed, the program started).
  /// @throws InputError when nobody can answer (no operator, input closed)
  virtual void confirm(const std::string& request) = 0;
  /// Tells what to do now, without waiting for an answer.
  virtual void tell(const std::string& text) = 0;
};

struct SessionOptions {
  std::string db_path = "mtcal.sqlite";
  std::string operator_name;                          ///< recorded with every run; empty: not known
  Observer* observer = nullptr;                       ///< none: nothing is reported
  Operator* person = nullptr;                         ///< none: nobody to ask (operations that need one say so)
  const std::atomic<bool>* stop_requested = nullptr;  ///< set to cancel (Ctrl-C, the dashboard's stop button)
  bool read_only = false;  ///< never write the archive (results are shown, not stored); operations that add refuse
  /// Read only, for a long-lived reader (the dashboard): sees the runs other processes record
  /// while it is open (storage::Open::kReadOnlyFollowing).
  bool follow_writers = false;
};

/// What an operation does with the archive.
enum class Access {
  kRead,    ///< reads (and stores results): the archive must exist; a write-protected one is read only
  kCreate,  ///< adds runs or models: the archive is created when missing
  kRecord,  ///< records runs: created when missing, and this process's heartbeat kept while the session lives
};

class Session {
 public:
  explicit Session(SessionOptions options);
  ~Session();
  /// The archive, opened (and migrated) on first use. @throws StorageError naming the file
  /// when it is missing and `access` does not create it
  storage::Store& store(Access access = Access::kRead);
  /// Opens the archive now (a server says a missing one at its start, not at the first request).
  void open(Access access = Access::kRead) { store(access); }
  /// Closes and removes the store this session created, when the operation that needed it
  /// failed and it holds no run and no model (call only for a store this session created).
  void discardNewStore();
  /// Stores an analysis of a run, once: the same processor, version, parameters and output
  /// as a stored result reuse it (results are never overwritten). On a read-only archive
  /// nothing is stored and the observer is told. @return the result's id, none when not stored
  std::optional<storage::Id> storeResult(storage::Id run_id, const std::string& processor, const std::string& version,
                                         const std::string& parameters_json, const std::string& output_json);
  const SessionOptions& options() const { return options_; }
  /// The observer given, or one that ignores everything.
  Observer& observer() const;
  /// The operator. @throws InputError naming `why` when the session has none
  Operator& person(const std::string& why) const;
  const std::atomic<bool>* stopRequested() const { return options_.stop_requested; }
  /// The instrument in the archive (added on first use). @throws StorageError
  storage::Id instrument(const drivers::DeviceInfo& info);
  /// Refuses `command` when --db is the plant archive (it is read, never written, and has no
  /// store file to check or copy). @throws InputError
  void requireLocalStore(const std::string& command) const;
  /// Records who measured a run (this session's operator) and every instrument that took
  /// part, with what it measured (`role`). One place for every run kind.
  void recordRun(storage::Id run_id, const std::vector<std::pair<drivers::DeviceInfo, std::string>>& instruments);

 private:
  SessionOptions options_;
  std::unique_ptr<storage::Store> store_;
  std::unique_ptr<storage::Heartbeat> heartbeat_;
};

/// Run ids from "12" or "cN" (every completed or imported run of campaign N whose kind is one
/// of `kinds`), in order, once each; a run given again (by its id and its campaign) is added to
/// `given_twice` when given. @throws InputError naming a source that is neither, or a campaign
/// without such a run
std::vector<storage::Id> resolveRuns(storage::Store& store, const std::vector<std::string>& sources,
                                     const std::vector<std::string>& kinds,
                                     std::vector<storage::Id>* given_twice = nullptr);

/// Progress of `total` steps timed from its construction, `done_before` of them done
/// earlier (a resumed run): the time left at the pace of this session's steps.
class ProgressClock {
 public:
  explicit ProgressClock(std::size_t total, std::size_t done_before = 0)
      : total_(total), done_before_(done_before), start_(std::chrono::steady_clock::now()) {}
  /// `done` of the total reached, just now.
  Progress at(std::size_t done, std::string what) const;
  std::size_t total() const { return total_; }

 private:
  std::size_t total_, done_before_;
  std::chrono::steady_clock::time_point start_;
};

}  // namespace mtcal::services
