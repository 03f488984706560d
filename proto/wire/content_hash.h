// SHA-256 (FIPS 180-4), from libsodium. Scenes are named by the SHA-256 of their canonical
// JSON, so a worker can cache a scene by name and a name can never point at two different
// scenes. Assets (meshes, buffers, textures) are named the same way by their bytes.
#pragma once

#include <memory>
#include <string>
#include <string_view>

namespace tcfarm::wire {

// 64 lowercase hex characters.
std::string Sha256Hex(std::string_view bytes);

// True for 64 lowercase hex characters: the only form a scene's or an asset's name takes.
bool IsSha256Hex(std::string_view text);

// The same hash over bytes that arrive in pieces: an asset upload is hashed as it streams
// to disk, never held in memory whole. Sha256Hex(a + b) == (Update(a), Update(b), Hex()).
class Sha256Stream {
 public:
  Sha256Stream();
  ~Sha256Stream();
  Sha256Stream(const Sha256Stream&) = delete;
  Sha256Stream& operator=(const Sha256Stream&) = delete;

  void Update(std::string_view bytes);
  // Ends the stream: 64 lowercase hex characters. Update after it throws std::logic_error.
  std::string Hex();

 private:
  struct State;  // libsodium's, kept out of this header
  std::unique_ptr<State> state_;
  bool finished_ = false;
};

}  // namespace tcfarm::wire
