#pragma once
/** @file Status and Result<T>: how earshot reports recoverable failures.
 *  Library code never throws across a module boundary on bad input and never
 *  aborts; it returns a Status whose message names what is wrong (file, field,
 *  value), ready to print as one line. */
#include <cstddef>
#include <optional>
#include <string>
#include <string_view>
#include <utility>

namespace earshot {

enum class StatusCode {
  kOk = 0,
  kInvalidArgument,  ///< a value out of range, NaN, wrong type
  kNotFound,         ///< a missing file or name
  kIoError,          ///< read/write failure
  kParseError,       ///< malformed file content
  kUnsupported,      ///< valid but not handled (format, mode)
  kOutOfRange,       ///< a size beyond the limits we accept
  kInternal,
};

/** Name of a status code, e.g. "invalid argument". */
const char* statusCodeName(StatusCode code);

namespace detail {
/** Escapes control characters, C1's U+0080-U+009F too (JSON's way: \\n,
 *  \\u001b, \\u009b), and replaces bytes that are not UTF-8 by U+FFFD, in
 *  place; nothing else changes. */
void makeOneLine(std::string& message);
}  // namespace detail

class [[nodiscard]] Status {
 public:
  Status() = default;
  /** The message is one line of valid UTF-8 whatever went into it (a name
   *  or path from a file included): detail::makeOneLine. */
  Status(StatusCode code, std::string message) : mCode(code), mMessage(std::move(message)) {
    detail::makeOneLine(mMessage);
  }
  static Status ok() { return {}; }

  bool isOk() const { return mCode == StatusCode::kOk; }
  explicit operator bool() const { return isOk(); }
  StatusCode code() const { return mCode; }
  const std::string& message() const { return mMessage; }

 private:
  StatusCode mCode = StatusCode::kOk;
  std::string mMessage;
};

inline Status invalidArgument(std::string m) { return {StatusCode::kInvalidArgument, std::move(m)}; }
inline Status notFound(std::string m) { return {StatusCode::kNotFound, std::move(m)}; }
inline Status ioError(std::string m) { return {StatusCode::kIoError, std::move(m)}; }
inline Status parseError(std::string m) { return {StatusCode::kParseError, std::move(m)}; }
inline Status unsupported(std::string m) { return {StatusCode::kUnsupported, std::move(m)}; }
inline Status outOfRange(std::string m) { return {StatusCode::kOutOfRange, std::move(m)}; }

inline constexpr size_t kQuotedNameBytes = 80;
/** A path from input, quoted: Linux opens none longer (PATH_MAX). */
inline constexpr size_t kQuotedPathBytes = 4096;

/** A name that came from input (a file's key, a glTF node's or material's
 *  name, a caller's string), quoted for a message: in double quotes, at most
 *  `maxBytes` bytes of it (cut before the character that would pass them,
 *  then "..."), with control characters (C1's too), `"` and `\` escaped as
 *  JSON does and each byte of invalid UTF-8 replaced by U+FFFD, so that the message
 *  stays one line of bounded length, and valid UTF-8, whatever the input.
 *  A path is quoted whole (maxBytes = std::string_view::npos) or, when the
 *  input holds it, up to kQuotedPathBytes. */
std::string quotedName(std::string_view name, size_t maxBytes = kQuotedNameBytes);

/** A path for a message: as it is when it is printable UTF-8 without `"`
 *  or `\` (every path a user types), else quotedName(path,
 *  kQuotedPathBytes): a file's reference cannot forge a line. */
std::string displayPath(std::string_view path);

/** A value or the Status that explains why there is none. */
template <class T>
class [[nodiscard]] Result {
 public:
  Result(T value) : mValue(std::move(value)) {}  // NOLINT: implicit on purpose
  Result(Status status) : mStatus(std::move(status)) {}  // NOLINT
  bool isOk() const { return mValue.has_value(); }
  explicit operator bool() const { return isOk(); }
  const Status& status() const { return mStatus; }
  T& value() & { return *mValue; }
  const T& value() const& { return *mValue; }
  T&& value() && { return std::move(*mValue); }
  T* operator->() { return &*mValue; }
  const T* operator->() const { return &*mValue; }
  T& operator*() & { return *mValue; }
  const T& operator*() const& { return *mValue; }

 private:
  std::optional<T> mValue;
  Status mStatus;
};

}  // namespace earshot

/** Return early from a function returning Status or Result<T>. */
#define EARSHOT_RETURN_IF_ERROR(expr)            \
  do {                                           \
    ::earshot::Status _es_status = (expr);       \
    if (!_es_status.isOk()) return _es_status;   \
  } while (0)
