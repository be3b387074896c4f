// Status and StatusOr: expected outcomes reported as values, in the style of abseil's Status.
#pragma once

#include <optional>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

namespace npfkct {

/// Canonical error codes; the numbering and names follow google.rpc.Code so that the server can
/// map them one to one onto gRPC status names.
enum class StatusCode : int {
  kOk = 0,
  kCancelled = 1,
  kUnknown = 2,
  kInvalidArgument = 3,
  kDeadlineExceeded = 4,
  kNotFound = 5,
  kAlreadyExists = 6,
  kPermissionDenied = 7,
  kResourceExhausted = 8,
  kFailedPrecondition = 9,
  kAborted = 10,
  kOutOfRange = 11,
  kUnimplemented = 12,
  kInternal = 13,
  kUnavailable = 14,
  kDataLoss = 15,
  kUnauthenticated = 16,
};

/// The gRPC name of a code, e.g. "INVALID_ARGUMENT".
std::string_view StatusCodeName(StatusCode code);

/// One offending field of a request, carried beside a status's message (google.rpc.BadRequest):
/// `field` is the path of the field in the request ("world.furniture[0].size", "budget.timeMs"),
/// `description` says what is wrong with it.
struct FieldViolation {
  std::string field;
  std::string description;
  friend bool operator==(const FieldViolation&, const FieldViolation&) = default;
};

/// An outcome: OK, or a code with a human-readable message, and optionally the fields it is
/// about as structured data (never parsed back out of the message):
///
///   Status s = InvalidFieldError("budget.timeMs", "must be at most 60000");
///   s.field_violations()[0].field;  // "budget.timeMs"
///   s.message();                     // "budget.timeMs: must be at most 60000"
class [[nodiscard]] Status {
 public:
  /// An OK status.
  Status() = default;
  /// A status with the given code and message.
  Status(StatusCode code, std::string message) : code_(code), message_(std::move(message)) {}

  /// Whether the outcome is OK.
  bool ok() const { return code_ == StatusCode::kOk; }
  /// The code.
  StatusCode code() const { return code_; }
  /// The message (empty for OK).
  const std::string& message() const { return message_; }
  /// "OK" or "CODE_NAME: message".
  std::string ToString() const;
  /// The fields this status is about (empty when none was attached).
  const std::vector<FieldViolation>& field_violations() const { return violations_; }
  /// Attaches a field violation; returns *this so that calls chain.
  Status& WithFieldViolation(std::string field, std::string description) {
    violations_.push_back({std::move(field), std::move(description)});
    return *this;
  }

  friend bool operator==(const Status& a, const Status& b) {
    return a.code_ == b.code_ && a.message_ == b.message_;
  }

 private:
  StatusCode code_ = StatusCode::kOk;
  std::string message_;
  std::vector<FieldViolation> violations_;
};

/// An OK status.
inline Status OkStatus() { return Status(); }
/// An INVALID_ARGUMENT status.
inline Status InvalidArgumentError(std::string msg) {
  return Status(StatusCode::kInvalidArgument, std::move(msg));
}
/// A FAILED_PRECONDITION status.
inline Status FailedPreconditionError(std::string msg) {
  return Status(StatusCode::kFailedPrecondition, std::move(msg));
}
/// A NOT_FOUND status.
inline Status NotFoundError(std::string msg) {
  return Status(StatusCode::kNotFound, std::move(msg));
}
/// An INTERNAL status.
inline Status InternalError(std::string msg) {
  return Status(StatusCode::kInternal, std::move(msg));
}
/// A RESOURCE_EXHAUSTED status.
inline Status ResourceExhaustedError(std::string msg) {
  return Status(StatusCode::kResourceExhausted, std::move(msg));
}
/// A CANCELLED status.
inline Status CancelledError(std::string msg) {
  return Status(StatusCode::kCancelled, std::move(msg));
}
/// An INVALID_ARGUMENT status about one field: message "<field>: <description>" and the field
/// violation {field, description} as its payload.
inline Status InvalidFieldError(std::string field, std::string description) {
  Status s(StatusCode::kInvalidArgument, field + ": " + description);
  s.WithFieldViolation(std::move(field), std::move(description));
  return s;
}
/// A status of `code` about one field (e.g. RESOURCE_EXHAUSTED naming the limit's field).
inline Status FieldError(StatusCode code, std::string field, std::string description) {
  Status s(code, field + ": " + description);
  s.WithFieldViolation(std::move(field), std::move(description));
  return s;
}
/// An OUT_OF_RANGE status.
inline Status OutOfRangeError(std::string msg) {
  return Status(StatusCode::kOutOfRange, std::move(msg));
}

/// A value or the error that prevented it.
template <class T>
class [[nodiscard]] StatusOr {
 public:
  /// Holds a value.
  StatusOr(T value) : value_(std::move(value)) {}  // NOLINT: implicit like absl::StatusOr
  /// Holds an error; `status` must not be OK.
  StatusOr(Status status) : status_(std::move(status)) {  // NOLINT
    if (status_.ok()) status_ = InternalError("StatusOr constructed from an OK status");
  }

  /// Whether a value is held.
  bool ok() const { return status_.ok(); }
  /// The status (OK when a value is held).
  const Status& status() const { return status_; }
  /// The value; only valid when ok().
  const T& value() const& { return *value_; }
  /// The value; only valid when ok().
  T& value() & { return *value_; }
  /// The value moved out; only valid when ok().
  T&& value() && { return std::move(*value_); }
  const T& operator*() const& { return *value_; }
  T& operator*() & { return *value_; }
  const T* operator->() const { return &*value_; }
  T* operator->() { return &*value_; }

 private:
  Status status_;
  std::optional<T> value_;
};

}  // namespace npfkct
