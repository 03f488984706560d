#include "coordinator/http/event_routes.h"

#include <httplib.h>

#include <algorithm>
#include <memory>
#include <optional>
#include <utility>

#include "coordinator/http/job_json.h"
#include "coordinator/http/query_params.h"

namespace tcfarm::http {
namespace {

using nlohmann::json;

// A job's events in one answer: every event of all but the longest jobs (a frames_written
// event covers ten frames or a second); `after` pages through the rest.
constexpr int64_t kMaxEventsPerPage = 10000;
constexpr int64_t kMaxEventSeq = int64_t{1} << 53;
// Events read from the store at once while a stream catches up.
constexpr size_t kStreamBatch = 500;
// A stream looks at the store at least this often: another process may record events its
// listener never hears, and Stop is seen this soon.
constexpr std::chrono::milliseconds kStreamPoll{1000};

// An event's sequence number to start after: `after`, else the Last-Event-ID header an
// EventSource sends when it reconnects; nullopt when neither is given.
std::optional<uint64_t> ParseEventCursor(const httplib::Request& request) {
  if (request.has_param("after")) return ParseInteger(request, "after", 0, kMaxEventSeq, 0);
  if (!request.has_header("Last-Event-ID")) return std::nullopt;
  const std::string text = request.get_header_value("Last-Event-ID");
  if (!AllDigits(text) || text.size() > 18) {
    throw ApiError(400, error_code::kInvalidParameter,
                   "Last-Event-ID " + ShowValue(text) + " is not an event's seq; expected the id: of an event "
                   "this stream sent");
  }
  return std::stoull(text);
}

}  // namespace

EventRoutes::EventRoutes(JobStore& store, size_t maxStreams, std::chrono::milliseconds keepAlive)
    : store_(store), keepAlive_(keepAlive), bell_(store, maxStreams) {}

std::vector<Route> EventRoutes::Routes() {
  return {
      {"GET", "/api/v1/jobs/([^/]+)/events", Access::kRead, Bind(this, &EventRoutes::GetJobEvents)},
      {"GET", "/api/v1/events", Access::kRead, Bind(this, &EventRoutes::StreamEvents)},
  };
}

void EventRoutes::GetJobEvents(const httplib::Request& request, const std::string&, httplib::Response& response) {
  const uint64_t id = ParseJobId(request.matches[1]);
  const uint64_t after = static_cast<uint64_t>(ParseInteger(request, "after", 0, kMaxEventSeq, 0));
  const size_t limit = static_cast<size_t>(ParseInteger(request, "limit", 1, kMaxEventsPerPage, kMaxEventsPerPage));
  RequireJob(store_, id);
  json events = json::array();
  for (const JobEvent& event : store_.Events({id, after, limit})) events.push_back(EventJson(event));
  WriteJson(response, json{{"events", std::move(events)}});
}

// Server-Sent Events: each event as "id: <seq>", "event: <type>", "data: <json>", from the
// store's log (after `after` or Last-Event-ID; without either, from now on), then live.
void EventRoutes::StreamEvents(const httplib::Request& request, const std::string&, httplib::Response& response) {
  const std::optional<uint64_t> cursor = ParseEventCursor(request);
  RequireAtMostOnce(request, "job");
  const std::optional<uint64_t> job =
      request.has_param("job") ? std::optional<uint64_t>(ParseJobId(request.get_param_value("job"))) : std::nullopt;
  if (job) RequireJob(store_, *job);
  if (!bell_.OpenStream()) {
    throw ApiError(503, error_code::kTooManyStreams,
                   std::to_string(bell_.maxStreams()) +
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
        const uint64_t heard = bell_.Heard();
        std::string text;
        std::vector<JobEvent> events = store_.Events({stream->job, stream->after, kStreamBatch});
        if (events.empty()) {
          const auto now = std::chrono::steady_clock::now();
          const auto keepAlive = stream->lastSent + keepAlive_;
          if (now >= keepAlive) {
            text = ": keepalive\n\n";
          } else if (!bell_.Await(heard, std::min(keepAlive, now + kStreamPoll))) {
            sink.done();  // the server stops: the stream ends cleanly
            return true;
          }
        }
        for (const JobEvent& event : events) {
          text += "id: " + std::to_string(event.seq) + "\nevent: " + event.type + "\ndata: " +
                  DumpJson(EventJson(event)) + "\n\n";
          stream->after = event.seq;
        }
        if (text.empty()) return true;  // woken: read the store again
        stream->lastSent = std::chrono::steady_clock::now();
        return sink.write(text.data(), text.size());
      },
      [this](bool) { bell_.CloseStream(); });
}

}  // namespace tcfarm::http
