#include "coordinator/http/api_route.h"

#include <httplib.h>
#include <prometheus/registry.h>

#include <utility>
#include <vector>

#include "proto/metrics/metric_builders.h"
#include "proto/net/guarded_connection.h"

namespace tcfarm::http {
namespace {

constexpr const char* kJsonType = "application/json";

// The Authorization header exactly as the client sent it. httplib 0.11.4 percent-decodes
// every header value it parses (detail::parse_header calls decode_url), so its
// Request::headers would take "Bearer TOK%45N" for "Bearer TOKEN" and cut
// "Bearer TOKEN%00junk" at the NUL; the connection keeps the raw head instead. None when the
// header is missing, given twice (which one counts would be a guess) or the raw head is
// not at hand.
std::optional<std::string> RawAuthorization() {
  const GuardedConnection* connection = GuardedConnection::Current();
  if (connection == nullptr) return std::nullopt;
  std::vector<std::string> values = RawHeaderValues(connection->rawHead(), "Authorization");
  if (values.size() != 1) return std::nullopt;
  return std::move(values.front());
}

}  // namespace

void WriteJson(httplib::Response& response, const nlohmann::json& body, int status) {
  response.status = status;
  response.set_content(DumpJson(body), kJsonType);
}

void WriteError(httplib::Response& response, const ApiError& error) {
  if (error.retryAfter()) response.set_header("Retry-After", std::to_string(error.retryAfter()->count()));
  WriteJson(response, error.Body(), error.status());
}

JobState RequireJob(const JobStore& store, uint64_t id) {
  const std::optional<JobState> state = store.StateOf(id);
  if (!state) throw ApiError(404, error_code::kJobNotFound, "no job " + std::to_string(id));
  return *state;
}

JobRecord LoadJob(const JobStore& store, uint64_t id) {
  std::optional<JobRecord> record = store.Get(id);
  if (!record) throw ApiError(404, error_code::kJobNotFound, "no job " + std::to_string(id));
  return std::move(*record);
}

ApiAuth::ApiAuth(std::shared_ptr<const ApiTokens> tokens, prometheus::Registry* metrics)
    : tokens_(std::move(tokens)) {
  if (metrics == nullptr) return;
  auto& refused = NewCounterFamily(*metrics, "tcfarm_http_requests_refused_total",
                                   "API requests refused before they ran: no known token (401, "
                                   "reason unauthorized) or a token whose role is too low (403, forbidden).");
  unauthorized_ = &refused.Add({{"reason", "unauthorized"}});
  forbidden_ = &refused.Add({{"reason", "forbidden"}});
}

std::optional<Caller> ApiAuth::CallerOf(const httplib::Request& request) const {
  if (!tokens_) return std::nullopt;
  if (!request.has_header("Authorization")) return std::nullopt;
  const std::optional<std::string> header = RawAuthorization();
  const std::optional<std::string> token = header ? BearerToken(*header) : std::nullopt;
  if (!token) return std::nullopt;
  return tokens_->Find(*token);
}

void ApiAuth::Authorize(const httplib::Request& request, Access access) const {
  if (!tokens_ || access == Access::kOpen) return;
  const std::optional<Caller> caller = CallerOf(request);
  if (!caller) {
    if (unauthorized_ != nullptr) unauthorized_->Increment();
    const bool sent = request.has_header("Authorization");
    throw ApiError(401, error_code::kUnauthorized,
                   std::string(sent ? "the Authorization header holds no token this coordinator knows"
                                    : "this coordinator needs an API token") +
                       "; expected the header Authorization: Bearer TOKEN with a token of its --api-tokens file");
  }
  const Role needed = access == Access::kRead     ? Role::kRead
                      : access == Access::kSubmit ? Role::kSubmit
                                                  : Role::kAdmin;
  if (caller->role < needed) {
    if (forbidden_ != nullptr) forbidden_->Increment();
    throw ApiError(403, error_code::kForbidden,
                   request.method + " " + request.path + " needs a token of role " + RoleName(needed) +
                       " or above; this one (id " + caller->tokenId + ") has role " + RoleName(caller->role));
  }
}

void ApiAuth::CheckMayChange(const httplib::Request& request, const JobStore& store, uint64_t id) const {
  const std::optional<Caller> caller = CallerOf(request);
  if (!caller || caller->role >= Role::kAdmin) {
    RequireJob(store, id);
    return;
  }
  const JobRecord record = LoadJob(store, id);
  const std::string owner = record.spec.options.is_object() ? record.spec.options.value("submitted_by", "") : "";
  if (owner != caller->tokenId) {
    if (forbidden_ != nullptr) forbidden_->Increment();
    throw ApiError(403, error_code::kForbidden,
                   "job " + std::to_string(id) + " was submitted " +
                       (owner.empty() ? std::string("without a token") : "by token " + owner) + ", not by this one (id " +
                       caller->tokenId + "); a submit token cancels, retries, changes and deletes only its own "
                       "jobs, an admin token any");
  }
}

}  // namespace tcfarm::http
