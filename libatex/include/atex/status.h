// Error values for every libatex API.
//
// Contract: no libatex function throws across the public API, prints, or exits.
// Failures come back as a Status (or StatusOr<T>) whose code is one of the
// numbered StatusCode values below and whose message names what went wrong and
// where (chunk, byte offset, element index, file name). The numbers are part of
// the format spec (format_spec/atex.md, "Error codes") and never change meaning.
#pragma once

#include <cstdint>
#include <sstream>
#include <string>
#include <string_view>
#include <utility>
#include <variant>

namespace atex {

enum class StatusCode : int {
  kOk = 0,
  kInvalidArgument = 1,      // the caller passed something out of contract
  kIoError = 2,              // the operating system refused a read, write or rename
  kTruncated = 3,            // input ends before a structure it announces
  kBadMagic = 4,             // not a file of the expected format
  kUnsupportedVersion = 5,   // a newer major version than this reader knows
  kChecksumMismatch = 6,     // stored bytes do not match their checksum
  kCorrupt = 7,              // structurally invalid content (bad offsets, sizes, values)
  kUnsupportedCodec = 8,     // a codec this build cannot decode (e.g. Draco not built in)
  kUnknownCriticalChunk = 9, // a chunk marked critical that this reader does not know
  kOutOfRange = 10,          // a value outside its documented range (NaN, axis 3, h = 3)
  kLimitExceeded = 11,       // a count or size beyond the reader's safety limits
  kNotFound = 12,            // a file, key or camera that does not exist
  kUnsupported = 13,         // a valid request this build or format cannot serve
  kNoDevice = 14,            // no CUDA device where one is needed
  kNumericalError = 15,      // NaN/Inf or divergence that could not be recovered
  kBudgetTooSmall = 16,      // a size budget below the smallest valid result
  kCancelled = 17,           // stopped by the caller's progress callback
  kInternal = 18,            // a bug: an invariant of libatex itself broke
};

// Short stable name of a code, e.g. "checksum-mismatch".
std::string_view StatusCodeName(StatusCode code);

class [[nodiscard]] Status {
 public:
  Status() = default;  // OK
  Status(StatusCode code, std::string message) : code_(code), message_(std::move(message)) {}

  static Status Ok() { return Status(); }
  bool ok() const { return code_ == StatusCode::kOk; }
  StatusCode code() const { return code_; }
  const std::string& message() const { return message_; }

  // "E6 checksum-mismatch: chunk 'GPOS' (#3) at byte 1184: stored CRC32C ..."
  std::string ToString() const;

  // Returns a copy whose message is "<context>: <message>" (no-op when OK).
  Status WithContext(std::string_view context) const;

 private:
  StatusCode code_ = StatusCode::kOk;
  std::string message_;
};

// Concatenates its arguments with operator<< (no <format> in gcc 12).
template <typename... Args>
std::string StrCat(const Args&... args) {
  std::ostringstream out;
  (out << ... << args);
  return out.str();
}

template <typename... Args>
Status MakeError(StatusCode code, const Args&... args) {
  return Status(code, StrCat(args...));
}

template <typename T>
class [[nodiscard]] StatusOr {
 public:
  StatusOr(Status status) : value_(std::move(status)) {  // NOLINT: implicit by design
    if (std::get<Status>(value_).ok()) {
      value_ = Status(StatusCode::kInternal, "StatusOr constructed from an OK status without a value");
    }
  }
  StatusOr(T value) : value_(std::move(value)) {}  // NOLINT: implicit by design

  bool ok() const { return std::holds_alternative<T>(value_); }
  Status status() const { return ok() ? Status() : std::get<Status>(value_); }

  // Precondition: ok().
  T& value() & { return std::get<T>(value_); }
  const T& value() const& { return std::get<T>(value_); }
  T&& value() && { return std::get<T>(std::move(value_)); }
  T& operator*() & { return value(); }
  const T& operator*() const& { return value(); }
  T* operator->() { return &value(); }
  const T* operator->() const { return &value(); }

 private:
  std::variant<Status, T> value_;
};

}  // namespace atex

#define ATEX_STATUS_CONCAT_INNER(a, b) a##b
#define ATEX_STATUS_CONCAT(a, b) ATEX_STATUS_CONCAT_INNER(a, b)

#define ATEX_RETURN_IF_ERROR(expr)                 \
  do {                                             \
    ::atex::Status atex_status_tmp_ = (expr);      \
    if (!atex_status_tmp_.ok()) return atex_status_tmp_; \
  } while (0)

#define ATEX_ASSIGN_OR_RETURN_IMPL(tmp, lhs, expr) \
  auto tmp = (expr);                               \
  if (!tmp.ok()) return tmp.status();              \
  lhs = std::move(tmp).value()

// ATEX_ASSIGN_OR_RETURN(auto x, FunctionReturningStatusOr());
// Expands to several statements: use it inside braces, never as the body of a bare if/for.
#define ATEX_ASSIGN_OR_RETURN(lhs, expr) \
  ATEX_ASSIGN_OR_RETURN_IMPL(ATEX_STATUS_CONCAT(atex_statusor_, __LINE__), lhs, expr)
