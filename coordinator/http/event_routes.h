// The HTTP API's events: a job's event log, and the stream of every job's events.
//   GET /api/v1/jobs/{id}/events   a page of one job's events (?after, ?limit)
//   GET /api/v1/events             Server-Sent Events, all jobs or ?job=, from ?after or
//                                  Last-Event-ID, else from now on
// A stream stays open: each holds one of the server's threads, so their number is bounded
// (maxStreams, 503 beyond it), and each wakes at least once a second, so Stop never waits
// for a client.
#pragma once

#include <chrono>
#include <cstddef>
#include <string>
#include <vector>

#include "coordinator/http/api_route.h"
#include "coordinator/http/event_bell.h"
#include "coordinator/jobs/job_store.h"

namespace tcfarm::http {

class EventRoutes {
 public:
  // keepAlive: a stream with nothing to say sends a comment this often.
  EventRoutes(JobStore& store, size_t maxStreams, std::chrono::milliseconds keepAlive);

  std::vector<Route> Routes();
  // Ends every open stream cleanly; the server is stopping. Safe to call twice.
  void Stop() { bell_.Stop(); }

 private:
  void GetJobEvents(const httplib::Request& request, const std::string& body, httplib::Response& response);
  void StreamEvents(const httplib::Request& request, const std::string& body, httplib::Response& response);

  JobStore& store_;
  std::chrono::milliseconds keepAlive_;
  EventBell bell_;  // what the streams wait on
};

}  // namespace tcfarm::http
