// libFuzzer harness: ParseSubmission over the input as the body of POST /api/v1/jobs, with
// no asset store. Bad input must be an ApiError with a 4xx status: anything else reaches
// the HTTP server as a 500.
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <string>

#include "coordinator/http/api_error.h"
#include "coordinator/http/submit_request.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string body(reinterpret_cast<const char*>(data), size);
  try {
    (void)tcfarm::http::ParseSubmission(body);
  } catch (const tcfarm::http::ApiError& error) {
    if (error.status() < 400 || error.status() > 499) std::abort();
  }
  return 0;
}
