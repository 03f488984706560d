// The HTTP API's one error shape:
//
//   {"error": {"status": 400, "code": "invalid_scene", "message": "...", "pointer": "/scene/..."}}
//
// Handlers and request validation throw ApiError; the server turns it into that body, so
// no route can answer an error in any other shape. "pointer" (RFC 6901, into the request
// body) is there only when the bad value has one.
#pragma once

#include <chrono>
#include <optional>
#include <stdexcept>
#include <string>

#include <nlohmann/json.hpp>

namespace tcfarm::http {

// The codes clients may branch on; proto/openapi.yaml lists the same set.
namespace error_code {
inline constexpr const char* kInvalidJson = "invalid_json";            // 400
inline constexpr const char* kUnknownField = "unknown_field";          // 400
inline constexpr const char* kMissingField = "missing_field";          // 400
inline constexpr const char* kInvalidField = "invalid_field";          // 400
inline constexpr const char* kInvalidScene = "invalid_scene";          // 400
inline constexpr const char* kInvalidParameter = "invalid_parameter";  // 400, path or query
inline constexpr const char* kMissingAsset = "missing_asset";          // 400, a hash the store lacks
inline constexpr const char* kAssetHashMismatch = "asset_hash_mismatch"; // 400, body is not the named asset
inline constexpr const char* kBadRequest = "bad_request";              // 400, malformed HTTP
inline constexpr const char* kUnauthorized = "unauthorized";            // 401, no known API token
inline constexpr const char* kForbidden = "forbidden";                  // 403, the token's role is too low
inline constexpr const char* kNotFound = "not_found";                  // 404, no such route
inline constexpr const char* kJobNotFound = "job_not_found";           // 404
inline constexpr const char* kFrameNotReady = "frame_not_ready";       // 404
inline constexpr const char* kBanNotFound = "ban_not_found";           // 404, lift a ban nobody holds
inline constexpr const char* kMethodNotAllowed = "method_not_allowed"; // 405
inline constexpr const char* kJobFinished = "job_finished";            // 409
inline constexpr const char* kJobActive = "job_active";                // 409, delete a queued or running job
inline constexpr const char* kJobNotRetryable = "job_not_retryable";  // 409, retry a job neither failed nor canceled
inline constexpr const char* kPayloadTooLarge = "payload_too_large";   // 413
inline constexpr const char* kJobTooLarge = "job_too_large";           // 413, frames beyond memory
inline constexpr const char* kImportTooLarge = "import_too_large";     // 413, beyond the whole import budget
inline constexpr const char* kInternal = "internal";                   // 500
inline constexpr const char* kNotImplemented = "not_implemented";      // 501, a method no route takes
inline constexpr const char* kTooManyStreams = "too_many_streams";    // 503, event streams at their limit
inline constexpr const char* kShuttingDown = "shutting_down";          // 503, the coordinator is stopping
inline constexpr const char* kImportBusy = "import_busy";              // 503, the import budget is in use
inline constexpr const char* kInsufficientStorage = "insufficient_storage";  // 507, the disk refused
}  // namespace error_code

class ApiError : public std::runtime_error {
 public:
  ApiError(int status, std::string code, const std::string& message,
           std::optional<std::string> pointer = std::nullopt)
      : std::runtime_error(message), status_(status), code_(std::move(code)),
        pointer_(std::move(pointer)) {}

  int status() const { return status_; }
  const std::string& code() const { return code_; }
  const std::optional<std::string>& pointer() const { return pointer_; }
  // A refusal the same request may get past later (503): the answer's Retry-After header.
  ApiError& RetryAfter(std::chrono::seconds wait) {
    retryAfter_ = wait;
    return *this;
  }
  const std::optional<std::chrono::seconds>& retryAfter() const { return retryAfter_; }

  nlohmann::json Body() const;

 private:
  int status_;
  std::string code_;
  std::optional<std::string> pointer_;
  std::optional<std::chrono::seconds> retryAfter_;
};

// Serializes for a response body. Replaces invalid UTF-8 instead of throwing: error
// messages quote whatever bytes the client sent.
std::string DumpJson(const nlohmann::json& value);

// A client's value quoted for a message, as JSON (control bytes escaped: a NUL cannot cut
// the message short), at most 60 bytes of it.
std::string ShowValue(const nlohmann::json& value);

}  // namespace tcfarm::http
