// The coordinator's HTTP API (/api/v1), plus /healthz and /metrics. proto/openapi.yaml
// is its contract: routes, bodies, status codes, and the one error shape
// {"error": {"status", "code", "message", "pointer"?}} that every failure answers with,
// including the ones the HTTP library produces itself (unknown route, body too large).
//
// With tokens (ApiOptions::tokens) every route but /healthz and the dashboard's static
// files needs "Authorization: Bearer TOKEN" of a role high enough: 401 without a known
// token, 403 with one whose role is too low (http/api_tokens.h). The token is read from
// the Authorization header byte for byte, as sent. Refused requests never have their
// bodies read: the connection closes after the answer. Every request passes the server's
// gate first (net/guarded_server.h): a body over its route's limit is refused with 413
// before any of it is read, whatever the method, and a method the server does not route
// gets 501.
//
// The server only reads and writes the JobStore and asks the FarmControl for cancels,
// priority changes and snapshots; it never touches the farm's state directly, so a slow
// client cannot stall rendering. Jobs are deleted through the StoreJanitor, by the same
// code as the retention.
//
// GET /api/v1/events is a stream (Server-Sent Events) that stays open: each holds one of
// the server's threads, so their number is bounded (ApiOptions::maxEventStreams, 503
// beyond it), and each wakes at least once a second, so Stop never waits for a client.
#pragma once

#include <chrono>
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <memory>
#include <mutex>
#include <regex>
#include <string>
#include <unordered_map>
#include <vector>

#include "coordinator/farm/farm_control.h"
#include "coordinator/http/api_error.h"
#include "coordinator/http/api_tokens.h"
#include "coordinator/http/event_bell.h"
#include "coordinator/http/job_json.h"
#include "coordinator/http/submit_request.h"
#include "proto/frame/view_transform.h"
#include "proto/net/http_listener.h"
#include "coordinator/jobs/job_store.h"
#include "coordinator/store/asset_store.h"
#include "coordinator/store/frame_store.h"
#include "coordinator/store/store_janitor.h"

namespace httplib {
class Server;
struct Request;
struct Response;
}  // namespace httplib

namespace prometheus {
class Counter;
class Registry;
}  // namespace prometheus

namespace tcfarm {

struct ApiOptions {
  std::string host = "0.0.0.0";
  int port = 8080;  // 0: any free port (Start returns it)
  // Submissions carry whole scenes with inline meshes; above this the body is refused
  // with 413 before it is read into memory.
  size_t maxBodyBytes = 64u << 20;
  std::filesystem::path storeRoot = "store";  // frames: storeRoot/<job id>/frame_NNNN.{exr,png}
                                              // assets: storeRoot/assets/<sha256>
  std::filesystem::path dashboardDirectory;   // static files served at / when set
  // The coordinator's memory for all running jobs (0: no limit): a job that would need
  // more even alone and one bin at a time is refused at submit with 413 job_too_large.
  uint64_t farmMemoryBytes = 0;
  // Each job's memory for frames ahead of their turn, part of what it needs.
  uint64_t pendingFrameBytes = 0;
  // One uploaded asset (PUT /api/v1/assets/{sha256}), streamed to disk, never held whole;
  // larger is refused with 413 (--asset-max-file-mib).
  uint64_t assetMaxFileBytes = uint64_t{512} << 20;
  // All the assets one submission names together (--asset-max-job-mib); 0: no limit.
  uint64_t assetMaxJobBytes = uint64_t{2048} << 20;
  // Who may do what (--api-tokens). Null: every request is allowed, for a coordinator on
  // loopback or one started with --insecure-no-auth.
  std::shared_ptr<const http::ApiTokens> tokens;
  // Both set: HTTPS with this certificate chain and private key (PEM files).
  std::filesystem::path tlsCertFile;
  std::filesystem::path tlsKeyFile;
  // Event streams (GET /api/v1/events) open at once; more are refused with 503. Each holds
  // a thread of the server for as long as it is open.
  size_t maxEventStreams = 32;
  // A stream with nothing to say sends a comment this often, so proxies and clients know
  // it is alive (and the server learns when a client has gone).
  std::chrono::milliseconds eventKeepAlive{15000};
};

class ApiServer {
 public:
  // janitor: deletes jobs (shared with the retention); none: the server keeps its own,
  // without retention.
  ApiServer(JobStore& store, FarmControl& farm, std::shared_ptr<prometheus::Registry> metrics,
            ApiOptions options, StoreJanitor* janitor = nullptr);
  ~ApiServer();  // stops
  ApiServer(const ApiServer&) = delete;
  ApiServer& operator=(const ApiServer&) = delete;

  // Binds and serves on a background thread; returns the bound port. Throws
  // std::runtime_error "cannot listen on host:port" when the address is taken or invalid,
  // or naming the TLS files when they do not make a certificate and its key.
  int Start();
  // Stops accepting, finishes the requests in progress and joins the server thread.
  // Safe to call twice or without Start.
  void Stop();

 private:
  // body: the request body, read by the server within options_.maxBodyBytes (httplib's
  // Request::body stays empty for bodies read that way).
  using Handler = void (ApiServer::*)(const httplib::Request& request, const std::string& body,
                                      httplib::Response& response);
  // For a body too large to hold in memory (asset uploads): the handler reads it from
  // `read` as it arrives. `read` calls its argument per piece, false when the body could not
  // be read whole; a request without a body has none.
  using BodyPieces = std::function<bool(const std::function<void(const char* data, size_t length)>&)>;
  using StreamHandler = void (ApiServer::*)(const httplib::Request& request, const BodyPieces& read,
                                            httplib::Response& response);
  // The least a caller needs for a route when the server has tokens.
  enum class Access { kOpen, kRead, kSubmit, kAdmin };
  struct Route {
    const char* method;
    const char* pattern;  // a regex on the decoded path; groups are the path parameters
    Access access;
    Handler handle;
    StreamHandler stream = nullptr;  // instead of handle, for routes that stream their body
  };
  // A job's frames, which never change once it is submitted.
  struct FrameRange {
    int firstFrame = 0;
    int lastFrame = 0;
    ViewTransform previewView;  // how a preview made on request shows the frames
  };

