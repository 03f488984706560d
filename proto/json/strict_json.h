// JSON as the farm reads it from users: nlohmann's parser, plus a refusal of what it lets
// through silently (a key given twice keeps only its last value), and errors that say
// where (an RFC 6901 pointer) and what was expected. Shared by the scene parser and the
// HTTP API, so a client sees one style of message everywhere.
#pragma once

#include <cstdint>
#include <stdexcept>
#include <string>
#include <string_view>

#include <nlohmann/json.hpp>

namespace tcfarm {

class JsonInputError : public std::runtime_error {
 public:
  JsonInputError(std::string pointer, std::string problem, std::string expected)
      : std::runtime_error(problem + "; expected " + expected),
        pointer_(std::move(pointer)),
        problem_(std::move(problem)),
        expected_(std::move(expected)) {}
  const std::string& pointer() const { return pointer_; }  // "" for the whole document
  const std::string& problem() const { return problem_; }
  const std::string& expected() const { return expected_; }

 private:
  std::string pointer_, problem_, expected_;
};

// Objects and arrays nest at most this deep: a scene needs fewer than ten levels.
constexpr size_t kMaxJsonDepth = 128;

// Parses `text`; throws JsonInputError for a syntax error ("invalid JSON at byte N: ...",
// pointer ""), a number beyond double range (pointer of the number), a duplicate key
// (pointer of the second occurrence), or nesting deeper than kMaxJsonDepth (pointer of
// the container that goes too deep).
nlohmann::json ParseStrictJson(const std::string& text);

// ParseStrictJson's nesting limit, for a document another parser reads (a glTF file's
// JSON, which tinygltf parses): throws JsonInputError with the pointer of the container
// that goes deeper than kMaxJsonDepth. Builds nothing, so a deep document costs no memory;
// a syntax error ends the check quietly, for the parser that follows to report.
void CheckJsonNesting(std::string_view text);

// At least the bytes nlohmann's DOM of `text` takes, without parsing it: what reading a
// document will cost, known before it is read (ImportBudget). One pass over the bytes.
uint64_t JsonDomBytes(std::string_view text);

// "~" -> "~0", "/" -> "~1" (RFC 6901).
std::string EscapePointerToken(const std::string& token);

// nlohmann's message without its "[json.exception.parse_error.101] " prefix.
std::string StripJsonExceptionPrefix(const std::string& what);

}  // namespace tcfarm
