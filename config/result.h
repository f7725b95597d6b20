// Result<T>: a value or an Error that names what failed (file:line, device, pose).
//
// Anything that can fail for reasons outside the program (devices, files, configuration,
// input data) returns Result<T>. No exception crosses a library boundary. A broken
// invariant (a bug) aborts through RIG_CHECK instead.
#pragma once

#include <cstdio>
#include <cstdlib>
#include <optional>
#include <string>
#include <utility>
#include <variant>

#include <fmt/format.h>

namespace rig {

enum class ErrorCode {
  kInvalidInput,   // bad configuration, bad file contents, bad arguments (exit 2)
  kNotFound,       // a file or device that is not there (exit 2)
  kIo,             // reading or writing failed
  kDevice,         // a device reported an error
  kTimeout,        // a device did not answer in time
  kBusy,           // a device or session is held by someone else
  kCorrupt,        // stored data failed verification
  kUnsupported,    // the device or build cannot do what was asked
  kInterrupted,    // SIGINT/SIGTERM arrived
  kFault,          // a device is in a fault state that retries did not clear
  kInternal,       // everything else
};

const char* ErrorCodeName(ErrorCode code);

struct Error {
  ErrorCode code = ErrorCode::kInternal;
  std::string message;
  // Where: "config/sim.toml:14:1", "/dev/ttyACM0", "pose h030_v10", a file path.
  std::string context;

  // "context: message" (or just the message when there is no context).
  std::string ToString() const {
    return context.empty() ? message : context + ": " + message;
  }
  // A copy with an outer context prepended ("pose h030_v10: /dev/ttyACM0: timeout").
  Error Within(const std::string& outer) const {
    Error e = *this;
    e.context = context.empty() ? outer : outer + ": " + context;
    return e;
  }
  // Exit status a command returns for this error: 2 for bad input, 1 otherwise.
  int ExitCode() const {
    // Bad input — a wrong value, a missing or damaged file given to us — is 2; a failure of
    // the work (a device, a write) is 1.
    return (code == ErrorCode::kInvalidInput || code == ErrorCode::kNotFound ||
            code == ErrorCode::kCorrupt)
               ? 2
               : 1;
  }
};

template <typename... Args>
Error MakeError(ErrorCode code, std::string context, fmt::format_string<Args...> f,
                Args&&... args) {
  return Error{code, fmt::format(f, std::forward<Args>(args)...), std::move(context)};
}

[[noreturn]] inline void CheckFailed(const char* expr, const char* file, int line,
                                     const std::string& msg) {
  std::fprintf(stderr, "rig: internal error: %s:%d: check failed: %s %s\n", file, line, expr,
               msg.c_str());
  std::abort();
}

#define RIG_CHECK(cond, ...)                                                          \
  do {                                                                                \
    if (!(cond)) ::rig::CheckFailed(#cond, __FILE__, __LINE__, std::string{__VA_ARGS__}); \
  } while (0)

template <typename T>
class [[nodiscard]] Result {
 public:
  Result(T value) : v_(std::in_place_index<0>, std::move(value)) {}  // NOLINT
  Result(Error error) : v_(std::in_place_index<1>, std::move(error)) {}  // NOLINT

  bool ok() const { return v_.index() == 0; }
  explicit operator bool() const { return ok(); }

  T& value() & {
    RIG_CHECK(ok(), error().ToString());
    return std::get<0>(v_);
  }
  const T& value() const& {
    RIG_CHECK(ok(), error().ToString());
    return std::get<0>(v_);
  }
  T&& value() && {
    RIG_CHECK(ok(), error().ToString());
    return std::get<0>(std::move(v_));
  }
  T* operator->() { return &value(); }
  const T* operator->() const { return &value(); }
  T& operator*() & { return value(); }
  const T& operator*() const& { return value(); }

  const Error& error() const {
    RIG_CHECK(!ok(), "error() on a Result that holds a value");
    return std::get<1>(v_);
  }

 private:
  std::variant<T, Error> v_;
};

template <>
class [[nodiscard]] Result<void> {
 public:
  Result() = default;
  Result(Error error) : e_(std::move(error)) {}  // NOLINT

  bool ok() const { return !e_.has_value(); }
  explicit operator bool() const { return ok(); }
  const Error& error() const {
    RIG_CHECK(!ok(), "error() on an ok Status");
    return *e_;
  }

 private:
  std::optional<Error> e_;
};

using Status = Result<void>;
inline Status Ok() { return Status(); }

inline const char* ErrorCodeName(ErrorCode code) {
  switch (code) {
    case ErrorCode::kInvalidInput: return "invalid input";
    case ErrorCode::kNotFound: return "not found";
    case ErrorCode::kIo: return "i/o error";
    case ErrorCode::kDevice: return "device error";
    case ErrorCode::kTimeout: return "timeout";
    case ErrorCode::kBusy: return "busy";
    case ErrorCode::kCorrupt: return "corrupt";
    case ErrorCode::kUnsupported: return "unsupported";
    case ErrorCode::kInterrupted: return "interrupted";
    case ErrorCode::kFault: return "fault";
    case ErrorCode::kInternal: return "internal";
  }
  return "unknown";
}

}  // namespace rig

// Propagates an error: RIG_TRY(status_expr); or RIG_ASSIGN_OR_RETURN(auto x, result_expr);
#define RIG_CONCAT_INNER(a, b) a##b
#define RIG_CONCAT(a, b) RIG_CONCAT_INNER(a, b)
#define RIG_TRY(expr)                                  \
  do {                                                 \
    auto rig_try_status_ = (expr);                     \
    if (!rig_try_status_.ok()) return rig_try_status_.error(); \
  } while (0)
#define RIG_ASSIGN_OR_RETURN_IMPL(tmp, decl, expr) \
  auto tmp = (expr);                               \
  if (!tmp.ok()) return tmp.error();               \
  decl = std::move(tmp).value()
#define RIG_ASSIGN_OR_RETURN(decl, expr) \
  RIG_ASSIGN_OR_RETURN_IMPL(RIG_CONCAT(rig_result_, __LINE__), decl, expr)
