#pragma once
// Plans the dashboard runs: one at a time (a station's instruments measure one run), each in
// a thread of its own with a session of its own on the archive. Its operator's requests wait
// for an answer from the page; a stop request ends it as Ctrl-C ends `mtcal run`.

#include <atomic>
#include <condition_variable>
#include <memory>
#include <mutex>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "mtcal/error.h"
#include "mtcal/services/run_plan.h"

namespace mtcal::web {

/// A plan asked for while another runs.
struct JobRunning : InputError {
  using InputError::InputError;
};

class Jobs {
 public:
  explicit Jobs(std::string db_path);
  /// Stops the running job and waits for it to end.
  ~Jobs();
  Jobs(const Jobs&) = delete;
  Jobs& operator=(const Jobs&) = delete;

  /// Starts a plan. `first_run_id`: the first run id it can record (every run after it by
  /// this process is the job's). @return the job's number
  /// @throws JobRunning when a job is running (naming it)
  int start(services::PlanRunRequest request, std::int64_t first_run_id);
  /// The job: {"id", "plan", "type", "status" (running, completed, failed, stopped), "error",
  /// "progress" {done, total, what, eta_s}, "messages" [...], "prompt" {number, text} while
  /// one waits, "first_run_id", "result"}. @throws InputError when there is no such job
  nlohmann::json document(int id) const;
  /// Every job, newest first.
  nlohmann::json list() const;
  /// Asks the job to stop (a waiting prompt is withdrawn). @throws InputError when there is no such job
  void stop(int id);
  /// Answers the job's prompt `number` (done). @throws InputError when it is not the one waiting
  void answer(int id, int number);

 private:
  struct Job;
  Job& job(int id) const;
  std::string db_path_;
  mutable std::mutex mutex_;
  std::vector<std::unique_ptr<Job>> jobs_;
};

}  // namespace mtcal::web
