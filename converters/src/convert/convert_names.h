// Format names and frame ranges of `atex convert` (atex/converters/convert.h), and the two
// helpers convert.cc shares with them.
#pragma once

#include <string>
#include <string_view>

#include "atex/converters/convert.h"
#include "atex/status.h"

namespace atex::convert_detail {

// ASCII lower case (extensions, format names, axes names).
std::string Lower(std::string_view s);

// Checks what ParseFrameRange checks, for ranges built in code.
Status CheckFrameRange(const FrameRange& r);

}  // namespace atex::convert_detail
