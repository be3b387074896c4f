// API errors in the gRPC style: a canonical status, a message, and the JSON path of the offending
// field, rendered as {"error": {"code", "status", "message", "details"}}.
#pragma once

#include <string>

#include "npfkct/solver/status.h"

namespace npfkct::server {

/// An error to report to a client.
struct ApiError {
  Status status;
  /// JSON path of the offending field ("world.furniture[0].size"); empty when none applies.
  std::string field;

  /// From a Status whose message starts with "<field>: ..." (the convention of the solver's and
  /// simulator's validators), taking the field from the message when `field` is not given.
  static ApiError From(Status status, std::string field = "");
};

/// The HTTP status of a canonical code (google.rpc.Code to HTTP mapping).
int HttpStatusOf(StatusCode code);

/// The JSON error body of an error.
std::string ErrorBody(const ApiError& error);

}  // namespace npfkct::server
