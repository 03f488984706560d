#include "proto/json/strict_json.h"

#include <set>
#include <vector>

namespace tcfarm {
namespace {

using json = nlohmann::json;

// Follows the parser through the document, so errors can name where they happened.
class DocumentPosition {
 public:
  // refuseDuplicateKeys false: only the nesting is checked (CheckJsonNesting).
  explicit DocumentPosition(bool refuseDuplicateKeys = true) : refuseDuplicateKeys_(refuseDuplicateKeys) {}

  bool OnEvent(json::parse_event_t event, const json& parsed) {
    switch (event) {
      case json::parse_event_t::object_start:
      case json::parse_event_t::array_start:
        // Deeper documents are refused while parsing: writing one back out (dump) recurses
        // once per level and would overflow the stack of whoever does it.
        if (levels_.size() >= kMaxJsonDepth) {
          throw JsonInputError(PendingValuePointer(), "objects and arrays nested deeper than " +
                                                          std::to_string(kMaxJsonDepth) + " levels",
                               "at most " + std::to_string(kMaxJsonDepth) + " levels");
        }
        BeginValue();
        levels_.push_back(Level{event == json::parse_event_t::object_start, {}, {}, -1});
        break;
      case json::parse_event_t::object_end:
      case json::parse_event_t::array_end:
        levels_.pop_back();
        break;
      case json::parse_event_t::key:
        OnKey(parsed.get<std::string>());
        break;
      case json::parse_event_t::value:
        BeginValue();
        break;
    }
    return true;
  }

  // The pointer of the value the parser is about to read (where it stopped on an error).
  std::string PendingValuePointer() const {
    if (levels_.empty()) return "";
    const Level& last = levels_.back();
    return EnclosingPointer() + "/" +
           (last.isObject ? EscapePointerToken(last.key) : std::to_string(last.index + 1));
  }

 private:
  struct Level {
    bool isObject;
    std::set<std::string> keys;
    std::string key;
    long index;
  };

  void BeginValue() {
    if (!levels_.empty() && !levels_.back().isObject) ++levels_.back().index;
  }

  void OnKey(const std::string& key) {
    Level& level = levels_.back();
    if (refuseDuplicateKeys_ && !level.keys.insert(key).second) {
      throw JsonInputError(EnclosingPointer() + "/" + EscapePointerToken(key),
                           "duplicate field \"" + key + "\"", "each field at most once per object");
    }
    level.key = key;
  }

  // Pointer of the innermost open container.
  std::string EnclosingPointer() const {
    std::string pointer;
    for (size_t i = 0; i + 1 < levels_.size(); ++i) {
      const Level& level = levels_[i];
      pointer += "/" + (level.isObject ? EscapePointerToken(level.key) : std::to_string(level.index));
    }
    return pointer;
  }

  bool refuseDuplicateKeys_;
  std::vector<Level> levels_;
};

// Builds the document as nlohmann's plain DOM parser does, telling `position` of each event
// first. Not nlohmann's callback parser: at the end of every object that one looks through
// all of the enclosing container for values to discard, which makes an array of n objects
// (a scene's shapes) cost O(n^2) to parse.
class PositionedDomBuilder {
 public:
  PositionedDomBuilder(json& result, DocumentPosition& position) : dom_(result), position_(position) {}

  bool null() { return Value() && dom_.null(); }
  bool boolean(bool value) { return Value() && dom_.boolean(value); }
  bool number_integer(json::number_integer_t value) { return Value() && dom_.number_integer(value); }
  bool number_unsigned(json::number_unsigned_t value) { return Value() && dom_.number_unsigned(value); }
  bool number_float(json::number_float_t value, const json::string_t& text) {
    return Value() && dom_.number_float(value, text);
  }
  bool string(json::string_t& value) { return Value() && dom_.string(value); }
  bool binary(json::binary_t& value) { return Value() && dom_.binary(value); }
  bool start_object(std::size_t size) {
    return position_.OnEvent(json::parse_event_t::object_start, nullptr) && dom_.start_object(size);
  }
  bool key(json::string_t& key) { return position_.OnEvent(json::parse_event_t::key, key) && dom_.key(key); }
  bool end_object() { return position_.OnEvent(json::parse_event_t::object_end, nullptr) && dom_.end_object(); }
  bool start_array(std::size_t size) {
    return position_.OnEvent(json::parse_event_t::array_start, nullptr) && dom_.start_array(size);
  }
  bool end_array() { return position_.OnEvent(json::parse_event_t::array_end, nullptr) && dom_.end_array(); }
  // Templated as nlohmann's own: the DOM parser throws `error` as its own type (parse_error,
  // out_of_range), which the caller tells apart.
  template <typename Exception>
  bool parse_error(std::size_t at, const std::string& token, const Exception& error) {
    return dom_.parse_error(at, token, error);
  }

