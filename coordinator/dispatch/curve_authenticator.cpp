#include "coordinator/dispatch/curve_authenticator.h"

#include <algorithm>
#include <cstdio>
#include <stdexcept>

#include "proto/curve/curve_keys.h"
#include "proto/curve/socket_events.h"

namespace tcfarm {
namespace {

// RFC 27: the fixed endpoint libzmq asks, and the version it speaks.
constexpr const char* kZapEndpoint = "inproc://zeromq.zap.01";
const std::string kZapVersion = "1.0";
// Bounds how long stopping waits for the thread.
constexpr std::chrono::milliseconds kPollTimeout{100};
constexpr std::chrono::seconds kLogInterval{1};

std::string Z85Of(const std::string& binaryKey) {
  if (binaryKey.size() != 32) return "";
  char text[curve::kKeyTextLength + 1] = {};
  zmq_z85_encode(text, reinterpret_cast<const uint8_t*>(binaryKey.data()), binaryKey.size());
  return text;
}

}  // namespace

CurveAuthenticator::CurveAuthenticator(zmq::context_t& context, const CurveServerKeys& keys,
                                       std::string monitorEndpoint)
    : directory_(keys.workerKeysDirectory), alsoAllowed_(keys.alsoAllowed) {
  // Throws for a folder that cannot be read: better no coordinator than one nobody reaches.
  listing_ = Listing();
  allowed_ = curve::ReadPublicKeys(directory_);
  zmq::socket_t zap(context, zmq::socket_type::rep);
  zap.set(zmq::sockopt::linger, 0);
  zap.bind(kZapEndpoint);
  zmq::socket_t monitor(context, zmq::socket_type::pair);
  monitor.set(zmq::sockopt::linger, 0);
  monitor.connect(monitorEndpoint);
  // The sockets move to the thread once; only it uses them from then on.
  thread_ = std::thread([this, zap = std::move(zap), monitor = std::move(monitor)]() mutable {
    Run(std::move(zap), std::move(monitor));
  });
}

CurveAuthenticator::~CurveAuthenticator() {
  stop_ = true;
  if (thread_.joinable()) thread_.join();
}

void CurveAuthenticator::Run(zmq::socket_t zap, zmq::socket_t monitor) {
  while (!stop_) {
    zmq::pollitem_t items[] = {{static_cast<void*>(zap), 0, ZMQ_POLLIN, 0},
                               {static_cast<void*>(monitor), 0, ZMQ_POLLIN, 0}};
    try {
      zmq::poll(items, 2, kPollTimeout);
      if (items[0].revents & ZMQ_POLLIN) AnswerZapRequest(zap);
      if (items[1].revents & ZMQ_POLLIN) ReadMonitorEvent(monitor);
    } catch (const zmq::error_t& e) {
      if (e.num() == ETERM) return;
      if (e.num() != EINTR) std::fprintf(stderr, "coordinator: authenticator: %s\n", e.what());
    }
  }
}

// Request frames (RFC 27): version, request id, domain, address, identity, mechanism,
// credentials (for CURVE, the client's 32-byte public key). The reply: version, request id,
// status code, status text, user id, metadata.
void CurveAuthenticator::AnswerZapRequest(zmq::socket_t& zap) {
  std::vector<std::string> frames;
  zmq::message_t frame;
  do {
    if (!zap.recv(frame)) return;
    frames.push_back(frame.to_string());
  } while (frame.more());
  const std::string requestId = frames.size() > 1 ? frames[1] : "";
  const bool wellFormed = frames.size() == 7 && frames[0] == kZapVersion && frames[5] == "CURVE";
  const std::string key = wellFormed ? Z85Of(frames[6]) : "";
  const bool allowed = !key.empty() && IsAllowed(key);
  if (!allowed) {
    ++refusedKeys_;
    LogRateLimited(LogKind::kKeyRefused, key.empty() ? "refused a client that presented no CURVE key"
                               : "refused worker key " + key + " from " + frames[3] + ": not in " +
                                     directory_.string());
  }
  const std::vector<std::string> reply = {kZapVersion, requestId, allowed ? "200" : "400",
                                          allowed ? "OK" : "key not allowed", allowed ? key : "", ""};
  for (size_t i = 0; i < reply.size(); ++i) {
    zap.send(zmq::buffer(reply[i]), i + 1 < reply.size() ? zmq::send_flags::sndmore : zmq::send_flags::none);
  }
}

void CurveAuthenticator::ReadMonitorEvent(zmq::socket_t& monitor) {
  while (auto event = curve::ReadSocketEvent(monitor)) {
    // A refusal by ZAP is counted where it is decided, with its key.
    if (event->event == ZMQ_EVENT_HANDSHAKE_FAILED_AUTH) continue;
    if (!(event->event & curve::kHandshakeFailureEvents)) continue;
    ++failedHandshakes_;
    LogRateLimited(LogKind::kHandshakeFailed, "refused a connection: " + curve::DescribeHandshakeFailure(*event));
  }
}

bool CurveAuthenticator::IsAllowed(const std::string& publicKey) {
  if (alsoAllowed_.count(publicKey)) return true;
  ReloadIfChanged();
  return allowed_.count(publicKey) > 0;
}

std::vector<CurveAuthenticator::ListingEntry> CurveAuthenticator::Listing() const {
  std::vector<ListingEntry> listing;
  std::error_code ec;
  std::filesystem::directory_iterator entries(directory_, ec);
  if (ec) throw std::invalid_argument("--worker-keys " + directory_.string() + ": cannot list: " + ec.message());
  for (const auto& entry : entries) {
    if (entry.path().extension() != ".pub") continue;
    std::error_code statError;
    ListingEntry item{entry.path().filename().string(), entry.last_write_time(statError),
                      entry.file_size(statError)};
    listing.push_back(std::move(item));
  }
  std::sort(listing.begin(), listing.end(),
            [](const ListingEntry& a, const ListingEntry& b) { return a.name < b.name; });
  return listing;
}

// A handshake is rare next to the messages that follow it, so the folder is listed at
// each one; the files are read again only when the listing differs.
void CurveAuthenticator::ReloadIfChanged() {
  std::vector<ListingEntry> listing;
  try {
    listing = Listing();
  } catch (const std::invalid_argument& e) {
    LogRateLimited(LogKind::kFolderUnreadable, std::string("cannot read the worker keys again: ") + e.what() + "; the keys read before still hold");
    return;
  }
  if (listing == listing_) return;
  std::map<std::string, std::string> skipped;
  allowed_ = curve::ReadPublicKeys(directory_, &skipped);
  listing_ = std::move(listing);
  std::fprintf(stderr, "coordinator: %zu worker keys allowed from %s\n", allowed_.size(), directory_.c_str());
  for (const auto& [file, why] : skipped) std::fprintf(stderr, "coordinator: skipped %s\n", why.c_str());
}

void CurveAuthenticator::LogRateLimited(LogKind kind, const std::string& line) {
  LogLimit& limit = logLimits_[static_cast<size_t>(kind)];
  const auto now = std::chrono::steady_clock::now();
  if (limit.last != std::chrono::steady_clock::time_point{} && now - limit.last < kLogInterval) {
    ++limit.unlogged;
    return;
  }
  limit.last = now;
  std::fprintf(stderr, "coordinator: %s", line.c_str());
  if (limit.unlogged > 0) {
    std::fprintf(stderr, " (and %llu lines like it not logged)", static_cast<unsigned long long>(limit.unlogged));
  }
  std::fprintf(stderr, "\n");
  limit.unlogged = 0;
}

}  // namespace tcfarm
