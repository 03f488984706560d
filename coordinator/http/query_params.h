// A request's path and query parameters, parsed strictly: each is a plain decimal number or
// a name from a fixed list, never used as text, and given at most once; anything else throws
// ApiError 400 invalid_parameter saying what was expected.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include <httplib.h>

#include "coordinator/jobs/job_store.h"
#include "coordinator/planner/strategy.h"

namespace tcfarm::http {

bool AllDigits(const std::string& text);
// A job id from the path: a positive decimal integer up to 2^63 - 1.
uint64_t ParseJobId(const std::string& text);
// A query parameter given twice is refused rather than one of its values picked.
void RequireAtMostOnce(const httplib::Request& request, const char* name);
// ?state=queued,running: empty when absent.
std::vector<JobState> ParseStateFilter(const httplib::Request& request);
// ?strategy=search,exact: empty when absent.
std::vector<Strategy> ParseStrategyFilter(const httplib::Request& request);
// ?name=: at most a job name's length.
std::string ParseNameFilter(const httplib::Request& request);
// A decimal integer in [low, high], or `fallback` when the parameter is absent.
int64_t ParseInteger(const httplib::Request& request, const char* name, int64_t low, int64_t high, int64_t fallback);

}  // namespace tcfarm::http
