#include "proto/scene/import/gltf_data_uris.h"

#include <cstring>

#include "proto/scene/import/messages.h"

namespace tcfarm::gltf {
namespace {

// Chosen so that no relative file name in a real glTF is likely to look like it; a "uri"
// already in this form is refused, so the names below always stand for this file's own data.
constexpr std::string_view kEmbeddedPrefix = "tcfarm-embedded-data:";
// A "uri" key written with escapes is still short; a longer key is not "uri".
constexpr size_t kMaxKeyBytes = 64;
constexpr unsigned char kNotAscii = 0xFF;

// The characters of a JSON string literal's text, escapes resolved; what is not ASCII
// reads as kNotAscii (neither a URI's header nor base64 holds any).
class LiteralReader {
 public:
  LiteralReader(std::string_view text, size_t begin, size_t end) : text_(text), at_(begin), end_(end) {}
  bool Done() const { return at_ >= end_; }
  size_t Offset() const { return at_; }  // of the next character in the file
  unsigned char Next() {
    const unsigned char c = static_cast<unsigned char>(text_[at_++]);
    if (c != '\\' || at_ >= end_) return c >= 0x80 ? kNotAscii : c;
    const char escaped = text_[at_++];
    switch (escaped) {
      case 'u': return Unicode();
      case 'b': return '\b';
      case 'f': return '\f';
      case 'n': return '\n';
      case 'r': return '\r';
      case 't': return '\t';
      default: return static_cast<unsigned char>(escaped);  // '"', '\\', '/'
    }
  }

 private:
  unsigned char Unicode() {
    unsigned code = 0;
    for (int k = 0; k < 4 && at_ < end_; ++k, ++at_) {
      const char h = text_[at_];
      const unsigned digit = h >= '0' && h <= '9'   ? static_cast<unsigned>(h - '0')
                             : h >= 'a' && h <= 'f' ? static_cast<unsigned>(h - 'a' + 10)
                             : h >= 'A' && h <= 'F' ? static_cast<unsigned>(h - 'A' + 10)
                                                    : 0x10000;
      code = code * 16 + digit;
    }
    return code < 0x80 ? static_cast<unsigned char>(code) : kNotAscii;
  }

