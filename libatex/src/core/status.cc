#include "atex/status.h"

namespace atex {

std::string_view StatusCodeName(StatusCode code) {
  switch (code) {
    case StatusCode::kOk: return "ok";
    case StatusCode::kInvalidArgument: return "invalid-argument";
    case StatusCode::kIoError: return "io-error";
    case StatusCode::kTruncated: return "truncated";
    case StatusCode::kBadMagic: return "bad-magic";
    case StatusCode::kUnsupportedVersion: return "unsupported-version";
    case StatusCode::kChecksumMismatch: return "checksum-mismatch";
    case StatusCode::kCorrupt: return "corrupt";
    case StatusCode::kUnsupportedCodec: return "unsupported-codec";
    case StatusCode::kUnknownCriticalChunk: return "unknown-critical-chunk";
    case StatusCode::kOutOfRange: return "out-of-range";
    case StatusCode::kLimitExceeded: return "limit-exceeded";
    case StatusCode::kNotFound: return "not-found";
    case StatusCode::kUnsupported: return "unsupported";
    case StatusCode::kNoDevice: return "no-device";
    case StatusCode::kNumericalError: return "numerical-error";
    case StatusCode::kBudgetTooSmall: return "budget-too-small";
    case StatusCode::kCancelled: return "cancelled";
    case StatusCode::kInternal: return "internal";
  }
  return "unknown";
}

std::string Status::ToString() const {
  if (ok()) return "OK";
  return StrCat("E", static_cast<int>(code_), " ", StatusCodeName(code_), ": ", message_);
}

Status Status::WithContext(std::string_view context) const {
  if (ok()) return *this;
  return Status(code_, StrCat(context, ": ", message_));
}

}  // namespace atex
