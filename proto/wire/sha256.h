// SHA-256 (FIPS 180-4). Scenes are named by the SHA-256 of their canonical JSON, so a
// worker can cache a scene by name and a name can never point at two different scenes.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <string>
#include <string_view>

namespace tcfarm::wire {

// Incremental hashing, for callers that produce the bytes in pieces.
class Sha256 {
 public:
  using Digest = std::array<uint8_t, 32>;

  Sha256();
  void Update(std::string_view bytes);
  // Pads and returns the digest; the object is spent afterwards (call Reset to reuse it).
  Digest Finish();
  void Reset();

 private:
  void CompressBlock(const uint8_t* block);

  std::array<uint32_t, 8> state_;
  std::array<uint8_t, 64> buffer_;
  size_t bufferedBytes_ = 0;
  uint64_t totalBytes_ = 0;
};

// 64 lowercase hex characters.
std::string Sha256Hex(std::string_view bytes);
std::string DigestHex(const Sha256::Digest& digest);

}  // namespace tcfarm::wire
