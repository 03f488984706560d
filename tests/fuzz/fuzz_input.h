// How the wire harness cuts one fuzzer input into the four parts of a message, shared by
// the harness and the seed writer so that seeds decode as the messages they were made from.
//
// Layout: three parts each preceded by its length (uint16, little-endian), then the last
// part, which is the rest of the input. A length past the end of the input is cut to what
// is left, so every input is some message: the fuzzer never wastes a run on framing.
// Version and command are one byte in every honest message; a length lets the fuzzer try
// others, which Decode must refuse.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

namespace tcfarm::fuzz {

inline std::vector<std::string> SplitIntoParts(const uint8_t* data, size_t size, size_t partCount) {
  std::vector<std::string> parts;
  size_t at = 0;
  for (size_t part = 0; part + 1 < partCount; ++part) {
    size_t length = 0;
    if (at + 2 <= size) {
      length = size_t{data[at]} | size_t{data[at + 1]} << 8;
      at += 2;
    } else {
      at = size;
    }
    const size_t take = length < size - at ? length : size - at;
    parts.emplace_back(reinterpret_cast<const char*>(data + at), take);
    at += take;
  }
  parts.emplace_back(reinterpret_cast<const char*>(data + at), size - at);
  return parts;
}

// The inverse, for seeds. Parts but the last must be shorter than 64 KiB (headers are at
// most 16 KiB; version and command one byte).
inline std::string JoinParts(const std::vector<std::string>& parts) {
  std::string joined;
  for (size_t part = 0; part + 1 < parts.size(); ++part) {
    const size_t length = parts[part].size();
    joined.push_back(static_cast<char>(length & 0xff));
    joined.push_back(static_cast<char>(length >> 8 & 0xff));
    joined += parts[part];
  }
  if (!parts.empty()) joined += parts.back();
  return joined;
}

}  // namespace tcfarm::fuzz
