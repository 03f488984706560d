#include "coordinator/http/api_server.h"

#include <httplib.h>
#include <prometheus/registry.h>
#include <prometheus/text_serializer.h>

#include <algorithm>
#include <chrono>
#include <map>
#include <cstdio>
#include <fstream>
#include <limits>
#include <stdexcept>
#include <utility>

#include <sys/socket.h>

#include "proto/frame/frame_io.h"
#include "coordinator/http/api_error.h"
#include "coordinator/http/query_params.h"
#include "coordinator/http/submit_request.h"
#include "proto/metrics/metric_builders.h"
#include "proto/net/guarded_server.h"
#include "coordinator/planner/job_memory.h"
#include "coordinator/planner/planner.h"
#include "coordinator/store/frame_finisher.h"

namespace tcfarm {
namespace {

using http::AllDigits;
using http::ApiError;
using http::ParseInteger;
using http::ParseJobId;
using http::ParseNameFilter;
using http::ParseStateFilter;
using http::ParseStrategyFilter;
using http::RequireAtMostOnce;
using nlohmann::json;
namespace error_code = http::error_code;

constexpr int kDefaultListLimit = 50;
constexpr int kMaxListLimit = 1000;  // one page stays a few hundred KiB of JSON
constexpr int64_t kMaxListOffset = int64_t{1} << 53;
// A job's events in one answer: every event of all but the longest jobs (a frames_written
// event covers ten frames or a second); `after` pages through the rest.
constexpr int64_t kMaxEventsPerPage = 10000;
constexpr int64_t kMaxEventSeq = int64_t{1} << 53;
// Events read from the store at once while a stream catches up.
constexpr size_t kStreamBatch = 500;
// A stream looks at the store at least this often: another process may record events its
// listener never hears, and Stop is seen this soon.
constexpr std::chrono::milliseconds kStreamPoll{1000};
constexpr size_t kFileChunkBytes = 64u << 10;
constexpr const char* kJsonType = "application/json";
// The Prometheus text exposition format, version 0.0.4: what a scraper asks for.
constexpr const char* kMetricsType = "text/plain; version=0.0.4";
constexpr const char* kMethodsWithCatchAll[] = {"GET", "POST", "PUT", "PATCH", "DELETE", "OPTIONS"};

void WriteJson(httplib::Response& response, const json& body, int status = 200) {
  response.status = status;
  response.set_content(http::DumpJson(body), kJsonType);
}

void WriteError(httplib::Response& response, const ApiError& error) {
  WriteJson(response, error.Body(), error.status());
}

ApiError PayloadTooLarge(size_t maxBytes) {
  return ApiError(413, error_code::kPayloadTooLarge,
                  "request body is larger than the limit of " + std::to_string(maxBytes) + " bytes");
}

ApiError AssetTooLarge(uint64_t maxBytes) {
  return ApiError(413, error_code::kPayloadTooLarge,
                  "asset is larger than the limit of " + std::to_string(maxBytes) + " bytes (" +
                      std::to_string(maxBytes >> 20) + " MiB, --asset-max-file-mib)");
}

bool TakesBody(const std::string& method) {
  return method == "POST" || method == "PUT" || method == "PATCH" || method == "DELETE";
}

// The connection ends after this response: the rest of the request's body is never read
// (net/guarded_server.h).
void CloseAfterResponse() {
  if (GuardedConnection* connection = GuardedConnection::Current()) connection->CloseAfterResponse();
}

// Reads the whole body, at most maxBytes of it: past that reading stops and the connection
// closes after the 413. A Content-Length over the limit never gets here (the server's gate
// refuses it before reading); a chunked body, or what a compressed one inflates to, is
// counted here as it comes. nullopt when the body is too large (413) or could not be read
// (400): the error is in response already.
std::optional<std::string> ReadLimitedBody(const httplib::ContentReader& reader, size_t maxBytes,
                                           httplib::Response& response) {
  std::string body;
  bool tooLarge = false;
  const bool complete = reader([&](const char* data, size_t length) {
    tooLarge = length > maxBytes - body.size();
    if (!tooLarge) body.append(data, length);
    return !tooLarge;
  });
  if (tooLarge) {
    CloseAfterResponse();
    WriteError(response, PayloadTooLarge(maxBytes));
    return std::nullopt;
  }
  if (!complete) {
    WriteError(response, ApiError(400, error_code::kBadRequest, "the request body could not be read"));
    return std::nullopt;
  }
  return body;
}

// A refused request's body is never read: an anonymous client cannot fill memory or disk,
// nor hold a thread while it sends. The connection closes after the answer instead, so
// the body's bytes are never taken for a next request.
void RefuseBody(const httplib::Request& request) {
  if (request.has_header("Content-Length") || request.has_header("Transfer-Encoding")) CloseAfterResponse();
}

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

int ParseLimit(const httplib::Request& request) {
  return static_cast<int>(ParseInteger(request, "limit", 1, kMaxListLimit, kDefaultListLimit));
}

// An event's sequence number to start after: `after`, else the Last-Event-ID header an
// EventSource sends when it reconnects; nullopt when neither is given.
std::optional<uint64_t> ParseEventCursor(const httplib::Request& request) {
  if (request.has_param("after")) return ParseInteger(request, "after", 0, kMaxEventSeq, 0);
  if (!request.has_header("Last-Event-ID")) return std::nullopt;
  const std::string text = request.get_header_value("Last-Event-ID");
  if (!AllDigits(text) || text.size() > 18) {
    throw ApiError(400, error_code::kInvalidParameter,
                   "Last-Event-ID " + http::ShowValue(text) + " is not an event's seq; expected the id: of an event "
                   "this stream sent");
  }
  return std::stoull(text);
}

struct FrameFile {
  int frame = 0;
  std::string extension;   // "png" or "exr"
  const char* contentType;
};

// "42.png" -> frame 42, png.
FrameFile ParseFrameFile(const std::string& text) {
  const std::string expected = "expected <frame number>.png or <frame number>.exr";
  constexpr size_t kMaxFrameDigits = 9;  // scene frames stay below 10^7 + 10^5
  const size_t dot = text.rfind('.');
  const std::string number = text.substr(0, dot);
  const std::string extension = dot == std::string::npos ? "" : text.substr(dot + 1);
  if (!AllDigits(number) || number.size() > kMaxFrameDigits) {
    throw ApiError(400, error_code::kInvalidParameter,
                   "frame file " + http::ShowValue(text) + " has no frame number; " + expected);
  }
  if (extension == "png") return FrameFile{std::stoi(number), extension, "image/png"};
  if (extension == "exr") return FrameFile{std::stoi(number), extension, "image/x-exr"};
  throw ApiError(400, error_code::kInvalidParameter,
                 "frame file " + http::ShowValue(text) + " has an unknown extension; " + expected);
}

// Streams the file so a 16K float EXR never has to sit in memory whole. The stream stays
// open for the response's lifetime: a frame renamed over it meanwhile is not mixed in.
bool ServeFile(httplib::Response& response, const std::filesystem::path& path, const char* contentType) {
  std::error_code error;
  if (!std::filesystem::is_regular_file(path, error)) return false;
  const uintmax_t size = std::filesystem::file_size(path, error);
  auto file = std::make_shared<std::ifstream>(path, std::ios::binary);
  if (error || !*file) return false;
  response.set_content_provider(
      static_cast<size_t>(size), contentType,
      [file](size_t offset, size_t length, httplib::DataSink& sink) {
        std::vector<char> buffer(std::min(length, kFileChunkBytes));
        file->seekg(static_cast<std::streamoff>(offset));
        file->read(buffer.data(), static_cast<std::streamsize>(buffer.size()));
        const std::streamsize got = file->gcount();
        return got > 0 && sink.write(buffer.data(), static_cast<size_t>(got));
      });
  return true;
}

// For errors the HTTP library answers itself, before any route runs.
ApiError LibraryError(const httplib::Request& request, int status, const ApiError& tooLarge) {
  switch (status) {
    case 413:
      return tooLarge;
    case 501:
      return ApiError(501, error_code::kNotImplemented,
                      "method " + http::ShowValue(request.method) +
                          " is not implemented; expected GET, HEAD, POST, PUT, PATCH, DELETE or OPTIONS");
    case 404:
      return ApiError(404, error_code::kNotFound, "no route for " + request.method + " " + request.path);
    default:
      if (status >= 500) return ApiError(status, error_code::kInternal, "internal server error");
      return ApiError(status, error_code::kBadRequest,
                      "malformed HTTP request (status " + std::to_string(status) + ")");
  }
}

}  // namespace

ApiServer::ApiServer(JobStore& store, FarmControl& farm, std::shared_ptr<prometheus::Registry> metrics,
                     ApiOptions options, StoreJanitor* janitor)
    : store_(store),
      farm_(farm),
      metrics_(std::move(metrics)),
      options_(std::move(options)),
      ownJanitor_(janitor ? nullptr
                          : std::make_unique<StoreJanitor>(
                                store, options_.storeRoot, [&farm](uint64_t id) { return farm.ReleaseJob(id); },
                                metrics_.get())),
      janitor_(janitor ? *janitor : *ownJanitor_),
      frameStore_(options_.storeRoot),
      assetStore_(options_.storeRoot / "assets"),
      events_(store, options_.maxEventStreams) {
  for (const Route& route : Routes()) routePatterns_.emplace_back(route.pattern);
  if (metrics_) {
    assetUploads_ = &NewCounter(*metrics_, "tcfarm_asset_uploads_total",
                                "Asset uploads accepted (hash verified), whether the store had the asset or not.");
    assetUploadBytes_ = &NewCounter(*metrics_, "tcfarm_asset_upload_bytes_total",
                                    "Bytes of the asset uploads accepted.");
    auto& refused = NewCounterFamily(*metrics_, "tcfarm_http_requests_refused_total",
                                     "API requests refused before they ran: no known token (401, "
                                     "reason unauthorized) or a token whose role is too low (403, forbidden).");
    unauthorized_ = &refused.Add({{"reason", "unauthorized"}});
    forbidden_ = &refused.Add({{"reason", "forbidden"}});
  }
}

ApiServer::~ApiServer() { Stop(); }

const std::vector<ApiServer::Route>& ApiServer::Routes() {
  static const std::vector<Route> routes{
      {"POST", "/api/v1/jobs", Access::kSubmit, &ApiServer::SubmitJob},
      {"GET", "/api/v1/jobs", Access::kRead, &ApiServer::ListJobs},
      {"GET", "/api/v1/jobs/([^/]+)", Access::kRead, &ApiServer::GetJob},
      // A submit token may cancel, retry, change and delete its own jobs only: the
      // handlers check whose the job is (CheckMayChange).
      {"POST", "/api/v1/jobs/([^/]+)/cancel", Access::kSubmit, &ApiServer::CancelJob},
      {"POST", "/api/v1/jobs/([^/]+)/retry", Access::kSubmit, &ApiServer::RetryJob},
      {"PATCH", "/api/v1/jobs/([^/]+)", Access::kSubmit, &ApiServer::PatchJob},
      {"DELETE", "/api/v1/jobs/([^/]+)", Access::kSubmit, &ApiServer::DeleteJob},
      {"GET", "/api/v1/jobs/([^/]+)/frames", Access::kRead, &ApiServer::GetFrameStates},
      {"GET", "/api/v1/jobs/([^/]+)/events", Access::kRead, &ApiServer::GetJobEvents},
      {"GET", "/api/v1/events", Access::kRead, &ApiServer::StreamEvents},
      {"GET", "/api/v1/jobs/([^/]+)/frames/([^/]+)", Access::kRead, &ApiServer::GetFrame},
      {"GET", "/api/v1/jobs/([^/]+)/frames/([^/]+)/(mask|change)\\.png", Access::kRead, &ApiServer::GetFrameMask},
      {"PUT", "/api/v1/assets/([^/]+)", Access::kSubmit, nullptr, &ApiServer::PutAsset},
      {"POST", "/api/v1/assets/missing", Access::kSubmit, &ApiServer::FindMissingAssets},
      {"GET", "/api/v1/workers", Access::kRead, &ApiServer::ListWorkers},
      {"DELETE", "/api/v1/workers/distrusted", Access::kAdmin, &ApiServer::LiftWorkerBan},
      {"GET", "/api/v1/strategies", Access::kRead, &ApiServer::ListStrategies},
      // Liveness probes (Kubernetes, compose) carry no token; the answer holds no data.
      {"GET", "/healthz", Access::kOpen, &ApiServer::Health},
      {"GET", "/metrics", Access::kRead, &ApiServer::Metrics},
  };
  return routes;
}

int ApiServer::Start() {
  std::unique_ptr<httplib::Server> server;
  ConnectionGuard* guard = nullptr;
  if (options_.tlsCertFile.empty()) {
    auto plain = std::make_unique<GuardedServer>();
    guard = plain.get();
    server = std::move(plain);
  } else {
    auto tls = std::make_unique<GuardedTlsServer>(options_.tlsCertFile.c_str(), options_.tlsKeyFile.c_str());
    guard = tls.get();
    if (!tls->is_valid()) {
      throw std::runtime_error("TLS: --tls-cert " + options_.tlsCertFile.string() + " and --tls-key " +
                               options_.tlsKeyFile.string() +
                               " are not a PEM certificate and its matching private key");
    }
    server = std::move(tls);
  }
  guard->set_body_limit([this](const httplib::Request& request) { return BodyLimitOf(request); });
  Configure(*server);
  return listener_.Start(std::move(server), options_.host, options_.port);
}

void ApiServer::Stop() {
  events_.Stop();
  listener_.Stop();
}

void ApiServer::Configure(httplib::Server& server) {
  // The library's own limit is the larger of the two; each route keeps to its own (the JSON
  // routes to maxBodyBytes in ReadLimitedBody, asset uploads to assetMaxFileBytes).
  server.set_payload_max_length(
      static_cast<size_t>(std::max<uint64_t>(options_.maxBodyBytes, options_.assetMaxFileBytes)));
  for (const Route& route : Routes()) {
    if (route.stream != nullptr) {
      RegisterStream(server, route.pattern, route.access, route.stream);
    } else {
      Register(server, route.method, route.pattern, route.access, route.handle);
    }
  }
  // Registered last, so they only see what no route matched: answers 405 or 404 in the
  // error shape instead of the library's empty 404.
  for (const char* method : kMethodsWithCatchAll) {
    Register(server, method, ".*", Access::kOpen, &ApiServer::RouteMiss);
  }
  // The library runs this for every status >= 400; a body already there came from a
  // handler and is kept. Replaces the guard's error handler, so does its mapping too.
  server.set_error_handler(httplib::Server::HandlerWithResponse(
      [this](const httplib::Request& request, httplib::Response& response) {
        if (!response.body.empty()) return httplib::Server::HandlerResponse::Unhandled;
        response.status = ConnectionGuard::LibraryStatus(request, response.status);
        WriteError(response, LibraryError(request, response.status, TooLarge(request)));
        return httplib::Server::HandlerResponse::Handled;
      }));
  if (!options_.dashboardDirectory.empty() &&
      !server.set_mount_point("/", options_.dashboardDirectory.string())) {
    throw std::runtime_error("dashboard directory " + options_.dashboardDirectory.string() +
                             " is not a readable folder");
  }
}

uint64_t ApiServer::BodyLimitOf(const httplib::Request& request) const {
  for (size_t i = 0; i < Routes().size(); ++i) {
    if (Routes()[i].stream != nullptr && request.method == Routes()[i].method &&
        std::regex_match(request.path, routePatterns_[i])) {
      return options_.assetMaxFileBytes;
    }
  }
  return options_.maxBodyBytes;
}

ApiError ApiServer::TooLarge(const httplib::Request& request) const {
  const uint64_t limit = BodyLimitOf(request);
  return limit == options_.maxBodyBytes ? PayloadTooLarge(options_.maxBodyBytes) : AssetTooLarge(limit);
}

void ApiServer::Register(httplib::Server& server, const std::string& method, const std::string& pattern,
                         Access access, Handler handle) {
  const httplib::Server::Handler withoutBody = [this, access, handle](const httplib::Request& request,
                                                                      httplib::Response& response) {
    if (Admit(request, access, response)) Dispatch(handle, request, request.body, response);
  };
  if (method == "GET") {
    server.Get(pattern, withoutBody);
  } else if (method == "OPTIONS") {
    server.Options(pattern, withoutBody);
  } else if (TakesBody(method)) {
    // httplib picks the body-reading handler whenever a body comes, the other otherwise.
    const httplib::Server::HandlerWithContentReader withBody =
        [this, access, handle](const httplib::Request& request, httplib::Response& response,
                               const httplib::ContentReader& reader) {
          if (!Admit(request, access, response)) {
            RefuseBody(request);
            return;
          }
          // httplib 0.11.4 reads a POST with neither header until the client closes (or its
          // read timeout), then answers 400; RFC 9112 says such a request has no body.
          if (!request.has_header("Content-Length") && !request.has_header("Transfer-Encoding")) {
            Dispatch(handle, request, std::string(), response);
            return;
          }
          const std::optional<std::string> body = ReadLimitedBody(reader, options_.maxBodyBytes, response);
          if (body) Dispatch(handle, request, *body, response);
        };
    if (method == "POST") {
      server.Post(pattern, withoutBody).Post(pattern, withBody);
    } else if (method == "PUT") {
      server.Put(pattern, withoutBody).Put(pattern, withBody);
    } else if (method == "PATCH") {
      server.Patch(pattern, withoutBody).Patch(pattern, withBody);
    } else {
      server.Delete(pattern, withoutBody).Delete(pattern, withBody);
    }
  } else {
    throw std::logic_error("ApiServer: no way to register method " + method);
  }
}

// Only PUT streams today (asset uploads).
void ApiServer::RegisterStream(httplib::Server& server, const std::string& pattern, Access access,
                               StreamHandler stream) {
  server.Put(pattern, [this, access, stream](const httplib::Request& request, httplib::Response& response) {
    if (!Admit(request, access, response)) return;
    Guard(request, response, [&] { (this->*stream)(request, BodyPieces(), response); });
  });
  server.Put(pattern, [this, access, stream](const httplib::Request& request, httplib::Response& response,
                                             const httplib::ContentReader& reader) {
    if (!Admit(request, access, response)) {
      RefuseBody(request);
      return;
    }
    BodyPieces read;
    // As in Register: neither length header means no body (RFC 9112).
    if (request.has_header("Content-Length") || request.has_header("Transfer-Encoding")) {
      read = [this, &reader](const std::function<void(const char*, size_t)>& piece) {
        uint64_t received = 0;
        return reader([this, &piece, &received](const char* data, size_t length) {
          piece(data, length);
          received += length;
          if (received <= options_.assetMaxFileBytes) return true;
          // Past the limit (a chunked body: the gate refused a Content-Length over it) the
          // answer is 413 whatever follows: stop reading, and close after it.
          CloseAfterResponse();
          return false;
        });
      };
    }
    Guard(request, response, [&] { (this->*stream)(request, read, response); });
  });
}

void ApiServer::Dispatch(Handler handle, const httplib::Request& request, const std::string& body,
                         httplib::Response& response) {
  Guard(request, response, [&] { (this->*handle)(request, body, response); });
}

void ApiServer::Guard(const httplib::Request& request, httplib::Response& response,
                      const std::function<void()>& handle) {
  try {
    handle();
  } catch (const ApiError& error) {
    // RFC 6750: a 401 names the scheme that would get in.
    if (error.status() == 401) response.set_header("WWW-Authenticate", "Bearer realm=\"tcfarm\"");
    WriteError(response, error);
  } catch (const JobStoreFullError& error) {
    // The job database's disk is full: this write is refused whole (no job half
    // submitted), reads go on, and the same request succeeds once there is room.
    WriteError(response, ApiError(507, error_code::kInsufficientStorage,
                                  request.method + " " + request.path +
                                      " could not be stored: the job database's disk is full; nothing was "
                                      "changed, retry once there is room (" + error.what() + ")"));
  } catch (const std::exception& error) {
    // A store failure or a bug: the client gets a 500 in the usual shape, the server goes on.
    std::fprintf(stderr, "coordinator http: %s %s failed: %s\n", request.method.c_str(),
                 request.path.c_str(), error.what());
    WriteError(response, ApiError(500, error_code::kInternal, error.what()));
  }
}

std::optional<http::Caller> ApiServer::CallerOf(const httplib::Request& request) const {
  if (!options_.tokens) return std::nullopt;
  if (!request.has_header("Authorization")) return std::nullopt;
  const std::optional<std::string> header = RawAuthorization();
  const std::optional<std::string> token = header ? http::BearerToken(*header) : std::nullopt;
  if (!token) return std::nullopt;
  return options_.tokens->Find(*token);
}

void ApiServer::Authorize(const httplib::Request& request, Access access) const {
  if (!options_.tokens || access == Access::kOpen) return;
  const std::optional<http::Caller> caller = CallerOf(request);
  if (!caller) {
    if (unauthorized_ != nullptr) unauthorized_->Increment();
    const bool sent = request.has_header("Authorization");
    throw ApiError(401, error_code::kUnauthorized,
                   std::string(sent ? "the Authorization header holds no token this coordinator knows"
                                    : "this coordinator needs an API token") +
                       "; expected the header Authorization: Bearer TOKEN with a token of its --api-tokens file");
  }
  const http::Role needed = access == Access::kRead     ? http::Role::kRead
                            : access == Access::kSubmit ? http::Role::kSubmit
                                                        : http::Role::kAdmin;
  if (caller->role < needed) {
    if (forbidden_ != nullptr) forbidden_->Increment();
    throw ApiError(403, error_code::kForbidden,
                   request.method + " " + request.path + " needs a token of role " + http::RoleName(needed) +
                       " or above; this one (id " + caller->tokenId + ") has role " + http::RoleName(caller->role));
  }
}

bool ApiServer::Admit(const httplib::Request& request, Access access, httplib::Response& response) {
  bool admitted = false;
  Guard(request, response, [&] {
    Authorize(request, access);
    admitted = true;
  });
  return admitted;
}

void ApiServer::CheckMayChange(const httplib::Request& request, uint64_t id) const {
  const std::optional<http::Caller> caller = CallerOf(request);
  if (!caller || caller->role >= http::Role::kAdmin) {
    RequireJob(id);
    return;
  }
  const JobRecord record = LoadJob(id);
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

void ApiServer::RouteMiss(const httplib::Request& request, const std::string&,
                          httplib::Response& response) {
  std::string allowed;
  for (size_t i = 0; i < Routes().size(); ++i) {
    if (!std::regex_match(request.path, routePatterns_[i])) continue;
    const std::string method = Routes()[i].method;
    allowed += (allowed.empty() ? "" : ", ") + method + (method == "GET" ? ", HEAD" : "");
  }
  if (allowed.empty()) {
    throw ApiError(404, error_code::kNotFound, "no route for " + request.method + " " + request.path);
  }
  response.set_header("Allow", allowed);
  if (request.method == "OPTIONS") {
    response.status = 204;
    return;
  }
  throw ApiError(405, error_code::kMethodNotAllowed,
                 request.method + " is not allowed on " + request.path + "; allowed: " + allowed);
}

// The job's memory at its most, alone and one bin at a time, against the farm's memory for
// all running jobs (RequestedJobShape: the most the strategy the farm resolves may need).
// A job that fits waits in the queue until the running jobs leave it room.
void ApiServer::CheckJobFitsInMemory(const JobSpec& spec) const {
  if (options_.farmMemoryBytes == 0) return;
  const JobMemoryShape shape =
      RequestedJobShape(spec.strategy, spec.binWidth, spec.lastFrame - spec.firstFrame + 1, spec.cameraOrLightsChange,
                        spec.frameSize.width, spec.frameSize.height, options_.pendingFrameBytes);
  const std::string shortfall = MemoryShortfall(options_.farmMemoryBytes, shape);
  if (!shortfall.empty()) {
    throw ApiError(413, error_code::kJobTooLarge,
                   shortfall + "; expected fewer pixels a frame, a narrower bin_width or a coordinator with "
                               "more memory",
                   "/scene/render");
  }
}

void ApiServer::SubmitJob(const httplib::Request& request, const std::string& body, httplib::Response& response) {
  // From checking the assets to storing the job that names them, no deletion removes them.
  uint64_t id = 0;
  JobSpec spec;
  {
    const auto holdAssets = janitor_.HoldAssets();
    spec = http::ParseSubmission(
        body, http::SubmissionAssets{&assetStore_, options_.assetMaxJobBytes, "--asset-max-job-mib"});
    CheckJobFitsInMemory(spec);
    // Which token submitted the job, by its id (never the token): a submit token may change
    // only its own jobs.
    if (const std::optional<http::Caller> caller = CallerOf(request)) spec.options["submitted_by"] = caller->tokenId;
    id = store_.Submit(spec);
  }
  {
    std::lock_guard<std::mutex> lock(frameRangesMutex_);
    frameRanges_[id] = FrameRange{spec.firstFrame, spec.lastFrame, JobPreviewView(spec)};
  }
  response.set_header("Location", http::JobPath(id));
  WriteJson(response, JobDetail(LoadJob(id)), 201);
}

void ApiServer::ListJobs(const httplib::Request& request, const std::string&, httplib::Response& response) {
  JobQuery query;
  query.states = ParseStateFilter(request);
  query.strategies = ParseStrategyFilter(request);
  query.nameContains = ParseNameFilter(request);
  query.limit = ParseLimit(request);
  query.offset = ParseInteger(request, "offset", 0, kMaxListOffset, 0);
  const JobPage page = store_.Query(query);
  const std::vector<JobRecord>& records = page.records;
  const bool anyRunning = std::any_of(records.begin(), records.end(), [](const JobRecord& record) {
    return record.state == JobState::kRunning;
  });
  const FarmSnapshot snapshot = anyRunning ? farm_.Snapshot() : FarmSnapshot{};
  json jobs = json::array();
  for (const JobRecord& record : records) {
    const auto live = snapshot.runningStats.find(record.id);
    jobs.push_back(http::JobJson(record, live == snapshot.runningStats.end() ? nullptr : &live->second));
  }
  WriteJson(response,
            json{{"jobs", std::move(jobs)}, {"total", page.total}, {"offset", query.offset}, {"limit", query.limit}});
}

void ApiServer::GetJob(const httplib::Request& request, const std::string&, httplib::Response& response) {
  WriteJson(response, JobDetail(LoadJob(ParseJobId(request.matches[1]))));
}

void ApiServer::CancelJob(const httplib::Request& request, const std::string&,
                          httplib::Response& response) {
  const uint64_t id = ParseJobId(request.matches[1]);
  CheckMayChange(request, id);
  // Cancel first and ask afterwards: checking the state first would race with the farm
  // finishing the job in between.
  if (!store_.Cancel(id)) {
    RefuseTransition(id, error_code::kJobFinished, "already ", "only queued or running jobs can be canceled");
  }
  farm_.RequestCancel(id);
  WriteJson(response, JobDetail(LoadJob(id)));
}

void ApiServer::RefuseTransition(uint64_t id, const char* code, const std::string& already,
                                 const std::string& expected) const {
  throw ApiError(409, code, "job " + std::to_string(id) + " is " + already + ToString(RequireJob(id)) + "; " + expected);
}

void ApiServer::RetryJob(const httplib::Request& request, const std::string&, httplib::Response& response) {
  const uint64_t id = ParseJobId(request.matches[1]);
  CheckMayChange(request, id);
  if (!store_.Retry(id)) RefuseTransition(id, error_code::kJobNotRetryable, "", "only failed or canceled jobs can be retried");
  WriteJson(response, JobDetail(LoadJob(id)));
}

void ApiServer::PatchJob(const httplib::Request& request, const std::string& body, httplib::Response& response) {
  const uint64_t id = ParseJobId(request.matches[1]);
  const JobChange change = http::ParseJobChange(body);
  CheckMayChange(request, id);
  if (!store_.Change(id, change)) RequireJob(id);
  // A running job's next tasks follow it; a queued one is claimed by it from the store.
  if (change.priority) farm_.RequestPriority(id, *change.priority);
  WriteJson(response, JobDetail(LoadJob(id)));
}

void ApiServer::DeleteJob(const httplib::Request& request, const std::string&, httplib::Response& response) {
  const uint64_t id = ParseJobId(request.matches[1]);
  CheckMayChange(request, id);
  StoreJanitor::Deletion deletion;
  try {
    deletion = janitor_.Delete(id, "on request (DELETE)");
  } catch (const FarmStoppingError& e) {
    throw ApiError(503, error_code::kShuttingDown, std::string(e.what()) + "; expected it to be asked again once the coordinator runs");
  }
  switch (deletion.outcome) {
    case DeletedJob::Outcome::kNotFound:
      throw ApiError(404, error_code::kJobNotFound, "no job " + std::to_string(id));
    case DeletedJob::Outcome::kActive:
      throw ApiError(409, error_code::kJobActive,
                     "job " + std::to_string(id) + " is " + ToString(deletion.state) +
                         "; cancel it first (POST /api/v1/jobs/" + std::to_string(id) + "/cancel), then delete it");
    case DeletedJob::Outcome::kDeleted:
      break;
  }
  {
    std::lock_guard<std::mutex> lock(frameRangesMutex_);
    frameRanges_.erase(id);
  }
  WriteJson(response, json{{"deleted", id}, {"freed_bytes", deletion.freedBytes}});
}

// queued, tracing (the farm is working on it), written (in the store, recorded), failed
// (a failed job's frame that was not written). A canceled job's unwritten frames are queued:
// a retry would render them.
void ApiServer::GetFrameStates(const httplib::Request& request, const std::string&, httplib::Response& response) {
  const uint64_t id = ParseJobId(request.matches[1]);
  const FrameRange range = FrameRangeOf(id);
  const JobState state = RequireJob(id);
  const std::vector<RecordedFrame> written = store_.RecordedFrames(id);
  std::vector<int> tracing;
  if (state == JobState::kRunning) {
    FarmSnapshot snapshot = farm_.Snapshot();
    if (auto live = snapshot.tracingFrames.find(id); live != snapshot.tracingFrames.end()) tracing = std::move(live->second);
  }
  json frames = json::array();
  std::map<std::string, int> counts{{"queued", 0}, {"tracing", 0}, {"written", 0}, {"failed", 0}};
  auto nextWritten = written.begin();
  auto nextTracing = tracing.begin();
  for (int frame = range.firstFrame; frame <= range.lastFrame; ++frame) {
    while (nextWritten != written.end() && nextWritten->frame < frame) ++nextWritten;
    while (nextTracing != tracing.end() && *nextTracing < frame) ++nextTracing;
    json entry{{"frame", frame}, {"traced", nullptr}, {"copied", nullptr}};
    std::string frameState = "queued";
    if (nextWritten != written.end() && nextWritten->frame == frame) {
      frameState = "written";
      entry["traced"] = nextWritten->traced;
      entry["copied"] = nextWritten->copied;
    } else if (nextTracing != tracing.end() && *nextTracing == frame) {
      frameState = "tracing";
    } else if (state == JobState::kFailed) {
      frameState = "failed";
    }
    entry["state"] = frameState;
    ++counts[frameState];
    frames.push_back(std::move(entry));
  }
  WriteJson(response, json{{"job", id}, {"state", ToString(state)}, {"frames", std::move(frames)}, {"counts", counts}});
}

void ApiServer::GetJobEvents(const httplib::Request& request, const std::string&, httplib::Response& response) {
  const uint64_t id = ParseJobId(request.matches[1]);
  const uint64_t after = static_cast<uint64_t>(ParseInteger(request, "after", 0, kMaxEventSeq, 0));
  const size_t limit = static_cast<size_t>(ParseInteger(request, "limit", 1, kMaxEventsPerPage, kMaxEventsPerPage));
  RequireJob(id);
  json events = json::array();
  for (const JobEvent& event : store_.Events({id, after, limit})) events.push_back(http::EventJson(event));
  WriteJson(response, json{{"events", std::move(events)}});
}

// Server-Sent Events: each event as "id: <seq>", "event: <type>", "data: <json>", from the
// store's log (after `after` or Last-Event-ID; without either, from now on), then live.
void ApiServer::StreamEvents(const httplib::Request& request, const std::string&, httplib::Response& response) {
  const std::optional<uint64_t> cursor = ParseEventCursor(request);
  RequireAtMostOnce(request, "job");
  const std::optional<uint64_t> job =
      request.has_param("job") ? std::optional<uint64_t>(ParseJobId(request.get_param_value("job"))) : std::nullopt;
  if (job) RequireJob(*job);
  if (!events_.OpenStream()) {
    throw ApiError(503, error_code::kTooManyStreams,
                   std::to_string(options_.maxEventStreams) +
                       " event streams are open, as many as this coordinator serves at once; expected a retry later "
                       "or the per-job events (GET /api/v1/jobs/{id}/events)");
  }
  struct Stream {
    uint64_t after;  // the last event sent (or skipped, before the stream began)
    std::optional<uint64_t> job;
    std::chrono::steady_clock::time_point lastSent;
  };
  auto stream = std::make_shared<Stream>(Stream{cursor ? *cursor : store_.LastEventSeq(), job,
                                                std::chrono::steady_clock::now()});
  response.set_header("Cache-Control", "no-cache");
  response.set_header("X-Accel-Buffering", "no");  // a proxy in front must not hold events back
  response.set_chunked_content_provider(
      "text/event-stream",
      [this, stream](size_t, httplib::DataSink& sink) {
        // Taken before the store is read, so an event recorded meanwhile wakes the wait below.
        const uint64_t heard = events_.Heard();
        std::string text;
        std::vector<JobEvent> events = store_.Events({stream->job, stream->after, kStreamBatch});
        if (events.empty()) {
          const auto now = std::chrono::steady_clock::now();
          const auto keepAlive = stream->lastSent + options_.eventKeepAlive;
          if (now >= keepAlive) {
            text = ": keepalive\n\n";
          } else if (!events_.Await(heard, std::min(keepAlive, now + kStreamPoll))) {
            sink.done();  // the server stops: the stream ends cleanly
            return true;
          }
        }
        for (const JobEvent& event : events) {
          text += "id: " + std::to_string(event.seq) + "\nevent: " + event.type + "\ndata: " +
                  http::DumpJson(http::EventJson(event)) + "\n\n";
          stream->after = event.seq;
        }
        if (text.empty()) return true;  // woken: read the store again
        stream->lastSent = std::chrono::steady_clock::now();
        return sink.write(text.data(), text.size());
      },
      [this](bool) { events_.CloseStream(); });
}

void ApiServer::CheckFrameInJob(uint64_t id, int frame) {
  const FrameRange range = FrameRangeOf(id);
  if (frame < range.firstFrame || frame > range.lastFrame) {
    throw ApiError(400, error_code::kInvalidParameter,
                   "frame " + std::to_string(frame) + " is outside job " + std::to_string(id) +
                       "'s frames [" + std::to_string(range.firstFrame) + ", " +
                       std::to_string(range.lastFrame) + "]");
  }
}

void ApiServer::GetFrame(const httplib::Request& request, const std::string&, httplib::Response& response) {
  const uint64_t id = ParseJobId(request.matches[1]);
  const FrameFile file = ParseFrameFile(request.matches[2]);
  CheckFrameInJob(id, file.frame);
  const std::filesystem::path path = frameStore_.FramePath(id, file.frame, file.extension);
  // A frame's preview is made once its job is done and the farm idle (FrameFinisher);
  // asked for before, it is made now from the frame's EXR.
  std::error_code missing;
  if (file.extension == "png" && !std::filesystem::is_regular_file(path, missing)) {
    std::optional<std::string> preview;
    try {
      preview = EncodePreview(frameStore_, id, file.frame, FrameRangeOf(id).previewView);
    } catch (const FrameIoError& e) {
      throw ApiError(500, error_code::kInternal,
                     "the preview of frame " + std::to_string(file.frame) + " of job " + std::to_string(id) +
                         " could not be made: " + e.what());
    }
    if (preview) {
      response.set_content(std::move(*preview), file.contentType);
      return;
    }
  }
  if (!ServeFile(response, path, file.contentType)) {
    RequireJob(id);  // deleted meanwhile (by the retention: the frame range was cached)
    throw ApiError(404, error_code::kFrameNotReady,
                   "frame " + std::to_string(file.frame) + " of job " + std::to_string(id) +
                       " is not written yet");
  }
}

// frames/<n>/mask.png: the pixels traced at frame n (white) and copied (black);
// frames/<n>/change.png: the pixels equal to frame n - 1's (white) and changed (black).
void ApiServer::GetFrameMask(const httplib::Request& request, const std::string&,
                             httplib::Response& response) {
  const uint64_t id = ParseJobId(request.matches[1]);
  const std::string number = request.matches[2];
  const std::string kind = request.matches[3];
  constexpr size_t kMaxFrameDigits = 9;
  if (!AllDigits(number) || number.size() > kMaxFrameDigits) {
    throw ApiError(400, error_code::kInvalidParameter,
                   "frame " + http::ShowValue(number) + " is not a frame number; expected <frame number>/" + kind +
                       ".png");
  }
  const int frame = std::stoi(number);
  CheckFrameInJob(id, frame);
  // The route's pattern admits only the two names.
  const std::filesystem::path path = frameStore_.MaskPath(id, MaskKindFromName(kind).value(), frame);
  if (!ServeFile(response, path, "image/png")) {
    RequireJob(id);
    throw ApiError(404, error_code::kFrameNotReady,
                   std::string(kind == "mask" ? "the traced-pixel" : "the change") + " mask of frame " +
                       std::to_string(frame) + " of job " +
                       std::to_string(id) + " is not written yet");
  }
}

// The body streams to a temp file, hashed on the way; the asset is stored only when the
// hash is the one in the path. The body is read to its end even when the answer is known
// before (a bad hash), so that the connection stays usable; past the size limit it is not.
void ApiServer::PutAsset(const httplib::Request& request, const BodyPieces& read, httplib::Response& response) {
  const std::string hash = request.matches[1];
  const bool validHash = IsAssetHash(hash);
  std::unique_ptr<AssetStore::Upload> upload;
  std::optional<std::string> writeError;
  if (validHash) {
    try {
      upload = assetStore_.BeginUpload();
    } catch (const std::runtime_error& error) {
      writeError = error.what();  // answered once the body is read
    }
  }
  uint64_t received = 0;
  bool tooLarge = false;
  const bool complete = !read || read([&](const char* data, size_t length) {
    received += length;
    if (received > options_.assetMaxFileBytes) {
      tooLarge = true;
      upload.reset();
    }
    if (!upload) return;
    try {
      upload->Write(std::string_view(data, length));
    } catch (const std::runtime_error& error) {
      writeError = error.what();
      upload.reset();
    }
  });
  // 413 here: the library refused a Content-Length over its limit before reading anything.
  if (tooLarge || response.status == 413) throw AssetTooLarge(options_.assetMaxFileBytes);
  if (!complete) throw ApiError(400, error_code::kBadRequest, "the request body could not be read");
  if (!validHash) {
    throw ApiError(400, error_code::kInvalidParameter,
                   "asset " + http::ShowValue(hash) + " is not a SHA-256; expected 64 lowercase hex characters");
  }
  if (writeError) {
    throw ApiError(507, error_code::kInsufficientStorage, "the store could not take the asset: " + *writeError);
  }
  std::string actual;
  AssetStore::CommitResult result = AssetStore::CommitResult::kHashMismatch;
  try {
    result = assetStore_.Commit(*upload, hash, &actual);
  } catch (const std::runtime_error& error) {
    throw ApiError(507, error_code::kInsufficientStorage,
                   std::string("the store could not take the asset: ") + error.what());
  }
  if (result == AssetStore::CommitResult::kHashMismatch) {
    throw ApiError(400, error_code::kAssetHashMismatch,
                   "the body's SHA-256 is " + actual + ", not " + hash +
                       "; expected the bytes whose SHA-256 the path names");
  }
  if (assetUploads_ != nullptr) {
    assetUploads_->Increment();
    assetUploadBytes_->Increment(static_cast<double>(received));
  }
  WriteJson(response, json{{"sha256", hash}, {"size", received}},
            result == AssetStore::CommitResult::kCreated ? 201 : 200);
}

void ApiServer::FindMissingAssets(const httplib::Request&, const std::string& body, httplib::Response& response) {
  WriteJson(response, json{{"missing", assetStore_.Missing(http::ParseMissingAssetsQuery(body))}});
}

void ApiServer::ListWorkers(const httplib::Request& request, const std::string&, httplib::Response& response) {
  // ?distrusted: the workers banned for returning wrong values instead of those connected.
  if (request.has_param("distrusted")) {
    WriteJson(response, http::BansJson(farm_.Bans()));
    return;
  }
  WriteJson(response, http::WorkersJson(farm_.Snapshot()));
}

void ApiServer::LiftWorkerBan(const httplib::Request& request, const std::string&, httplib::Response& response) {
  // A query parameter, not a path segment: a CURVE key's Z85 text may hold '/' and '?'.
  if (request.get_param_value_count("principal") != 1) {
    throw ApiError(400, error_code::kInvalidParameter,
                   "principal: expected once, as in ?principal=key:<Z85 public key> or ?principal=name:<name>@<address> "
                   "(GET /api/v1/workers?distrusted lists them)");
  }
  const std::string principal = request.get_param_value("principal");
  if (!farm_.LiftBan(principal)) {
    throw ApiError(404, error_code::kBanNotFound, "no worker is banned as " + principal);
  }
  WriteJson(response, json{{"lifted", principal}});
}

void ApiServer::ListStrategies(const httplib::Request&, const std::string&, httplib::Response& response) {
  WriteJson(response, http::StrategiesJson());
}

void ApiServer::Health(const httplib::Request&, const std::string&, httplib::Response& response) {
  WriteJson(response, json{{"status", "ok"}});
}

void ApiServer::Metrics(const httplib::Request&, const std::string&, httplib::Response& response) {
  const std::string text = metrics_ ? prometheus::TextSerializer().Serialize(metrics_->Collect()) : "";
  response.set_content(text, kMetricsType);
}

JobState ApiServer::RequireJob(uint64_t id) const {
  const std::optional<JobState> state = store_.StateOf(id);
  if (!state) throw ApiError(404, error_code::kJobNotFound, "no job " + std::to_string(id));
  return *state;
}

JobRecord ApiServer::LoadJob(uint64_t id) const {
  std::optional<JobRecord> record = store_.Get(id);
  if (!record) throw ApiError(404, error_code::kJobNotFound, "no job " + std::to_string(id));
  return std::move(*record);
}

json ApiServer::JobDetail(const JobRecord& record) {
  if (record.state != JobState::kRunning) return http::JobDetailJson(record, nullptr);
  const FarmSnapshot snapshot = farm_.Snapshot();
  const auto live = snapshot.runningStats.find(record.id);
  return http::JobDetailJson(record, live == snapshot.runningStats.end() ? nullptr : &live->second);
}

ApiServer::FrameRange ApiServer::FrameRangeOf(uint64_t id) {
  {
    std::lock_guard<std::mutex> lock(frameRangesMutex_);
    const auto cached = frameRanges_.find(id);
    if (cached != frameRanges_.end()) return cached->second;
  }
  const JobRecord record = LoadJob(id);
  const FrameRange range{record.spec.firstFrame, record.spec.lastFrame, JobPreviewView(record.spec)};
  std::lock_guard<std::mutex> lock(frameRangesMutex_);
  frameRanges_.emplace(id, range);
  return range;
}

}  // namespace tcfarm
