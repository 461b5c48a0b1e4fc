#pragma once
// What the dashboard answers: a request's method, target and headers in, a response out. No
// sockets here, so that every endpoint is one function of the archive.

#include <map>
#include <string>

#include "mtcal/services/session.h"

namespace mtcal::web {

struct Request {
  std::string method;  ///< GET, HEAD, POST ...
  std::string target;  ///< path and query: "/api/runs?kind=linear"
  std::string body;
  /// The headers a state-changing request is judged by: host, origin, content-type,
  /// x-mtcal-request (lower case; absent: not sent).
  std::map<std::string, std::string> headers{};
};

struct Response {
  unsigned status = 200;
  std::string media_type = "application/json";
  std::string body;
  std::map<std::string, std::string> headers;  ///< besides Content-Type and Content-Length
};

class Jobs;

/// The answer to a request that passed the server's checks (token, size). `jobs`: the plans
/// the dashboard runs (none: read-only, nothing changes state).
Response answer(services::Session& session, const Request& request, Jobs* jobs);

/// A JSON error document {"schema_version", "error", "status"} with that status.
Response errorResponse(unsigned status, const std::string& message);

/// The query's parameters, percent-decoded ("a=1&b=x%20y").
std::map<std::string, std::string> queryOf(const std::string& target);
/// The path of a target, without its query.
std::string pathOf(const std::string& target);

}  // namespace mtcal::web
