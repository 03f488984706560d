// For tests: a worker in the test's own process, a real DEALER socket that speaks the
// wire protocol and answers tasks with a fixed colour instead of tracing.
#pragma once

#include <gtest/gtest.h>

#include <string>
#include <vector>

#include <zmq.hpp>

#include "proto/wire/wire.h"
#include "proto/wire/zmq_io.h"

namespace tcfarm {

class FakeWorker {
 public:
  // name: what it says in READY; by default one of its own, so that fake workers are
  // different principals (without CURVE a worker is its name and address).
  FakeWorker(zmq::context_t& context, const std::string& endpoint, uint32_t capacity, std::string name = "")
      : socket_(context, zmq::socket_type::dealer) {
    static int made = 0;
    socket_.set(zmq::sockopt::linger, 0);
    socket_.connect(endpoint);
    Send(wire::Ready{capacity, 1, name.empty() ? "fake-" + std::to_string(made++) : name});
  }
  void Send(const wire::Message& message) { ASSERT_TRUE(wire::SendMessage(socket_, message)); }
  void SendRaw(const std::vector<std::string>& parts) {
    for (size_t i = 0; i < parts.size(); ++i) {
      socket_.send(zmq::buffer(parts[i]),
                   i + 1 < parts.size() ? zmq::send_flags::sndmore : zmq::send_flags::none);
    }
  }
  // Everything the dispatcher sent us so far, decoded.
  std::vector<wire::Message> Drain() {
    std::vector<wire::Message> messages;
    while (auto parts = wire::ReceiveParts(socket_)) messages.push_back(wire::Decode(*parts));
    return messages;
  }
  std::vector<wire::Task> Tasks() {
    std::vector<wire::Task> tasks;
    for (auto& m : Drain()) {
      if (auto* t = std::get_if<wire::Task>(&m)) tasks.push_back(std::move(*t));
    }
    return tasks;
  }
  std::vector<wire::AssetPiece> Pieces() {
    std::vector<wire::AssetPiece> pieces;
    for (auto& m : Drain()) {
      if (auto* p = std::get_if<wire::AssetPiece>(&m)) pieces.push_back(std::move(*p));
    }
    return pieces;
  }
  // Every pixel `value`, traced in no time.
  void Answer(const wire::Task& task, float value = 0.5f) {
    wire::Result result;
    result.taskId = task.taskId;
    result.jobId = task.jobId;
    result.frame = task.frame;
    result.rgb.assign(task.pixels.size() * 3, value);
    Send(result);
  }

 private:
  zmq::socket_t socket_;
};

}  // namespace tcfarm
