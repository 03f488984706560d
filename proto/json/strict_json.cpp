#include "json/strict_json.h"

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
  DocumentPosition position;
  json::parser_callback_t callback = [&position](int, json::parse_event_t event, json& parsed) {
    return position.OnEvent(event, parsed);
  };
  try {
    return json::parse(text, callback);
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
