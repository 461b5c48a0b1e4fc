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
};

struct Response {
  unsigned status = 200;
  std::string media_type = "application/json";
  std::string body;
  std::map<std::string, std::string> headers;  ///< besides Content-Type and Content-Length
};

/// The answer to a request that passed the server's checks (token, size).
Response answer(services::Session& session, const Request& request, bool read_only);

/// A JSON error document {"schema_version", "error", "status"} with that status.
Response errorResponse(unsigned status, const std::string& message);

/// The query's parameters, percent-decoded ("a=1&b=x%20y").
std::map<std::string, std::string> queryOf(const std::string& target);
/// The path of a target, without its query.
std::string pathOf(const std::string& target);

}  // namespace mtcal::web
