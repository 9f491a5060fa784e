// Whitespace tokens and strict number parsing for the line-based text formats of this module
// (COLMAP cameras.txt, images.txt, points3D.txt). Not a public header.
#pragma once

#include <charconv>
#include <cmath>
#include <string_view>
#include <system_error>
#include <type_traits>
#include <vector>

namespace atex {

// The tokens of `line` separated by spaces, tabs and carriage returns (views into `line`).
inline std::vector<std::string_view> SplitTokens(std::string_view line) {
  std::vector<std::string_view> out;
  size_t i = 0;
  while (i < line.size()) {
    while (i < line.size() && (line[i] == ' ' || line[i] == '\t' || line[i] == '\r')) ++i;
    size_t j = i;
    while (j < line.size() && line[j] != ' ' && line[j] != '\t' && line[j] != '\r') ++j;
    if (j > i) out.push_back(line.substr(i, j - i));
    i = j;
  }
  return out;
}

// Parses the whole token as a number; false on trailing characters, overflow, or (floating point)
// a NaN or infinity.
template <typename T>
bool ParseNumber(std::string_view token, T* value) {
  auto [ptr, ec] = std::from_chars(token.data(), token.data() + token.size(), *value);
  if (ec != std::errc() || ptr != token.data() + token.size()) return false;
  if constexpr (std::is_floating_point_v<T>) return std::isfinite(*value);
  return true;
}

}  // namespace atex
