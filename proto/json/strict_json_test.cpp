// What the import budget learns of a JSON document before it is parsed: its nesting, checked
// as ParseStrictJson checks it, and a bound on the memory its DOM takes.
#include "proto/json/strict_json.h"

#include <gtest/gtest.h>
#include <malloc.h>

#include <string>

#if defined(__SANITIZE_ADDRESS__)
// AddressSanitizer's runtime (sanitizer/allocator_interface.h, which gcc does not ship).
extern "C" size_t __sanitizer_get_current_allocated_bytes();
#endif

namespace tcfarm {
namespace {

std::string Repeated(const std::string& piece, size_t times) {
  std::string text;
  for (size_t i = 0; i < times; ++i) text += piece;
  return text;
}

// The memory malloc has handed out, its own mapped blocks (large vectors) included. Under
// AddressSanitizer its allocator stands in for glibc's, which then counts nothing: it is
// asked instead.
uint64_t MallocBytes() {
#if defined(__SANITIZE_ADDRESS__)
  return __sanitizer_get_current_allocated_bytes();
#else
  const struct mallinfo2 info = mallinfo2();
  return info.uordblks + info.hblkhd;
#endif
}

// The memory the DOM of `text` holds once parsed, as malloc counts it.
uint64_t HeapOfDom(const std::string& text) {
  const uint64_t before = MallocBytes();
  const nlohmann::json document = nlohmann::json::parse(text);
  const uint64_t after = MallocBytes();
  return after > before ? after - before : 0;
}

TEST(StrictJsonTest, TheDomEstimateBoundsWhatTheDomHolds) {
  const std::string documents[] = {
      "[" + Repeated("0,", 100000) + "0]",                // the densest array
      "[" + Repeated("0.123456789,", 100000) + "0]",      // a mesh's numbers
      "[" + Repeated("{\"a\":1},", 50000) + "{}]",        // small objects
      "[" + Repeated("[[[[]]]],", 20000) + "0]",          // empty containers
      "[" + Repeated("\"a string longer than fifteen bytes\",", 20000) + "\"\"]",
      "{\"k\": [], \"a key longer than fifteen bytes\": \"" + std::string(40, 'x') + "\"}",
      "{\"escaped\": \"\\\"\\\\\\u0041\"}",
  };
  for (const std::string& text : documents) {
    const uint64_t estimate = JsonDomBytes(text);
    const uint64_t held = HeapOfDom(text);
    EXPECT_GE(estimate, held) << text.substr(0, 60);
    EXPECT_LE(estimate, 4 * held + 1024) << text.substr(0, 60);  // and not wildly more
  }
}

TEST(StrictJsonTest, NestingAsDeepAsTheLimitPasses) {
  const std::string deepest = std::string(kMaxJsonDepth, '[') + std::string(kMaxJsonDepth, ']');
  EXPECT_NO_THROW(CheckJsonNesting(deepest));
  EXPECT_NO_THROW(ParseStrictJson(deepest));
}

TEST(StrictJsonTest, NestingPastTheLimitNamesWhereAsTheParserDoes) {
  const std::string tooDeep =
      "{\"a\": [1, {\"b~/\": " + std::string(kMaxJsonDepth, '[') + std::string(kMaxJsonDepth, ']') + "}]}";
  std::string checked, parsed;
  try {
    CheckJsonNesting(tooDeep);
  } catch (const JsonInputError& error) {
    checked = error.pointer();
  }
  try {
    ParseStrictJson(tooDeep);
  } catch (const JsonInputError& error) {
    parsed = error.pointer();
  }
  std::string expected = "/a/1/b~0~1";
  for (size_t level = 4; level <= kMaxJsonDepth; ++level) expected += "/0";
  EXPECT_EQ(checked, expected);
  EXPECT_EQ(parsed, expected);
}

TEST(StrictJsonTest, TheNestingCheckLeavesOtherErrorsToTheParser) {
  EXPECT_NO_THROW(CheckJsonNesting("{\"a\": 1, \"a\": 2}"));  // a duplicate key
  EXPECT_NO_THROW(CheckJsonNesting("[1, 2"));                 // a syntax error
  EXPECT_NO_THROW(CheckJsonNesting("[1e999]"));               // a number past a double's range
  EXPECT_THROW(CheckJsonNesting("[1, " + std::string(1000000, '[')), JsonInputError);  // deep before it ends
}

}  // namespace
}  // namespace tcfarm
