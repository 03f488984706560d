// Shared by the importers: errors in the parser's shape ("<problem>; expected <what>").
#pragma once

#include <string>

#include <nlohmann/json.hpp>

#include "proto/scene/scene.h"

namespace tcfarm {

[[noreturn]] inline void FailInput(const std::string& pointer, const std::string& problem,
                                   const std::string& expected) {
  throw SceneError(pointer, problem + "; expected " + expected);
}

// A name from the input, JSON-quoted and cut at 40 characters so a message stays a line.
inline std::string QuoteInput(const std::string& text) {
  constexpr size_t kMaxShown = 40;
  std::string shown = text.size() > kMaxShown ? text.substr(0, kMaxShown) + "..." : text;
  return nlohmann::json(shown).dump(-1, ' ', false, nlohmann::json::error_handler_t::replace);
}

}  // namespace tcfarm
