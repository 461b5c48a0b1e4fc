#include "jobs.h"

#include <fmt/format.h>

#include <deque>

#include "mtcal/error.h"

namespace mtcal::web {

/// One plan run: its state, shared between its thread and the server's.
struct Jobs::Job final : services::Observer, services::Operator {
  int id = 0;
  std::string plan_name, type;
  std::int64_t first_run_id = 0;
  std::atomic<bool> stop_requested{false};
  std::mutex& mutex;  ///< the registry's: guards everything below
  std::condition_variable answered;
  std::string status = "running", error;
  services::Progress progress;
  std::deque<std::string> messages;   ///< the last 100
  int prompt_number = 0;              ///< of the last prompt asked
  std::optional<std::string> prompt;  ///< the one waiting for an answer
  nlohmann::json result;
  std::thread thread;

  explicit Job(std::mutex& m) : mutex(m) {}

  void onProgress(const services::Progress& p) override {
    std::lock_guard lock(mutex);
    progress = p;
  }
  void onMessage(const std::string& level, const std::string& text) override {
    std::lock_guard lock(mutex);
    say(level + ": " + text);
  }
  void tell(const std::string& text) override {
    std::lock_guard lock(mutex);
    say(text);
  }
  /// Waits for the page's answer (or the stop request).
  void confirm(const std::string& request) override {
    std::unique_lock lock(mutex);
    const int number = ++prompt_number;
    prompt = request;
    say("asked: " + request);
    answered.wait(lock, [&] { return !prompt || prompt_number != number || stop_requested; });
    if (stop_requested) {
      prompt.reset();
      throw InputError("stopped from the dashboard while waiting for: " + request);
    }
  }
  void say(const std::string& text) {
    messages.push_back(text);
    if (messages.size() > 100) messages.pop_front();
  }
};

Jobs::Jobs(std::string db_path) : db_path_(std::move(db_path)) {}

Jobs::~Jobs() {
  // No job starts any more: the server that started them has stopped.
  for (auto& j : jobs_) {
    {
      std::lock_guard lock(mutex_);
      j->stop_requested = true;
    }
    j->answered.notify_all();
    if (j->thread.joinable()) j->thread.join();
  }
}

int Jobs::start(services::PlanRunRequest request, std::int64_t first_run_id) {
  std::lock_guard lock(mutex_);
  for (const auto& j : jobs_) {
    if (j->status == "running")
      throw JobRunning(fmt::format("job {} ({}) is running: stop it or wait for it to end", j->id, j->plan_name));
  }
  auto job = std::make_unique<Job>(mutex_);
  job->id = static_cast<int>(jobs_.size()) + 1;
  job->plan_name = request.plan_name;
  job->type = services::planType(request.plan, request.plan_name);
  job->first_run_id = first_run_id;
  Job& j = *job;
  jobs_.push_back(std::move(job));
  j.thread = std::thread([this, &j, request = std::move(request)] {
    services::SessionOptions options;
    options.db_path = db_path_;
    options.operator_name = "dashboard";
    options.observer = &j;
    options.person = &j;
    options.stop_requested = &j.stop_requested;
    std::string status, error;
    nlohmann::json result;
    try {
      services::Session session(options);
      result = services::runPlan(session, request);
      status = j.stop_requested ? "stopped" : "completed";
    } catch (const std::exception& e) {
      status = j.stop_requested ? "stopped" : "failed";
      error = e.what();
    }
    std::lock_guard done(mutex_);
    j.status = status, j.error = error, j.result = std::move(result);
    j.prompt.reset();
    j.progress.eta_s.reset();  // nothing left to wait for
  });
  return j.id;
}

Jobs::Job& Jobs::job(int id) const {
  if (id < 1 || id > static_cast<int>(jobs_.size())) throw InputError(fmt::format("no job {}", id));
  return *jobs_[static_cast<std::size_t>(id - 1)];
}

nlohmann::json Jobs::document(int id) const {
  std::lock_guard lock(mutex_);
  const Job& j = job(id);
  nlohmann::json d{{"schema_version", 1},
                   {"id", j.id},
                   {"plan", j.plan_name},
                   {"type", j.type},
                   {"status", j.status},
                   {"first_run_id", j.first_run_id},
                   {"progress", {{"done", j.progress.done}, {"total", j.progress.total}, {"what", j.progress.what}}},
                   {"messages", j.messages}};
  if (j.progress.eta_s) d["progress"]["eta_s"] = *j.progress.eta_s;
  if (!j.error.empty()) d["error"] = j.error;
  if (j.prompt) d["prompt"] = {{"number", j.prompt_number}, {"text", *j.prompt}};
  if (!j.result.is_null()) d["result"] = j.result;
  return d;
}

nlohmann::json Jobs::list() const {
  nlohmann::json list = nlohmann::json::array();
  std::size_t n = 0;
  {
    std::lock_guard lock(mutex_);
    n = jobs_.size();
  }
  for (std::size_t k = n; k > 0; --k) list.push_back(document(static_cast<int>(k)));
  return {{"schema_version", 1}, {"jobs", list}};
}

void Jobs::stop(int id) {
  Job* j = nullptr;
  {
    std::lock_guard lock(mutex_);
    j = &job(id);
    j->stop_requested = true;
  }
  j->answered.notify_all();
}

void Jobs::answer(int id, int number) {
  Job* j = nullptr;
  {
    std::lock_guard lock(mutex_);
    j = &job(id);
    if (!j->prompt || j->prompt_number != number) {
      throw InputError(j->prompt ? fmt::format("job {} waits for prompt {}, not {}", id, j->prompt_number, number)
                                 : fmt::format("job {} waits for no answer", id));
    }
    j->say("answered: " + *j->prompt);
    j->prompt.reset();
  }
  j->answered.notify_all();
}

}  // namespace mtcal::web
