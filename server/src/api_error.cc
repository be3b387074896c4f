#include "npfkct/server/api_error.h"

#include <nlohmann/json.hpp>

namespace npfkct::server {

ApiError ApiError::From(Status status, std::string field) {
  ApiError e{std::move(status), std::move(field)};
  if (e.field.empty() && !e.status.ok() &&
      (e.status.code() == StatusCode::kInvalidArgument ||
       e.status.code() == StatusCode::kOutOfRange)) {
    const std::string& m = e.status.message();
    const size_t colon = m.find(": ");
    // A field path has no spaces: "world.furniture[0].size".
    if (colon != std::string::npos && colon > 0 &&
        m.substr(0, colon).find(' ') == std::string::npos) {
      e.field = m.substr(0, colon);
    }
  }
  return e;
}

int HttpStatusOf(StatusCode code) {
  switch (code) {
    case StatusCode::kOk:
      return 200;
    case StatusCode::kCancelled:
      return 499;
    case StatusCode::kInvalidArgument:
    case StatusCode::kFailedPrecondition:
    case StatusCode::kOutOfRange:
      return 400;
    case StatusCode::kDeadlineExceeded:
      return 504;
    case StatusCode::kNotFound:
      return 404;
    case StatusCode::kAlreadyExists:
    case StatusCode::kAborted:
      return 409;
    case StatusCode::kPermissionDenied:
      return 403;
    case StatusCode::kUnauthenticated:
      return 401;
    case StatusCode::kResourceExhausted:
      return 429;
    case StatusCode::kUnimplemented:
      return 501;
    case StatusCode::kUnavailable:
      return 503;
    case StatusCode::kUnknown:
    case StatusCode::kInternal:
    case StatusCode::kDataLoss:
      return 500;
  }
  return 500;
}

std::string ErrorBody(const ApiError& error) {
  nlohmann::json body;
  body["error"]["code"] = HttpStatusOf(error.status.code());
  body["error"]["status"] = std::string(StatusCodeName(error.status.code()));
  body["error"]["message"] = error.status.message();
  body["error"]["details"] = nlohmann::json::array();
  if (!error.field.empty()) {
    std::string description = error.status.message();
    if (description.rfind(error.field + ": ", 0) == 0) {
      description = description.substr(error.field.size() + 2);
    }
    body["error"]["details"].push_back(
        {{"@type", "type.googleapis.com/google.rpc.BadRequest"},
         {"fieldViolations", {{{"field", error.field}, {"description", description}}}}});
  }
  return body.dump(-1, ' ', false, nlohmann::json::error_handler_t::replace);
}

}  // namespace npfkct::server
