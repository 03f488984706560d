// Moving wire messages over ZeroMQ sockets. The codec (wire.h) knows nothing of ZeroMQ;
// these helpers turn its parts into zmq frames and back, adding or removing the peer
// identity frame that a ROUTER socket sees.
#pragma once

#include <zmq.hpp>
#include <zmq_addon.hpp>

#include <cerrno>
#include <chrono>
#include <optional>
#include <string>
#include <vector>

#include "proto/wire/wire.h"

namespace tcfarm::wire {

// Sends a message on a DEALER socket. Returns false if it would block (peer gone and
// the high-water mark reached): the caller treats that like a lost message.
inline bool SendMessage(zmq::socket_t& socket, const Message& message) {
  std::vector<std::string> parts = Encode(message);
  for (size_t i = 0; i < parts.size(); ++i) {
    auto flags = zmq::send_flags::dontwait;
    if (i + 1 < parts.size()) flags = flags | zmq::send_flags::sndmore;
    if (!socket.send(zmq::buffer(parts[i]), flags)) return false;
  }
  return true;
}

// Sends a message to one peer of a ROUTER socket.
inline bool SendMessageTo(zmq::socket_t& socket, const std::string& identity,
                          const Message& message) {
  if (!socket.send(zmq::buffer(identity), zmq::send_flags::sndmore | zmq::send_flags::dontwait)) {
    return false;
  }
  return SendMessage(socket, message);
}

// Waits up to `timeout` for a message to read on the socket. A signal (SIGTERM, SIGINT:
// stop) cuts the wait short and is no error: the caller's loop looks at its stop flag and
// says goodbye. Any other failure throws.
inline void WaitForInput(zmq::socket_t& socket, std::chrono::milliseconds timeout) {
  zmq::pollitem_t item{static_cast<void*>(socket), 0, ZMQ_POLLIN, 0};
  try {
    zmq::poll(&item, 1, timeout);
  } catch (const zmq::error_t& e) {
    if (e.num() != EINTR) throw;
  }
}

// Receives one multipart message without blocking; nullopt when none is waiting.
inline std::optional<std::vector<std::string>> ReceiveParts(zmq::socket_t& socket) {
  std::vector<zmq::message_t> frames;
  auto received = zmq::recv_multipart(socket, std::back_inserter(frames), zmq::recv_flags::dontwait);
  if (!received) return std::nullopt;
  std::vector<std::string> parts;
  parts.reserve(frames.size());
  for (auto& frame : frames) parts.emplace_back(frame.to_string());
  return parts;
}

// Who sent a message on a ROUTER socket, as ZeroMQ knows it from the connection (not
// from anything the peer says): the CURVE public key that ZAP accepted (Z85), and the
// peer's address. Either is empty where the transport has none.
struct Peer {
  std::string curveKey;
  std::string address;
};

// ReceiveParts, with the connection's Peer read from the message's metadata.
inline std::optional<std::vector<std::string>> ReceivePartsFrom(zmq::socket_t& socket, Peer& peer) {
  std::vector<zmq::message_t> frames;
  auto received = zmq::recv_multipart(socket, std::back_inserter(frames), zmq::recv_flags::dontwait);
  if (!received) return std::nullopt;
  // A property the transport does not set is an error (EINVAL) that only means "none".
  // The ROUTER's routing-id frame is made locally and may carry no metadata: the frames
  // that came over the connection do, so each is asked until one answers.
  auto property = [&](const char* name) -> std::string {
    for (zmq::message_t& frame : frames) {
      if (const char* value = zmq_msg_gets(frame.handle(), name)) return value;
    }
    return "";
  };
  peer = Peer{property("User-Id"), property("Peer-Address")};
  std::vector<std::string> parts;
  parts.reserve(frames.size());
  for (auto& frame : frames) parts.emplace_back(frame.to_string());
  return parts;
}

}  // namespace tcfarm::wire
