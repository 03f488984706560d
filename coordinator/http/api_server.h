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
// The routes live in groups, each in its own file with only the stores it needs:
// http/job_routes.h, frame_routes.h, event_routes.h (the Server-Sent Events stream, bounded
// by ApiOptions::maxEventStreams), asset_routes.h, worker_routes.h and service_routes.h
// (strategies, /healthz, /metrics). What they share (a route's shape, the token checks, the
// JSON replies) is http/api_route.h. The server registers every group's routes, checks the
// caller's token before a handler runs, reads the body within its route's limit, and
// answers what no route takes (404, 405, OPTIONS) and every error in the one shape.
#pragma once

#include <chrono>
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <memory>
#include <regex>
#include <string>
#include <vector>

#include "coordinator/farm/farm_control.h"
#include "coordinator/http/api_error.h"
#include "coordinator/http/api_route.h"
#include "coordinator/http/api_tokens.h"
#include "coordinator/http/asset_routes.h"
#include "coordinator/http/event_routes.h"
#include "coordinator/http/frame_routes.h"
#include "coordinator/http/job_routes.h"
#include "coordinator/http/service_routes.h"
#include "coordinator/http/worker_routes.h"
#include "coordinator/jobs/job_store.h"
#include "coordinator/store/asset_store.h"
#include "coordinator/store/store_janitor.h"
#include "proto/net/http_listener.h"
#include "proto/scene/import/import_budget.h"

namespace httplib {
class Server;
struct Request;
struct Response;
}  // namespace httplib

namespace prometheus {
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
  // The memory scene checks and submits import and decode scenes in, all of them at once
  // (--import-budget-mib; proto/scene/import/import_budget.h). Null: each import is bounded
  // only by the importers' per-file limits.
  std::shared_ptr<ImportBudget> importBudget;
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
  void Configure(httplib::Server& server);
  void Register(httplib::Server& server, const std::string& method, const std::string& pattern,
                http::Access access, http::Handler handle);
  void RegisterStream(httplib::Server& server, const std::string& pattern, http::Access access,
                      http::StreamHandler stream);
  // The largest body the request's route takes: an asset upload's or a JSON body's.
  uint64_t BodyLimitOf(const httplib::Request& request) const;
  http::ApiError TooLarge(const httplib::Request& request) const;  // the 413 naming that limit
  // Authorizes the request, answering the error itself: false when the request is refused.
  bool Admit(const httplib::Request& request, http::Access access, httplib::Response& response);
  void RouteMiss(const httplib::Request& request, const std::string& body, httplib::Response& response);

  ApiOptions options_;
  std::shared_ptr<prometheus::Registry> metrics_;
  std::unique_ptr<StoreJanitor> ownJanitor_;  // when none is given
  StoreJanitor& janitor_;
  AssetStore assetStore_;  // options_.storeRoot/assets
  http::FrameRanges frameRanges_;
  // The route groups. Made in this order so that /metrics lists their counters as before.
  http::AssetRoutes assets_;
  http::ApiAuth auth_;
  http::JobRoutes jobs_;
  http::FrameRoutes frames_;
  http::EventRoutes events_;
  http::WorkerRoutes workers_;
  http::ServiceRoutes service_;
  // Every group's routes, in the order the Allow header lists a path's methods.
  std::vector<http::Route> routes_;
  std::vector<std::regex> routePatterns_;  // routes_ compiled once, for 405 vs 404

  HttpListener listener_;
};

}  // namespace tcfarm
