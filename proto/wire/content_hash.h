// SHA-256 (FIPS 180-4), from libsodium. Scenes are named by the SHA-256 of their canonical
// JSON, so a worker can cache a scene by name and a name can never point at two different
// scenes.
#pragma once

#include <string>
#include <string_view>

namespace tcfarm::wire {

// 64 lowercase hex characters.
std::string Sha256Hex(std::string_view bytes);

}  // namespace tcfarm::wire
