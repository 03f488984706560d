#include "coordinator/http/api_error.h"

namespace tcfarm::http {

nlohmann::json ApiError::Body() const {
  nlohmann::json error{{"status", status_}, {"code", code_}, {"message", what()}};
  if (pointer_) error["pointer"] = *pointer_;
  return nlohmann::json{{"error", std::move(error)}};
}

std::string DumpJson(const nlohmann::json& value) {
  return value.dump(-1, ' ', false, nlohmann::json::error_handler_t::replace);
}

std::string ShowValue(const nlohmann::json& value) {
  constexpr size_t kShownValueBytes = 60;  // enough to recognize a value, short enough to read
  std::string text = DumpJson(value);
  if (text.size() > kShownValueBytes) text = text.substr(0, kShownValueBytes) + "...";
  return text;
}

}  // namespace tcfarm::http
