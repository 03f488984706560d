#include "coordinator/http/api_server.h"

#include <httplib.h>

#include <algorithm>
#include <cstdio>
#include <optional>
#include <stdexcept>
#include <utility>

#include "coordinator/http/api_error.h"
#include "proto/net/guarded_server.h"

namespace tcfarm {
namespace {

using http::Access;
using http::ApiError;
using http::Route;
using http::WriteError;
namespace error_code = http::error_code;

constexpr const char* kMethodsWithCatchAll[] = {"GET", "POST", "PUT", "PATCH", "DELETE", "OPTIONS"};

ApiError PayloadTooLarge(size_t maxBytes) {
  return ApiError(413, error_code::kPayloadTooLarge,
                  "request body is larger than the limit of " + std::to_string(maxBytes) + " bytes");
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

// Runs a handler, turning what it throws into the one error shape.
void Guard(const httplib::Request& request, httplib::Response& response, const std::function<void()>& handle) {
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

}  // namespace

ApiServer::ApiServer(JobStore& store, FarmControl& farm, std::shared_ptr<prometheus::Registry> metrics,
                     ApiOptions options, StoreJanitor* janitor)
    : options_(std::move(options)),
      metrics_(std::move(metrics)),
      ownJanitor_(janitor ? nullptr
                          : std::make_unique<StoreJanitor>(
                                store, options_.storeRoot, [&farm](uint64_t id) { return farm.ReleaseJob(id); },
                                metrics_.get())),
      janitor_(janitor ? *janitor : *ownJanitor_),
      assetStore_(options_.storeRoot / "assets"),
      frameRanges_(store),
      assets_(assetStore_, options_.assetMaxFileBytes, metrics_.get()),
      auth_(options_.tokens, metrics_.get()),
      jobs_(store, farm, janitor_, assetStore_, frameRanges_, auth_,
            http::JobLimits{options_.farmMemoryBytes, options_.pendingFrameBytes, options_.assetMaxJobBytes,
                            options_.importBudget.get()},
            metrics_.get()),
      frames_(store, farm, frameRanges_, options_.storeRoot),
      events_(store, options_.maxEventStreams, options_.eventKeepAlive),
      workers_(farm),
      service_(metrics_) {
  for (const std::vector<Route>& group : {jobs_.Routes(), frames_.Routes(), events_.Routes(), assets_.Routes(),
                                          workers_.Routes(), service_.Routes()}) {
    routes_.insert(routes_.end(), group.begin(), group.end());
  }
  for (const Route& route : routes_) routePatterns_.emplace_back(route.pattern);
}

ApiServer::~ApiServer() { Stop(); }

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
  for (const Route& route : routes_) {
    if (route.stream != nullptr) {
      RegisterStream(server, route.pattern, route.access, route.stream);
    } else {
      Register(server, route.method, route.pattern, route.access, route.handle);
    }
  }
  // Registered last, so they only see what no route matched: answers 405 or 404 in the
  // error shape instead of the library's empty 404.
  for (const char* method : kMethodsWithCatchAll) {
    Register(server, method, ".*", Access::kOpen,
             [this](const httplib::Request& request, const std::string& body, httplib::Response& response) {
               RouteMiss(request, body, response);
             });
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
  for (size_t i = 0; i < routes_.size(); ++i) {
    if (routes_[i].stream != nullptr && request.method == routes_[i].method &&
        std::regex_match(request.path, routePatterns_[i])) {
      return options_.assetMaxFileBytes;
    }
  }
  return options_.maxBodyBytes;
}

ApiError ApiServer::TooLarge(const httplib::Request& request) const {
  const uint64_t limit = BodyLimitOf(request);
  return limit == options_.maxBodyBytes ? PayloadTooLarge(options_.maxBodyBytes) : http::AssetTooLarge(limit);
}

void ApiServer::Register(httplib::Server& server, const std::string& method, const std::string& pattern,
                         Access access, http::Handler handle) {
  const httplib::Server::Handler withoutBody = [this, access, handle](const httplib::Request& request,
                                                                      httplib::Response& response) {
    if (!Admit(request, access, response)) return;
    Guard(request, response, [&] { handle(request, request.body, response); });
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
            Guard(request, response, [&] { handle(request, std::string(), response); });
            return;
          }
          const std::optional<std::string> body = ReadLimitedBody(reader, options_.maxBodyBytes, response);
          if (body) Guard(request, response, [&] { handle(request, *body, response); });
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
                               http::StreamHandler stream) {
  server.Put(pattern, [this, access, stream](const httplib::Request& request, httplib::Response& response) {
    if (!Admit(request, access, response)) return;
    Guard(request, response, [&] { stream(request, http::BodyPieces(), response); });
  });
  server.Put(pattern, [this, access, stream](const httplib::Request& request, httplib::Response& response,
                                             const httplib::ContentReader& reader) {
    if (!Admit(request, access, response)) {
      RefuseBody(request);
      return;
    }
    http::BodyPieces read;
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
    Guard(request, response, [&] { stream(request, read, response); });
  });
}

bool ApiServer::Admit(const httplib::Request& request, Access access, httplib::Response& response) {
  bool admitted = false;
  Guard(request, response, [&] {
    auth_.Authorize(request, access);
    admitted = true;
  });
  return admitted;
}

void ApiServer::RouteMiss(const httplib::Request& request, const std::string&,
                          httplib::Response& response) {
  std::string allowed;
  for (size_t i = 0; i < routes_.size(); ++i) {
    if (!std::regex_match(request.path, routePatterns_[i])) continue;
    const std::string method = routes_[i].method;
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

}  // namespace tcfarm
