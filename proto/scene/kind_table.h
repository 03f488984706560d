// The lookups a table of kinds (shapes, lights) offers the reader and its messages: a
// kind by its JSON name, and the names as a message lists them. `formats` holds one entry
// per kind in the enum's order, each with Name().
#pragma once

#include <cstddef>
#include <optional>
#include <string>

namespace tcfarm {

template <typename Formats>
std::optional<size_t> FindKindIndex(const Formats& formats, const std::string& name) {
  for (size_t i = 0; i < formats.size(); ++i) {
    if (name == formats[i]->Name()) return i;
  }
  return std::nullopt;
}

// "\"a\", \"b\" or \"c\"".
template <typename Formats>
std::string KindChoices(const Formats& formats) {
  std::string joined;
  for (size_t i = 0; i < formats.size(); ++i) {
    if (i > 0) joined += i + 1 == formats.size() ? " or " : ", ";
    joined += "\"" + std::string(formats[i]->Name()) + "\"";
  }
  return joined;
}

}  // namespace tcfarm
