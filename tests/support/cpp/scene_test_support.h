// For tests of scene reading and importing: the message of the SceneError an action
// throws, and Base64 to write data URIs with.
#pragma once

#include <algorithm>
#include <cstdint>
#include <functional>
#include <string>

#include "proto/scene/scene.h"

namespace tcfarm {

// What the action's SceneError says, or "no SceneError" when it throws none.
inline std::string ErrorOf(const std::function<void()>& action) {
  try {
    action();
  } catch (const SceneError& error) {
    return error.what();
  }
  return "no SceneError";
}

// RFC 4648 Base64 with padding.
inline std::string Base64(const std::string& bytes) {
  static const char* const kAlphabet = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
  std::string out;
  for (size_t i = 0; i < bytes.size(); i += 3) {
    uint32_t v = 0;
    for (size_t k = 0; k < 3; ++k) v = v << 8 | (i + k < bytes.size() ? static_cast<uint8_t>(bytes[i + k]) : 0u);
    const size_t chars = std::min<size_t>(4, (bytes.size() - i) * 4 / 3 + 1);
    for (size_t k = 0; k < 4; ++k) out += k < chars ? kAlphabet[(v >> (18 - 6 * k)) & 63] : '=';
  }
  return out;
}

}  // namespace tcfarm