  std::string_view text_;
  size_t at_, end_;
};

std::string Resolved(std::string_view text, size_t begin, size_t end, size_t most) {
  std::string out;
  for (LiteralReader reader(text, begin, end); !reader.Done() && out.size() < most;) {
    out += static_cast<char>(reader.Next());
  }
  return out;
}

// The end of the string literal whose text starts at `begin` (the index of its closing
// quote), or npos when the text ends first.
size_t LiteralEnd(std::string_view text, size_t begin) {
  for (size_t at = begin;; ++at) {
    const void* quote = std::memchr(text.data() + at, '"', text.size() - at);
    if (quote == nullptr) return std::string_view::npos;
    at = static_cast<size_t>(static_cast<const char*>(quote) - text.data());
    size_t backslashes = 0;
    while (at - backslashes > begin && text[at - backslashes - 1] == '\\') ++backslashes;
    if (backslashes % 2 == 0) return at;
  }
}

size_t SkipSpaceBack(std::string_view text, size_t at) {  // `at` is one past the character looked at
  while (at > 0 && (text[at - 1] == ' ' || text[at - 1] == '\t' || text[at - 1] == '\n' || text[at - 1] == '\r')) --at;
  return at;
}

// True when the literal opening at `quote` is the value of a key "uri".
bool IsUriValue(std::string_view text, size_t quote) {
  size_t at = SkipSpaceBack(text, quote);
  if (at == 0 || text[at - 1] != ':') return false;
  at = SkipSpaceBack(text, at - 1);
  if (at == 0 || text[at - 1] != '"') return false;
  const size_t keyEnd = at - 1;
  const size_t limit = keyEnd > kMaxKeyBytes ? keyEnd - kMaxKeyBytes : 0;
  for (size_t open = keyEnd; open > limit; --open) {
    if (text[open - 1] != '"') continue;
    const size_t quote = open - 1;
    size_t backslashes = 0;
    while (quote > backslashes && text[quote - 1 - backslashes] == '\\') ++backslashes;
    if (backslashes % 2 == 1) continue;  // an escaped quote inside the key
    return Resolved(text, open, keyEnd, 4) == "uri" && Resolved(text, open, keyEnd, kMaxKeyBytes).size() == 3;
  }
  return false;
}

[[noreturn]] void Fail(const std::string& displayName, size_t offset, const std::string& problem,
                       const std::string& expected) {
  FailInput("", displayName + ": byte " + std::to_string(offset) + ": " + problem, expected);
}

// The base64 after the header, decoded into bytes of their exact size; `reader` stands
// just after the header's comma.
std::vector<unsigned char> DecodeBase64(LiteralReader reader, size_t rawLength, const std::string& displayName) {
  const std::string expected = "a data URI of base64 (A-Z, a-z, 0-9, +, /, then up to two '=')";
  std::vector<unsigned char> bytes;
  // At least what the text says (escapes only make it longer): never grown, so never copied.
  bytes.reserve(rawLength / 4 * 3 + 3);
  uint32_t bits = 0;
  int pending = 0, padding = 0;
  while (!reader.Done()) {
    const size_t offset = reader.Offset();
    const unsigned char c = reader.Next();
    const int value = Base64Value(c);
    if (c == '=' && padding < 2) {
      ++padding;
      continue;
    }
    if (value < 0 || padding > 0) {
      Fail(displayName, offset, c == kNotAscii ? "a character outside ASCII in a data URI"
                                               : "character " + QuoteInput(std::string(1, static_cast<char>(c))) +
                                                     " in a data URI's base64",
           expected);
    }
    bits = bits << 6 | static_cast<uint32_t>(value);
    if (++pending == 4) {
      bytes.insert(bytes.end(), {static_cast<unsigned char>(bits >> 16), static_cast<unsigned char>(bits >> 8),
                                 static_cast<unsigned char>(bits)});
      bits = 0;
      pending = 0;
    }
  }
  if (pending == 1) Fail(displayName, reader.Offset(), "a data URI's base64 ends inside a byte", expected);
  if (pending >= 2) bytes.push_back(static_cast<unsigned char>(bits >> (pending * 6 - 8)));
  if (pending == 3) bytes.push_back(static_cast<unsigned char>(bits >> 2));
  return bytes;
}

struct Found {
  size_t open, close;  // the literal's quotes
};

// The literal at `found` as bytes, when it is a data URI; npos-free: throws on bad base64.
std::optional<std::vector<unsigned char>> DecodeIfDataUri(std::string_view json, Found found,
                                                          const std::string& displayName) {
  constexpr size_t kMaxHeader = 256;  // "data:" and a media type with its parameters
  LiteralReader reader(json, found.open + 1, found.close);
  std::string header;
  while (!reader.Done() && header.size() < kMaxHeader && (header.empty() || header.back() != ',')) {
    header += static_cast<char>(reader.Next());
  }
  if (header.compare(0, kEmbeddedPrefix.size(), kEmbeddedPrefix) == 0) {
    Fail(displayName, found.open, "a uri " + QuoteInput(header) + " in the form this importer reserves for itself",
         "a data URI or a relative file name");
  }
  if (header.compare(0, 5, "data:") != 0) return std::nullopt;
  const std::string base64 = ";base64,";
  if (header.size() < base64.size() || header.compare(header.size() - base64.size(), base64.size(), base64) != 0) {
    Fail(displayName, found.open, "a data URI " + QuoteInput(header) + " that is not base64",
         "data:<media type>;base64,<data>");
  }
  return DecodeBase64(reader, found.close - reader.Offset(), displayName);
}

}  // namespace

std::string EmbeddedName(size_t index) { return std::string(kEmbeddedPrefix) + std::to_string(index); }

std::optional<size_t> EmbeddedIndex(std::string_view uri) {
  if (uri.substr(0, kEmbeddedPrefix.size()) != kEmbeddedPrefix || uri.size() == kEmbeddedPrefix.size()) {
    return std::nullopt;
  }
  size_t index = 0;
  for (const char c : uri.substr(kEmbeddedPrefix.size())) {
    if (c < '0' || c > '9' || index > (SIZE_MAX - 9) / 10) return std::nullopt;
    index = index * 10 + static_cast<size_t>(c - '0');
  }
  return index;
}

EmbeddedData ExtractDataUris(std::string_view json, const std::string& displayName) {
  EmbeddedData data;
  std::vector<Found> replaced;
  size_t kept = json.size();
  for (size_t at = 0; at < json.size(); ++at) {
    const void* quote = std::memchr(json.data() + at, '"', json.size() - at);
    if (quote == nullptr) break;
    const Found found{static_cast<size_t>(static_cast<const char*>(quote) - json.data()), 0};
    const size_t close = LiteralEnd(json, found.open + 1);
    if (close == std::string_view::npos) break;  // unterminated: tinygltf says so
    at = close;
    if (!IsUriValue(json, found.open)) continue;
    std::optional<std::vector<unsigned char>> bytes = DecodeIfDataUri(json, {found.open, close}, displayName);
    if (!bytes) continue;
    data.bytes.push_back(std::move(*bytes));
    replaced.push_back({found.open, close});
    kept -= close - found.open - 1;
  }
  // The text again, each replaced literal's content now its name: built at its final size.
  for (size_t i = 0; i < replaced.size(); ++i) kept += EmbeddedName(i).size();
  data.json.reserve(kept);
  size_t from = 0;
  for (size_t i = 0; i < replaced.size(); ++i) {
    data.json.append(json.substr(from, replaced[i].open + 1 - from));
    data.json += EmbeddedName(i);
    from = replaced[i].close;
  }
  data.json.append(json.substr(from));
  return data;
}

int Base64Value(unsigned char c) {
  if (c >= 'A' && c <= 'Z') return c - 'A';
  if (c >= 'a' && c <= 'z') return c - 'a' + 26;
  if (c >= '0' && c <= '9') return c - '0' + 52;
  if (c == '+') return 62;
  if (c == '/') return 63;
  return -1;
}

}  // namespace tcfarm::gltf
