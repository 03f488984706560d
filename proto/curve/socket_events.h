// Reading a ZeroMQ socket's monitor (zmq_socket_monitor): the events that say why a
// CURVE handshake failed. Both ends use it: the coordinator to count connections it
// refused, a worker to say why it is refused and back off instead of retrying at once.
#pragma once

#include <zmq.hpp>

#include <cstdint>
#include <cstdio>
#include <cstring>
#include <optional>
#include <string>

namespace tcfarm::curve {

// Events that end a connection in its handshake.
inline constexpr int kHandshakeFailureEvents =
    ZMQ_EVENT_HANDSHAKE_FAILED_NO_DETAIL | ZMQ_EVENT_HANDSHAKE_FAILED_PROTOCOL | ZMQ_EVENT_HANDSHAKE_FAILED_AUTH;

struct SocketEvent {
  uint16_t event = 0;
  uint32_t value = 0;  // errno, protocol error code or ZAP status, by event
};

// The next event on a monitor's PAIR socket, without waiting; nothing when none is there.
inline std::optional<SocketEvent> ReadSocketEvent(zmq::socket_t& monitor) {
  zmq::message_t head, endpoint;
  if (!monitor.recv(head, zmq::recv_flags::dontwait)) return std::nullopt;
  if (head.more()) (void)monitor.recv(endpoint);  // the endpoint: always sent, not needed
  SocketEvent event;
  if (head.size() < 6) return event;  // not an event libzmq writes; event 0 matches nothing
  std::memcpy(&event.event, head.data(), 2);
  std::memcpy(&event.value, static_cast<const char*>(head.data()) + 2, 4);
  return event;
}

// For people: why a handshake failed.
inline std::string DescribeHandshakeFailure(const SocketEvent& event) {
  switch (event.event) {
    case ZMQ_EVENT_HANDSHAKE_FAILED_AUTH:
      return "the key was refused (ZAP status " + std::to_string(event.value) + ")";
    case ZMQ_EVENT_HANDSHAKE_FAILED_NO_DETAIL:
      return std::string("the handshake failed: ") + zmq_strerror(static_cast<int>(event.value));
    case ZMQ_EVENT_HANDSHAKE_FAILED_PROTOCOL:
      switch (event.value) {
        case ZMQ_PROTOCOL_ERROR_ZMTP_MECHANISM_MISMATCH:
          return "security mechanisms differ (one end uses CURVE keys, the other none)";
        case ZMQ_PROTOCOL_ERROR_ZMTP_CRYPTOGRAPHIC:
          return "CURVE cryptography failed (the client holds the wrong server public key?)";
        default:
          return "the handshake broke the protocol (error 0x" + [&] {
            char hex[16];
            std::snprintf(hex, sizeof hex, "%x", event.value);
            return std::string(hex);
          }() + ")";
      }
    default:
      return "event " + std::to_string(event.event);
  }
}

}  // namespace tcfarm::curve
