// Error values for code that must not throw: physics, haptics, parsers, services.
//
// STYLE.md: inside physics and haptics there are no exceptions; a function that can fail returns
// Expected<T> (a value or an Error) and the caller decides. `field` names the offending input
// (a parameter, a JSON key, a command-line flag) so a front end can point at it.
#pragma once

#include <string>
#include <utility>
#include <variant>

namespace vsurg {

enum class ErrorCode {
  kInvalidArgument,  // a parameter is out of its domain (zero radius, negative stiffness, NaN)
  kParseError,       // a file or message is malformed (carries the line or offset in the message)
  kIoError,          // the operating system refused a read or a write
  kNotFound,         // a named thing does not exist (scene, session, file)
  kFailedPrecondition,  // the call is valid but not in this state (e.g. mesh has no vertices)
  kNumerical,           // a computation did not converge or produced a non-finite value
  kAlreadyExists,       // a unique thing exists already (a user name, a second evaluation)
  kUnavailable,         // a resource is busy or shutting down; retrying may succeed
  kResourceExhausted,   // a quota is used up (e.g. a user's live sessions); free some first
  kUnauthenticated,     // no valid credentials
  kPermissionDenied,    // valid credentials, not allowed
};

struct Error {
  ErrorCode code = ErrorCode::kInvalidArgument;
  std::string message;  // one line, for a human: what is wrong and why
  std::string field;    // the input it concerns, empty when none
};

inline Error InvalidArgument(std::string field, std::string message) {
  return Error{ErrorCode::kInvalidArgument, std::move(message), std::move(field)};
}

template <class T>
class [[nodiscard]] Expected {
 public:
  Expected(T value) : v_(std::move(value)) {}      // NOLINT: implicit by design
  Expected(Error error) : v_(std::move(error)) {}  // NOLINT: implicit by design

  bool ok() const { return v_.index() == 0; }
  explicit operator bool() const { return ok(); }

  T& value() & { return std::get<0>(v_); }
  const T& value() const& { return std::get<0>(v_); }
  T&& value() && { return std::get<0>(std::move(v_)); }
  T* operator->() { return &std::get<0>(v_); }
  const T* operator->() const { return &std::get<0>(v_); }
  T& operator*() & { return std::get<0>(v_); }
  const T& operator*() const& { return std::get<0>(v_); }
  T&& operator*() && { return std::get<0>(std::move(v_)); }

  const Error& error() const { return std::get<1>(v_); }

 private:
  std::variant<T, Error> v_;
};

// For functions that return nothing but can fail.
class [[nodiscard]] Status {
 public:
  Status() = default;
  Status(Error error) : error_(std::move(error)), ok_(false) {}  // NOLINT: implicit by design
  static Status Ok() { return Status(); }

  bool ok() const { return ok_; }
  explicit operator bool() const { return ok_; }
  const Error& error() const { return error_; }

 private:
  Error error_;
  bool ok_ = true;
};

}  // namespace vsurg
