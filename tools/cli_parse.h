// The one strict parser of every `atex` option value: a value is the whole token
// (no trailing characters: "1abc" is not 1), numbers are finite (no nan, inf) and
// inside the option's documented range, sizes are exact (no wrap-around of
// "4294967344x48"). The Add* helpers register CLI11 options that go through these
// parsers, so a bad value is a usage error (exit 2) that names the option and the
// value before the command does any work.
#pragma once

#include <cstdint>
#include <limits>
#include <string>
#include <string_view>
#include <vector>

#include <CLI/CLI.hpp>

#include "atex/status.h"

namespace atex::cli {

// A decimal integer in [min, max] ("+3", "-2" and "0" are integers; "1.0", "1e3",
// "0x10", " 1" and "" are not). kOutOfRange when outside, kInvalidArgument when not an
// integer; the message starts with `what` (e.g. "--repeats").
StatusOr<long long> ParseInteger(std::string_view text, long long min, long long max, std::string_view what);

// A finite decimal number in [min, max] ("0.5", "1e-3", "-2"); never nan, inf, hex
// floats or trailing text.
StatusOr<double> ParseReal(std::string_view text, double min, double max, std::string_view what);

// A byte size: a positive number with an optional unit B, K/KiB, M/MiB, G/GiB (powers of
// 1024) or KB, MB, GB (powers of 1000), case-insensitive, optionally separated by one
// space: "80MiB", "80 MB", "1.5GiB", "102400". At least one byte, at most 2^63.
StatusOr<uint64_t> ParseByteSize(std::string_view text, std::string_view what);

// A comma-separated list of byte sizes; two entries of the same size ("100KiB,102400")
// are an error naming both, since they would name one output twice.
StatusOr<std::vector<uint64_t>> ParseByteSizeList(std::string_view text, std::string_view what,
                                                  std::vector<std::string>* pieces = nullptr);

// "WxH" with 1 <= W, H <= 65536 (e.g. "1352x1014").
struct ImageSize {
  int width = 0, height = 0;
};
StatusOr<ImageSize> ParseImageSize(std::string_view text, std::string_view what);

// "test:N" / "train:N": the split name and the index N >= 0 (whole token).
struct ViewSpec {
  std::string split;
  size_t index = 0;
};
StatusOr<ViewSpec> ParseViewSpec(std::string_view text, std::string_view what);

// CLI11 options whose value goes through the parsers above; a bad value throws
// CLI::ValidationError (exit 2, with the option and the parser's message). The default
// shown in --help is the variable's value at registration.
CLI::Option* AddInt(CLI::App& app, const std::string& name, int* value, long long min, long long max,
                    const std::string& help);
CLI::Option* AddInt64(CLI::App& app, const std::string& name, long long* value, long long min, long long max,
                      const std::string& help);
CLI::Option* AddUint64(CLI::App& app, const std::string& name, uint64_t* value, const std::string& help);
CLI::Option* AddReal(CLI::App& app, const std::string& name, double* value, double min, double max,
                     const std::string& help);
// A fixed number of finite reals given as separate tokens (e.g. --intrinsics fx fy cx cy).
CLI::Option* AddReals(CLI::App& app, const std::string& name, std::vector<double>* values, int count,
                      const std::string& help);
// Comma-separated integers in [min, max] (e.g. --test-cameras 0,10).
CLI::Option* AddIntList(CLI::App& app, const std::string& name, std::vector<int>* values, long long min,
                        long long max, const std::string& help);

}  // namespace atex::cli
