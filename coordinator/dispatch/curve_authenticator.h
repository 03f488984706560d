// The coordinator's gatekeeper for CurveZMQ (zguide's Ironhouse): a ZAP handler (RFC 27)
// that lets in only CURVE clients whose public key is on the allow-list, and a reader of
// the ROUTER's monitor events that sees the connections refused before ZAP is asked (a
// client without keys, or one that has the wrong server key).
//
// The allow-list is every `*.pub` file of a folder (proto/curve/curve_keys.h), read again
// when the folder's listing changes, so adding a worker needs no restart; keys given in
// memory (the coordinator's own local workers) are always allowed.
//
// One thread owns both sockets (ZAP's REP and the monitor's PAIR) and polls them with a
// finite timeout; the farm loop only reads the counters.
#pragma once

#include <atomic>
#include <chrono>
#include <cstdint>
#include <filesystem>
#include <map>
#include <set>
#include <string>
#include <thread>
#include <vector>

#include <zmq.hpp>

namespace tcfarm {

struct CurveServerKeys {
  std::string secretKey;  // the coordinator's, Z85
  std::filesystem::path workerKeysDirectory;
  std::set<std::string> alsoAllowed;  // Z85 public keys allowed besides the folder's
};

class CurveAuthenticator {
 public:
  // Reads the allow-list once (throws std::invalid_argument when the folder cannot be
  // listed), then serves ZAP on inproc://zeromq.zap.01 of `context` and reads the monitor
  // events published at monitorEndpoint. Returns once both sockets are ready, so that a
  // ROUTER bound afterwards never meets a client unchecked.
  CurveAuthenticator(zmq::context_t& context, const CurveServerKeys& keys, std::string monitorEndpoint);
  ~CurveAuthenticator();  // stops the thread (within one poll timeout)
  CurveAuthenticator(const CurveAuthenticator&) = delete;
  CurveAuthenticator& operator=(const CurveAuthenticator&) = delete;

  // Clients whose key is not on the allow-list (ZAP said 400).
  uint64_t RefusedKeys() const { return refusedKeys_.load(); }
  // Connections whose handshake failed before ZAP: no CURVE, wrong server key, garbage.
  uint64_t FailedHandshakes() const { return failedHandshakes_.load(); }

 private:
  struct ListingEntry {
    std::string name;
    std::filesystem::file_time_type modified;
    std::uintmax_t size;
    bool operator==(const ListingEntry& other) const {
      return name == other.name && modified == other.modified && size == other.size;
    }
  };

  void Run(zmq::socket_t zap, zmq::socket_t monitor);
  void AnswerZapRequest(zmq::socket_t& zap);
  void ReadMonitorEvent(zmq::socket_t& monitor);
  bool IsAllowed(const std::string& publicKey);
  void ReloadIfChanged();
  std::vector<ListingEntry> Listing() const;
  // At most one line a second of each kind: a rogue that reconnects in a loop must not
  // flood the log, nor hide the refusals of another kind.
  enum class LogKind { kKeyRefused, kHandshakeFailed, kFolderUnreadable, kCount };
  void LogRateLimited(LogKind kind, const std::string& line);

  std::filesystem::path directory_;
  std::set<std::string> alsoAllowed_;
  std::map<std::string, std::string> allowed_;  // key -> file; only the thread touches it
  std::vector<ListingEntry> listing_;
  struct LogLimit {
    std::chrono::steady_clock::time_point last{};
    uint64_t unlogged = 0;
  };
  LogLimit logLimits_[static_cast<size_t>(LogKind::kCount)];
  std::atomic<uint64_t> refusedKeys_{0};
  std::atomic<uint64_t> failedHandshakes_{0};
  std::atomic<bool> stop_{false};
  std::thread thread_;
};

}  // namespace tcfarm
