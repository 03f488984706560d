#include "proto/json/strict_json.h"

#include <set>
#include <vector>

namespace tcfarm {
namespace {

using json = nlohmann::json;

// Follows the parser through the document, so errors can name where they happened.
class DocumentPosition {
 public:
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
    if (!level.keys.insert(key).second) {
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

}  // namespace

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
