// Parsing sizes for `atex fit --budget` (fit.h).
#include <cctype>
#include <cmath>
#include <map>
#include <string>

#include "atex/fit.h"

namespace atex::fit {

StatusOr<uint64_t> ParseByteSize(const std::string& text) {
  size_t pos = 0;
  while (pos < text.size() && (std::isdigit(static_cast<unsigned char>(text[pos])) || text[pos] == '.')) ++pos;
  const std::string number = text.substr(0, pos);
  std::string unit;
  for (size_t k = pos; k < text.size(); ++k) {
    if (!std::isspace(static_cast<unsigned char>(text[k]))) unit += static_cast<char>(std::tolower(text[k]));
  }
  static const std::map<std::string, double> kUnits = {
      {"", 1.0},           {"b", 1.0},           {"k", 1024.0},          {"kib", 1024.0},
      {"kb", 1e3},         {"m", 1048576.0},     {"mib", 1048576.0},     {"mb", 1e6},
      {"g", 1073741824.0}, {"gib", 1073741824.0}, {"gb", 1e9}};
  const auto unit_it = kUnits.find(unit);
  if (number.empty() || number.find('.') != number.rfind('.') || unit_it == kUnits.end()) {
    return MakeError(StatusCode::kInvalidArgument, "size '", text,
                     "' is not a number with an optional unit (B, KiB, MiB, GiB, KB, MB, GB)");
  }
  const double bytes = std::stod(number) * unit_it->second;
  if (!(bytes >= 1.0) || bytes > 1.8e19) {
    return MakeError(StatusCode::kInvalidArgument, "size '", text, "' is out of range");
  }
  return static_cast<uint64_t>(std::floor(bytes));
}

}  // namespace atex::fit