  static const std::vector<Route>& Routes();
  void Configure(httplib::Server& server);
  void Register(httplib::Server& server, const std::string& method, const std::string& pattern,
                Access access, Handler handle);
  void RegisterStream(httplib::Server& server, const std::string& pattern, Access access, StreamHandler stream);
  // The largest body the request's route takes: an asset upload's or a JSON body's.
  uint64_t BodyLimitOf(const httplib::Request& request) const;
  http::ApiError TooLarge(const httplib::Request& request) const;  // the 413 naming that limit
  // Throws ApiError 401 (no known token) or 403 (a role too low). Without tokens, allows all.
  void Authorize(const httplib::Request& request, Access access) const;
  // Authorize, answering the error itself: false when the request is refused.
  bool Admit(const httplib::Request& request, Access access, httplib::Response& response);
  // The token's owner; nullopt when the server has no tokens.
  std::optional<http::Caller> CallerOf(const httplib::Request& request) const;
  // A submit token cancels, retries, changes and deletes only the jobs it submitted;
  // throws 403 for another's (404 for an unknown job).
  void CheckMayChange(const httplib::Request& request, uint64_t id) const;
  void Dispatch(Handler handle, const httplib::Request& request, const std::string& body,
                httplib::Response& response);
  // Runs a handler, turning what it throws into the one error shape.
  void Guard(const httplib::Request& request, httplib::Response& response, const std::function<void()>& handle);
  void RouteMiss(const httplib::Request& request, const std::string& body, httplib::Response& response);

  void SubmitJob(const httplib::Request& request, const std::string& body, httplib::Response& response);
  void CheckJobFitsInMemory(const JobSpec& spec) const;
  void ListJobs(const httplib::Request& request, const std::string& body, httplib::Response& response);
  void GetJob(const httplib::Request& request, const std::string& body, httplib::Response& response);
  void CancelJob(const httplib::Request& request, const std::string& body, httplib::Response& response);
  void RetryJob(const httplib::Request& request, const std::string& body, httplib::Response& response);
  void PatchJob(const httplib::Request& request, const std::string& body, httplib::Response& response);
  void DeleteJob(const httplib::Request& request, const std::string& body, httplib::Response& response);
  void GetFrameStates(const httplib::Request& request, const std::string& body, httplib::Response& response);
  void GetJobEvents(const httplib::Request& request, const std::string& body, httplib::Response& response);
  void StreamEvents(const httplib::Request& request, const std::string& body, httplib::Response& response);
  void GetFrame(const httplib::Request& request, const std::string& body, httplib::Response& response);
  void GetFrameMask(const httplib::Request& request, const std::string& body, httplib::Response& response);
  void PutAsset(const httplib::Request& request, const BodyPieces& read, httplib::Response& response);
  void FindMissingAssets(const httplib::Request& request, const std::string& body, httplib::Response& response);
  void ListWorkers(const httplib::Request& request, const std::string& body, httplib::Response& response);
  void LiftWorkerBan(const httplib::Request& request, const std::string& body, httplib::Response& response);
  void ListStrategies(const httplib::Request& request, const std::string& body, httplib::Response& response);
  void Health(const httplib::Request& request, const std::string& body, httplib::Response& response);
  void Metrics(const httplib::Request& request, const std::string& body, httplib::Response& response);

  JobRecord LoadJob(uint64_t id) const;  // throws ApiError 404 job_not_found
  JobState RequireJob(uint64_t id) const;  // the job's state, without loading it; 404 the same
  // A transition the store refused: throws 409 `code` saying the job's state ("is <already>
  // canceled; <expected>"), or 404 when the job is gone.
  [[noreturn]] void RefuseTransition(uint64_t id, const char* code, const std::string& already,
                                     const std::string& expected) const;
  // Throws 400 invalid_parameter when frame is outside job id's frames.
  void CheckFrameInJob(uint64_t id, int frame);
  nlohmann::json JobDetail(const JobRecord& record);
  // Cached per job, so that serving a frame does not load the job's scene and per-frame
  // counts each time.
  FrameRange FrameRangeOf(uint64_t id);

  JobStore& store_;
  FarmControl& farm_;
  std::shared_ptr<prometheus::Registry> metrics_;
  ApiOptions options_;
  std::unique_ptr<StoreJanitor> ownJanitor_;  // when none is given
  StoreJanitor& janitor_;
  FrameStore frameStore_;  // where options_.storeRoot holds each job's files
  AssetStore assetStore_;  // options_.storeRoot/assets
  prometheus::Counter* assetUploads_ = nullptr;      // with a metrics registry only
  prometheus::Counter* assetUploadBytes_ = nullptr;
  prometheus::Counter* unauthorized_ = nullptr;  // 401s
  prometheus::Counter* forbidden_ = nullptr;     // 403s
  std::vector<std::regex> routePatterns_;  // Routes() compiled once, for 405 vs 404

  std::mutex frameRangesMutex_;
  std::unordered_map<uint64_t, FrameRange> frameRanges_;

  http::EventBell events_;  // what event streams wait on; stopped by Stop

  HttpListener listener_;
};

}  // namespace tcfarm
