// What every route group of the HTTP API shares: the shape of a route, who may call it
// (ApiAuth), the JSON replies, and the job lookups that answer 404 the same way. Each group
// (http/*_routes.h) lists its routes and answers them with the stores it is given; ApiServer
// (http/api_server.h) registers every group's routes, checks the caller's token first and
// turns what a handler throws into the one error shape (http/api_error.h).
#pragma once

#include <cstddef>
#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <string>

#include <nlohmann/json.hpp>

#include "coordinator/http/api_error.h"
#include "coordinator/http/api_tokens.h"
#include "coordinator/jobs/job_store.h"

namespace httplib {
struct Request;
struct Response;
}  // namespace httplib

namespace prometheus {
class Counter;
class Registry;
}  // namespace prometheus

namespace tcfarm::http {

// The least a caller needs for a route when the server has tokens.
enum class Access { kOpen, kRead, kSubmit, kAdmin };

// body: the request body, read by the server within ApiOptions::maxBodyBytes (httplib's
// Request::body stays empty for bodies read that way).
using Handler =
    std::function<void(const httplib::Request& request, const std::string& body, httplib::Response& response)>;
// For a body too large to hold in memory (asset uploads): the handler reads it from `read`
// as it arrives. `read` calls its argument per piece, false when the body could not be read
// whole; a request without a body has none.
using BodyPieces = std::function<bool(const std::function<void(const char* data, size_t length)>&)>;
using StreamHandler =
    std::function<void(const httplib::Request& request, const BodyPieces& read, httplib::Response& response)>;

struct Route {
  const char* method;
  const char* pattern;  // a regex on the decoded path; groups are the path parameters
  Access access;
  Handler handle;
  StreamHandler stream = nullptr;  // instead of handle, for routes that stream their body
};

// A group's member function as a route's handler.
template <class Group>
Handler Bind(Group* group,
             void (Group::*handle)(const httplib::Request&, const std::string&, httplib::Response&)) {
  return [group, handle](const httplib::Request& request, const std::string& body, httplib::Response& response) {
    (group->*handle)(request, body, response);
  };
}
template <class Group>
StreamHandler Bind(Group* group,
                   void (Group::*stream)(const httplib::Request&, const BodyPieces&, httplib::Response&)) {
  return [group, stream](const httplib::Request& request, const BodyPieces& read, httplib::Response& response) {
    (group->*stream)(request, read, response);
  };
}

void WriteJson(httplib::Response& response, const nlohmann::json& body, int status = 200);
void WriteError(httplib::Response& response, const ApiError& error);

JobState RequireJob(const JobStore& store, uint64_t id);  // throws ApiError 404 job_not_found
JobRecord LoadJob(const JobStore& store, uint64_t id);    // the same, loading the whole record

// Who is calling, by the Authorization header's API token, and what that token may do.
class ApiAuth {
 public:
  // tokens null: every request is allowed. metrics (may be null) gets the count of refusals.
  ApiAuth(std::shared_ptr<const ApiTokens> tokens, prometheus::Registry* metrics);

  // The token's owner; nullopt when the server has no tokens.
  std::optional<Caller> CallerOf(const httplib::Request& request) const;
  // Throws ApiError 401 (no known token) or 403 (a role too low). Without tokens, allows all.
  void Authorize(const httplib::Request& request, Access access) const;
  // A submit token cancels, retries, changes and deletes only the jobs it submitted;
  // throws 403 for another's (404 for an unknown job).
  void CheckMayChange(const httplib::Request& request, const JobStore& store, uint64_t id) const;

 private:
  std::shared_ptr<const ApiTokens> tokens_;
  prometheus::Counter* unauthorized_ = nullptr;  // 401s, with a metrics registry only
  prometheus::Counter* forbidden_ = nullptr;     // 403s
};

}  // namespace tcfarm::http
