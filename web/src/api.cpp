#include "api.h"

#include <fmt/format.h>
#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <limits>
#include <nlohmann/json.hpp>
#include <regex>

#include "assets.h"
#include "jobs.h"
#include "mtcal/error.h"
#include "mtcal/services/archive.h"
#include "mtcal/services/compensate.h"
#include "mtcal/services/export.h"
#include "mtcal/services/model.h"
#include "mtcal/services/report.h"
#include "mtcal/services/run_plan.h"
#include "mtcal/services/version.h"

namespace mtcal::web {
namespace {

constexpr std::size_t kPageOfRuns = 500, kMaxPageOfRuns = 20000;

Response json(const nlohmann::json& document) { return {200, "application/json", document.dump(), {}}; }

int hexValue(char c) {
  if (c >= '0' && c <= '9') return c - '0';
  c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return c >= 'a' && c <= 'f' ? c - 'a' + 10 : -1;
}

std::string percentDecoded(const std::string& text) {
  std::string out;
  for (std::size_t i = 0; i < text.size(); ++i) {
    if (text[i] == '+') {
      out += ' ';
    } else if (text[i] == '%' && i + 2 < text.size() && hexValue(text[i + 1]) >= 0 && hexValue(text[i + 2]) >= 0) {
      out += static_cast<char>(hexValue(text[i + 1]) * 16 + hexValue(text[i + 2]));
      i += 2;
    } else {
      out += text[i];
    }
  }
  return out;
}

struct NotFound : InputError {
  using InputError::InputError;
};

/// A file to save, named.
Response download(std::string body, const std::string& media_type, const std::string& file_name) {
  return {200, media_type, std::move(body), {{"Content-Disposition", "attachment; filename=\"" + file_name + "\""}}};
}

/// A report, or the reason there is none as a page of its own (the run page shows it framed).
Response reportPage(services::Session& session, const services::ArchiveItem& what,
                    const std::map<std::string, std::string>& query) {
  services::ReportRequest request;
  try {
    if (const auto it = query.find("after"); it != query.end()) {
      request.after = services::ArchiveItem::parse(it->second, "r").run;
    }
    if (const auto it = query.find("standard"); it != query.end()) request.standard = it->second;
    return {200, "text/html; charset=utf-8", services::makeReport(session, what, request).html, {}};
  } catch (const NotFound&) {
    throw;
  } catch (const InputError& e) {
    return {422,
            "text/html; charset=utf-8",
            "<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\"><title>No report</title></head><body>"
            "<p>No report: " +
                services::xmlEscape(e.what()) + "</p></body></html>\n",
            {}};
  }
}

Response runEndpoint(services::Session& session, const std::string& id_text, const std::string& what,
                     const std::string& name, const std::map<std::string, std::string>& query) {
  const storage::Id id = std::stoll(id_text);
  services::ArchiveItem item;
  item.run = id;
  try {
    services::runsOf(session, item);
  } catch (const InputError& e) {
    throw NotFound(e.what());
  }
  if (what.empty()) return json(services::showRun(session, id).document());
  if (what == "report.html" && name.empty()) return reportPage(session, item, query);
  if (what == "report.pdf" && name.empty()) {
    return download(services::pdfOf(services::makeReport(session, item, {}).html), "application/pdf",
                    fmt::format("run{}_report.pdf", id));
  }
  if (what == "files" && name.empty()) {
    nlohmann::json files = nlohmann::json::array();
    for (const auto& f : services::exportedFiles(session, id)) {
      files.push_back({{"name", f.path.substr(f.path.find('_') + 1)}, {"file", f.path}, {"what", f.what}});
    }
    return json({{"schema_version", 1}, {"run_id", id}, {"files", files}});
  }
  if (what == "files") {
    const auto body = services::exportedFile(session, id, name);
    return download(body, name.ends_with(".json") ? "application/json" : "text/csv; charset=utf-8",
                    fmt::format("run{}_{}", id, name));
  }
  if (what == "compensation" && name.empty()) {
    services::CompensateRequest request;
    if (const auto it = query.find("controller"); it != query.end()) request.controller = it->second;
    // The table's options as `mtcal compensate` takes them: start, end, interval, reference (mm), mean.
    for (const auto& [key, into] : {std::pair{"start", &request.table.start},
                                    {"end", &request.table.end},
                                    {"interval", &request.table.interval},
                                    {"reference", &request.table.reference}}) {
      const auto it = query.find(key);
      if (it == query.end() || it->second.empty()) continue;
      std::size_t used = 0;
      double value = NAN;
      try {
        value = std::stod(it->second, &used);
      } catch (const std::exception&) {
        used = 0;
      }
      if (used == 0 || used != it->second.size() || !std::isfinite(value))
        throw InputError(fmt::format("{}={}: a number of millimetres, e.g. 20", key, it->second));
      *into = value;
    }
    request.table.bidirectional = !query.count("mean");
    const auto table = services::compensateRun(session, id, request);
    return download(table.file.text, "text/plain; charset=utf-8",
                    fmt::format("run{}_{}_{}{}", id, table.axis, table.controller, table.file.extension));
  }
  throw NotFound("no such page of a run: " + what + (name.empty() ? "" : "/" + name));
}

/// A state-changing request comes from the dashboard's own pages: a JSON body, the header
/// X-Mtcal-Request (a page of another site cannot send it without a CORS preflight, which is
/// never granted) and, when the browser names the origin, this server's. @return the refusal
std::optional<Response> crossSiteRefusal(const Request& request) {
  const auto header = [&](const char* name) {
    const auto it = request.headers.find(name);
    return it == request.headers.end() ? std::string() : it->second;
  };
  const std::string origin = header("origin");
  if (header("x-mtcal-request").empty() || !header("content-type").starts_with("application/json") ||
      (!origin.empty() && origin != "http://" + header("host"))) {
    return errorResponse(403,
                         "a request that changes state must come from the dashboard's own pages (a JSON body, the "
                         "header X-Mtcal-Request, the same origin)");
  }
  return std::nullopt;
}

/// The job's document with the runs it recorded so far: of `runs` (the archive's), this
/// process' from its first run id up to the next job's.
nlohmann::json jobDocument(const std::vector<storage::RunInfo>& runs, Jobs& jobs, int id) {
  auto d = jobs.document(id);
  std::int64_t until = std::numeric_limits<std::int64_t>::max();
  try {
    until = jobs.document(id + 1)["first_run_id"].get<std::int64_t>();
  } catch (const InputError&) {
    // the newest job
  }
  nlohmann::json own = nlohmann::json::array();
  for (const auto& run : runs) {
    if (run.id >= d["first_run_id"].get<std::int64_t>() && run.id < until && run.owner && run.owner->pid == ::getpid())
      own.push_back(run.id);
  }
  d["runs"] = own;
  return d;
}

Response jobEndpoint(services::Session& session, const Request& request, Jobs& jobs) {
  const std::string path = pathOf(request.target);
  static const std::regex job_path("/api/jobs/([0-9]{1,9})(?:/(stop|answer))?");
  std::smatch m;
  if (request.method != "POST") {
    if (std::regex_match(path, m, job_path) && m[2].matched) {
      auto r = errorResponse(405, "POST only: it changes the job");
      r.headers["Allow"] = "POST";
      return r;
    }
    if (path == "/api/jobs") {
      auto list = jobs.list();
      const auto runs = services::listRuns(session);  // once for every job
      for (auto& job : list["jobs"]) job = jobDocument(runs, jobs, job["id"].get<int>());
      return json(list);
    }
    if (!std::regex_match(path, m, job_path) || m[2].matched) throw NotFound("no such page: " + path);
    try {
      return json(jobDocument(services::listRuns(session), jobs, std::stoi(m[1])));
    } catch (const InputError& e) {
      throw NotFound(e.what());
    }
  }
  if (auto refused = crossSiteRefusal(request)) return *refused;
  const auto body = nlohmann::json::parse(request.body, nullptr, false);
  if (!body.is_object()) throw InputError("the request's body is not a JSON object");
  if (path == "/api/jobs") {
    // {"plan": {...}, "plan_name", "device", "logger", "machine", "seed", "time_scale"}
    services::PlanRunRequest plan;
    plan.plan = body.value("plan", nlohmann::json());
    plan.plan_name = body.value("plan_name", std::string("the plan"));
    services::planType(plan.plan, "key 'plan'");
    plan.device_uri = body.value("device", std::string());
    plan.logger_uri = body.value("logger", std::string());
    plan.machine = body.value("machine", std::string("unnamed machine"));
    if (body.contains("seed")) {
      if (!body["seed"].is_number_unsigned()) throw InputError("key 'seed': a whole number");
      plan.simulation.seed = body["seed"].get<std::uint64_t>();
    }
    if (body.contains("time_scale")) {
      if (!body["time_scale"].is_number() || !(body["time_scale"].get<double>() > 0.0))
        throw InputError("key 'time_scale': simulated seconds per second, more than 0");
      plan.simulation.time_scale = body["time_scale"].get<double>();
    }
    services::RunFilter newest;
    newest.descending = true;
    const auto runs = services::listRuns(session, newest);
    const int id = jobs.start(std::move(plan), runs.empty() ? 1 : runs.front().id + 1);
    auto r = json(jobDocument(services::listRuns(session), jobs, id));
    r.status = 201;
    r.headers["Location"] = fmt::format("/api/jobs/{}", id);
    return r;
  }
  if (!std::regex_match(path, m, job_path) || !m[2].matched) throw NotFound("no such page: " + path);
  const int id = std::stoi(m[1]);
  try {
    jobs.document(id);
  } catch (const InputError& e) {
    throw NotFound(e.what());
  }
  if (m[2] == "stop") {
    jobs.stop(id);
  } else {
    if (!body.contains("prompt") || !body["prompt"].is_number_integer())
      throw InputError("key 'prompt': the number of the prompt answered");
    jobs.answer(id, body["prompt"].get<int>());
  }
  return json(jobDocument(services::listRuns(session), jobs, id));
}

}  // namespace

Response errorResponse(unsigned status, const std::string& message) {
  return {status,
          "application/json",
          nlohmann::json{{"schema_version", 1}, {"error", message}, {"status", status}}.dump(),
          {}};
}

std::string pathOf(const std::string& target) { return target.substr(0, target.find('?')); }

std::map<std::string, std::string> queryOf(const std::string& target) {
  std::map<std::string, std::string> out;
  const auto q = target.find('?');
  if (q == std::string::npos) return out;
  std::size_t at = q + 1;
  while (at <= target.size()) {
    const auto end = std::min(target.find('&', at), target.size());
    const std::string pair = target.substr(at, end - at);
    const auto eq = pair.find('=');
    if (!pair.empty())
      out[percentDecoded(pair.substr(0, eq))] = eq == std::string::npos ? "" : percentDecoded(pair.substr(eq + 1));
    at = end + 1;
  }
  return out;
}

Response answer(services::Session& session, const Request& request, Jobs* jobs) {
  const bool read_only = jobs == nullptr;
  const std::string path = pathOf(request.target);
  const bool job_path = path == "/api/jobs" || path.starts_with("/api/jobs/");
  if (request.method != "GET" && request.method != "HEAD" && !(request.method == "POST" && jobs && job_path)) {
    auto r = errorResponse(405, read_only  ? "the dashboard is read-only: only GET and HEAD"
                                : job_path ? "GET, HEAD or POST"
                                           : "only GET and HEAD");
    r.headers["Allow"] = !read_only && job_path ? "GET, HEAD, POST" : "GET, HEAD";
    return r;
  }
  try {
    if (job_path) {
      if (read_only) return errorResponse(404, "the dashboard is read-only: it runs no plans");
      return jobEndpoint(session, request, *jobs);
    }
    if (path == "/") {
      Response r{302, "text/plain", "", {{"Location", "/index.html"}}};
      return r;
    }
    for (const auto& a : assets()) {
      if (path == a.path) return {200, std::string(a.media_type), std::string(a.content), {}};
    }
    if (path == "/api/status") {
      return json({{"schema_version", 1},
                   {"archive", session.options().db_path},
                   {"read_only", read_only},
                   {"controllers", services::compensationControllers()},
                   {"version", services::kVersion}});
    }
    if (path == "/api/runs") {
      const auto q = queryOf(request.target);
      services::RunFilter filter;
      const auto take = [&](const char* key, std::string& into) {
        if (const auto it = q.find(key); it != q.end()) into = it->second;
      };
      take("machine", filter.machine), take("kind", filter.kind), take("axis", filter.axis);
      take("status", filter.status), take("since", filter.since), take("until", filter.until);
      take("sort", filter.sort);
      if (const auto it = q.find("campaign"); it != q.end() && !it->second.empty()) {
        filter.campaign = services::ArchiveItem::parse(it->second, "c").campaign;
      }
      if (q.count("descending")) filter.descending = true;
      // A page of the list: an archive of years has tens of thousands of runs, and a browser
      // shows a few hundred usefully.
      const auto number = [&](const char* key, std::size_t fallback, std::size_t largest) {
        const auto it = q.find(key);
        if (it == q.end()) return fallback;
        std::size_t used = 0;
        unsigned long long v = 0;
        try {
          v = std::stoull(it->second, &used);
        } catch (const std::exception&) {
          used = 0;
        }
        if (used == 0 || used != it->second.size() || v > largest)
          throw InputError(fmt::format("{}={}: a whole number up to {}", key, it->second, largest));
        return static_cast<std::size_t>(v);
      };
      const std::size_t limit = number("limit", kPageOfRuns, kMaxPageOfRuns);
      const std::size_t offset = number("offset", 0, std::numeric_limits<std::uint32_t>::max());
      auto runs = services::listRuns(session, filter);
      const std::size_t total = runs.size();
      runs.erase(runs.begin(), runs.begin() + static_cast<std::ptrdiff_t>(std::min(offset, total)));
      if (runs.size() > limit) runs.resize(limit);
      auto document = services::runListDocument(runs);
      document["total"] = total;
      document["offset"] = offset;
      document["limit"] = limit;
      return json(document);
    }
    if (path == "/api/models") return json(services::modelListDocument(services::listModels(session)));
    static const std::regex run_path("/api/runs/([0-9]{1,15})(?:/([a-z0-9._]+)(?:/([a-z0-9._]+))?)?");
    static const std::regex report_path("/api/(campaigns|models)/([0-9]{1,15})/report\\.html");
    std::smatch m;
    if (std::regex_match(path, m, run_path)) return runEndpoint(session, m[1], m[2], m[3], queryOf(request.target));
    if (std::regex_match(path, m, report_path)) {
      const auto what = services::ArchiveItem::parse((m[1] == "models" ? "m" : "c") + m[2].str(), "cm");
      const auto models = what.model ? services::listModels(session) : std::vector<storage::ModelRecord>{};
      if (what.model && std::none_of(models.begin(), models.end(), [&](const auto& r) { return r.id == *what.model; }))
        throw NotFound(fmt::format("no model {}", *what.model));
      try {
        if (what.campaign) services::runsOf(session, what);
      } catch (const InputError& e) {
        throw NotFound(e.what());
      }
      return reportPage(session, what, queryOf(request.target));
    }
    return errorResponse(404, "no such page: " + path);
  } catch (const NotFound& e) {
    return errorResponse(404, e.what());
  } catch (const JobRunning& e) {
    return errorResponse(409, e.what());
  } catch (const InputError& e) {
    return errorResponse(422, e.what());
  } catch (const nlohmann::json::exception& e) {
    // A request's JSON of the wrong shape (a number where a name belongs ...).
    return errorResponse(422, std::string("the request's JSON: ") + e.what());
  } catch (const Error& e) {
    return errorResponse(500, e.what());
  } catch (const std::exception& e) {
    return errorResponse(500, e.what());
  }
}

}  // namespace mtcal::web
