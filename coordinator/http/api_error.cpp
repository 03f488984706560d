#include "http/api_error.h"

namespace tcfarm::http {

nlohmann::json ApiError::Body() const {
  nlohmann::json error{{"status", status_}, {"code", code_}, {"message", what()}};
  if (pointer_) error["pointer"] = *pointer_;
  return nlohmann::json{{"error", std::move(error)}};
}

std::string DumpJson(const nlohmann::json& value) {
  return value.dump(-1, ' ', false, nlohmann::json::error_handler_t::replace);
}

}  // namespace tcfarm::http
