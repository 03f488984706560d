#include "coordinator/http/query_params.h"

#include <algorithm>
#include <limits>
#include <optional>

#include "coordinator/http/api_error.h"
#include "coordinator/http/submit_request.h"

namespace tcfarm::http {
namespace {

// "queued,running": a comma-separated list of names, each one `parse` knows; empty when the
// parameter is absent. `expected` lists the names.
template <typename T, typename Parse>
std::vector<T> ParseNameList(const httplib::Request& request, const char* name, Parse parse,
                             const std::string& what, const std::string& expected) {
  RequireAtMostOnce(request, name);
  if (!request.has_param(name)) return {};
  const std::string text = request.get_param_value(name);
  std::vector<T> values;
  size_t begin = 0;
  for (;;) {
    const size_t comma = text.find(',', begin);
    const std::string item = text.substr(begin, comma == std::string::npos ? std::string::npos : comma - begin);
    const std::optional<T> value = parse(item);
    if (!value) {
      throw ApiError(400, error_code::kInvalidParameter,
                     std::string(name) + " " + ShowValue(item) + " is not " + what + "; expected one of " +
                         expected + ", or several separated by commas");
    }
    values.push_back(*value);
    if (comma == std::string::npos) return values;
    begin = comma + 1;
  }
}

}  // namespace

bool AllDigits(const std::string& text) {
  return !text.empty() &&
         std::all_of(text.begin(), text.end(), [](char c) { return c >= '0' && c <= '9'; });
}

// Path and query parameters are parsed as plain decimal integers, never used as text: no
// sign, no spaces, no "..", so nothing a client sends can name a path outside the store.
uint64_t ParseJobId(const std::string& text) {
  constexpr size_t kMaxDigits = 19;  // every 19-digit number fits in uint64_t
  const std::string expected = "expected a positive integer up to 9223372036854775807";
  if (!AllDigits(text) || text.size() > kMaxDigits ||
      std::stoull(text) > static_cast<uint64_t>(std::numeric_limits<int64_t>::max())) {
    throw ApiError(400, error_code::kInvalidParameter,
                   "job id " + ShowValue(text) + " is not a job id; " + expected);
  }
  return std::stoull(text);
}

// A query parameter given twice is refused rather than one of its values picked.
void RequireAtMostOnce(const httplib::Request& request, const char* name) {
  if (request.get_param_value_count(name) > 1) {
    throw ApiError(400, error_code::kInvalidParameter,
                   std::string(name) + " is given " + std::to_string(request.get_param_value_count(name)) +
                       " times; expected it at most once");
  }
}

std::vector<JobState> ParseStateFilter(const httplib::Request& request) {
  return ParseNameList<JobState>(request, "state", JobStateFromString, "a job state",
                                 "queued, running, completed, failed, canceled");
}

std::vector<Strategy> ParseStrategyFilter(const httplib::Request& request) {
  std::string names;
  for (const StrategyNameEntry& entry : kStrategyNames) names += (names.empty() ? "" : ", ") + std::string(entry.name);
  return ParseNameList<Strategy>(request, "strategy", StrategyFromString, "a strategy", names);
}

std::string ParseNameFilter(const httplib::Request& request) {
  RequireAtMostOnce(request, "name");
  const std::string text = request.get_param_value("name");
  if (text.size() > kMaxNameBytes) {
    throw ApiError(400, error_code::kInvalidParameter,
                   "name is " + std::to_string(text.size()) + " bytes long; expected at most " +
                       std::to_string(kMaxNameBytes) + " bytes, the longest a job's name can be");
  }
  return text;
}

// A decimal integer in [low, high], or `fallback` when the parameter is absent.
int64_t ParseInteger(const httplib::Request& request, const char* name, int64_t low, int64_t high, int64_t fallback) {
  RequireAtMostOnce(request, name);
  if (!request.has_param(name)) return fallback;
  const std::string text = request.get_param_value(name);
  const std::string expected = "expected an integer in [" + std::to_string(low) + ", " + std::to_string(high) + "]";
  constexpr size_t kMaxDigits = 18;  // below 2^63
  if (!AllDigits(text) || text.size() > kMaxDigits || std::stoll(text) < low || std::stoll(text) > high) {
    throw ApiError(400, error_code::kInvalidParameter,
                   std::string(name) + " " + ShowValue(text) + " is out of range; " + expected);
  }
  return std::stoll(text);
}

}  // namespace tcfarm::http