 private:
  bool Value() { return position_.OnEvent(json::parse_event_t::value, nullptr); }
  nlohmann::detail::json_sax_dom_parser<json> dom_;
  DocumentPosition& position_;
};

// Follows a document's nesting without building it; stops quietly at a syntax error, which
// the parser that reads the document next reports in its own words.
class NestingCheck {
 public:
  bool null() { return Value(); }
  bool boolean(bool) { return Value(); }
  bool number_integer(json::number_integer_t) { return Value(); }
  bool number_unsigned(json::number_unsigned_t) { return Value(); }
  bool number_float(json::number_float_t, const json::string_t&) { return Value(); }
  bool string(json::string_t&) { return Value(); }
  bool binary(json::binary_t&) { return Value(); }
  bool start_object(std::size_t) { return position_.OnEvent(json::parse_event_t::object_start, nullptr); }
  bool key(json::string_t& key) { return position_.OnEvent(json::parse_event_t::key, key); }
  bool end_object() { return position_.OnEvent(json::parse_event_t::object_end, nullptr); }
  bool start_array(std::size_t) { return position_.OnEvent(json::parse_event_t::array_start, nullptr); }
  bool end_array() { return position_.OnEvent(json::parse_event_t::array_end, nullptr); }
  template <typename Exception>
  bool parse_error(std::size_t, const std::string&, const Exception&) {
    return false;
  }

 private:
  bool Value() { return position_.OnEvent(json::parse_event_t::value, nullptr); }
  DocumentPosition position_{false};
};

// What nlohmann's DOM spends (64-bit libstdc++, with malloc's 16 bytes a block): an array
// element 16 bytes, and up to 16 more while its vector grows by doubling; an object member
// a tree node of 96 bytes holding its key (inline up to 15 bytes) and value; an object or
// array a block of 64; a string a block of 48 plus, past the 15 characters held inline, a
// block of its characters (up to 24 bytes more than they: malloc's header and alignment).
// A key's long characters count alike.
constexpr uint64_t kValueBytes = 16, kArraySlackBytes = 16, kMemberNodeBytes = 96, kContainerBytes = 64;
constexpr uint64_t kStringBytes = 48, kInlineStringBytes = 15, kBlockOverheadBytes = 24;

}  // namespace

void CheckJsonNesting(std::string_view text) {
  NestingCheck check;
  json::sax_parse(text.begin(), text.end(), &check, json::input_format_t::json, true);
}

uint64_t JsonDomBytes(std::string_view text) {
  // Every '{' and '[' outside strings opens a container and its first entry, every ','
  // starts another entry of the innermost one; a string's length is bounded by its bytes.
  // An empty container counts an entry it lacks: an estimate from above.
  uint64_t bytes = kValueBytes;
  std::vector<bool> inObject;  // per open container, innermost last
  const auto entry = [&] {
    return !inObject.empty() && inObject.back() ? kMemberNodeBytes : kValueBytes + kArraySlackBytes;
  };
  for (size_t at = 0; at < text.size(); ++at) {
    switch (text[at]) {
      case '"': {
        const size_t begin = at + 1;
        while (++at < text.size() && text[at] != '"') at += text[at] == '\\';
        const uint64_t length = at - begin;  // escapes only make the text longer than the string
        bytes += kStringBytes + (length > kInlineStringBytes ? length + kBlockOverheadBytes : 0);
        break;
      }
      case '{':
      case '[':
        inObject.push_back(text[at] == '{');
        bytes += kContainerBytes + entry();
        break;
      case '}':
      case ']':
        if (!inObject.empty()) inObject.pop_back();
        break;
      case ',':
        bytes += entry();
        break;
      default:
        break;
    }
  }
  return bytes;
}

std::string EscapePointerToken(const std::string& token) {
  std::string escaped;
  for (char c : token) {
    if (c == '~') {
      escaped += "~0";
    } else if (c == '/') {
      escaped += "~1";
    } else {
      escaped += c;
    }
  }
  return escaped;
}

std::string StripJsonExceptionPrefix(const std::string& what) {
  size_t end = what.find("] ");
  return what.rfind("[json.exception.", 0) == 0 && end != std::string::npos ? what.substr(end + 2)
                                                                            : what;
}

json ParseStrictJson(const std::string& text) {
  json parsed;
  DocumentPosition position;
  PositionedDomBuilder builder(parsed, position);
  try {
    json::sax_parse(text, &builder);
    return parsed;
  } catch (const json::parse_error& error) {
    // nlohmann's message already ends in "; expected ...": keep its expectation as ours.
    std::string detail = StripJsonExceptionPrefix(error.what());
    size_t split = detail.find("; expected ");
    std::string expected = split == std::string::npos ? "a JSON document" : detail.substr(split + 11);
    throw JsonInputError("", "invalid JSON at byte " + std::to_string(error.byte) + ": " +
                                 detail.substr(0, split),
                         expected);
  } catch (const json::out_of_range& error) {
    // nlohmann refuses numbers that overflow a double (1e999) before the callback sees them.
    throw JsonInputError(position.PendingValuePointer(), StripJsonExceptionPrefix(error.what()),
                         "a finite number");
  } catch (const json::exception& error) {
    throw JsonInputError(position.PendingValuePointer(), StripJsonExceptionPrefix(error.what()),
                         "a JSON document");
  }
}

}  // namespace tcfarm
