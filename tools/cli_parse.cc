#include "cli_parse.h"

#include <cctype>
#include <charconv>
#include <cmath>
#include <map>

namespace atex::cli {

namespace {

// `text` without one leading '+' (std::from_chars does not take it); empty when that
// leaves nothing or a second sign.
std::string_view WithoutPlus(std::string_view text) {
  if (!text.empty() && text[0] == '+') {
    text.remove_prefix(1);
    if (text.empty() || text[0] == '+' || text[0] == '-') return {};
  }
  return text;
}

std::string Quote(std::string_view text) { return StrCat("'", text, "'"); }

}  // namespace

StatusOr<long long> ParseInteger(std::string_view text, long long min, long long max, std::string_view what) {
  const std::string_view digits = WithoutPlus(text);
  long long value = 0;
  const auto [end, error] = std::from_chars(digits.data(), digits.data() + digits.size(), value);
  if (digits.empty() || end != digits.data() + digits.size() ||
      (error != std::errc() && error != std::errc::result_out_of_range)) {
    return MakeError(StatusCode::kInvalidArgument, what, " ", Quote(text), " is not an integer");
  }
  if (error == std::errc::result_out_of_range || value < min || value > max) {
    return MakeError(StatusCode::kOutOfRange, what, " ", Quote(text), " is outside [", min, ", ", max, "]");
  }
  return value;
}

StatusOr<double> ParseReal(std::string_view text, double min, double max, std::string_view what) {
  const std::string_view number = WithoutPlus(text);
  double value = 0;
  const auto [end, error] =
      std::from_chars(number.data(), number.data() + number.size(), value, std::chars_format::general);
  if (number.empty() || end != number.data() + number.size() ||
      (error != std::errc() && error != std::errc::result_out_of_range)) {
    return MakeError(StatusCode::kInvalidArgument, what, " ", Quote(text), " is not a number");
  }
  if (error == std::errc::result_out_of_range || !std::isfinite(value)) {
    return MakeError(StatusCode::kOutOfRange, what, " ", Quote(text), " is not a finite number");
  }
  if (value < min || value > max) {
    return MakeError(StatusCode::kOutOfRange, what, " ", Quote(text), " is outside [", min, ", ", max, "]");
  }
  return value;
}

StatusOr<uint64_t> ParseByteSize(std::string_view text, std::string_view what) {
  size_t pos = 0;
  while (pos < text.size() && (std::isdigit(static_cast<unsigned char>(text[pos])) || text[pos] == '.')) ++pos;
  const std::string_view number = text.substr(0, pos);
  std::string_view rest = text.substr(pos);
  if (!rest.empty() && rest[0] == ' ') rest.remove_prefix(1);
  std::string unit;
  for (char c : rest) unit += static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  static const std::map<std::string, double> kUnits = {
      {"", 1.0},     {"b", 1.0},           {"k", 1024.0},        {"kib", 1024.0},      {"kb", 1e3},
      {"m", 1048576.0}, {"mib", 1048576.0}, {"mb", 1e6},          {"g", 1073741824.0},  {"gib", 1073741824.0},
      {"gb", 1e9}};
  const auto unit_it = kUnits.find(unit);
  double value = 0;
  const auto [end, error] = std::from_chars(number.data(), number.data() + number.size(), value,
                                            std::chars_format::fixed);
  if (number.empty() || unit_it == kUnits.end() || end != number.data() + number.size() || error != std::errc()) {
    return MakeError(StatusCode::kInvalidArgument, what, " ", Quote(text),
                     " is not a number with an optional unit (B, KiB, MiB, GiB, KB, MB, GB)");
  }
  const double bytes = value * unit_it->second;
  if (!(bytes >= 1.0) || bytes > 9.2e18) {
    return MakeError(StatusCode::kOutOfRange, what, " ", Quote(text), " is outside [1 B, 8 EiB]");
  }
  return static_cast<uint64_t>(std::floor(bytes));
}

StatusOr<std::vector<uint64_t>> ParseByteSizeList(std::string_view text, std::string_view what,
                                                  std::vector<std::string>* pieces) {
  std::vector<uint64_t> sizes;
  std::vector<std::string> texts;
  for (size_t start = 0; start <= text.size();) {
    const size_t comma = std::min(text.find(',', start), text.size());
    texts.emplace_back(text.substr(start, comma - start));
    ATEX_ASSIGN_OR_RETURN(const uint64_t size, ParseByteSize(texts.back(), what));
    for (size_t k = 0; k < sizes.size(); ++k) {
      if (sizes[k] == size) {
        return MakeError(StatusCode::kInvalidArgument, what, " lists ", Quote(texts[k]), " and ", Quote(texts.back()),
                         ", the same size (", size, " bytes) twice");
      }
    }
    sizes.push_back(size);
    start = comma + 1;
  }
  if (pieces) *pieces = std::move(texts);
  return sizes;
}

StatusOr<ImageSize> ParseImageSize(std::string_view text, std::string_view what) {
  const size_t x = text.find('x');
  if (x == std::string_view::npos) {
    return MakeError(StatusCode::kInvalidArgument, what, " ", Quote(text), " is not WxH (e.g. 1352x1014)");
  }
  const std::string width_what = StrCat(what, " width"), height_what = StrCat(what, " height");
  ATEX_ASSIGN_OR_RETURN(const long long w, ParseInteger(text.substr(0, x), 1, 65536, width_what));
  ATEX_ASSIGN_OR_RETURN(const long long h, ParseInteger(text.substr(x + 1), 1, 65536, height_what));
  return ImageSize{static_cast<int>(w), static_cast<int>(h)};
}

StatusOr<ViewSpec> ParseViewSpec(std::string_view text, std::string_view what) {
  const size_t colon = text.find(':');
  const std::string_view split = text.substr(0, colon);
  if (colon == std::string_view::npos || (split != "test" && split != "train")) {
    return MakeError(StatusCode::kInvalidArgument, what, " ", Quote(text), " is not test:N or train:N");
  }
  ATEX_ASSIGN_OR_RETURN(const long long index, ParseInteger(text.substr(colon + 1), 0, std::numeric_limits<int>::max(),
                                                           StrCat(what, " ", Quote(text), ": index")));
  return ViewSpec{std::string(split), static_cast<size_t>(index)};
}

namespace {

// Registers `name` as a one-token option whose text `apply` parses and stores.
template <typename Apply>
CLI::Option* AddParsed(CLI::App& app, const std::string& name, const std::string& help, const std::string& shown,
                       Apply apply) {
  const std::string label = name.substr(0, name.find(','));
  CLI::Option* option = app.add_option_function<std::string>(
      name,
      [label, apply](const std::string& text) {
        const Status s = apply(text, label);
        if (!s.ok()) throw CLI::ValidationError(label, s.message());
      },
      help);
  if (!shown.empty()) option->default_str(shown);
  return option;
}

template <typename T>
std::string Shown(T value) {
  std::ostringstream out;
  out << value;
  return out.str();
}

}  // namespace

CLI::Option* AddInt(CLI::App& app, const std::string& name, int* value, long long min, long long max,
                    const std::string& help) {
  return AddParsed(app, name, help, Shown(*value), [value, min, max](const std::string& text, const std::string& what) {
    StatusOr<long long> v = ParseInteger(text, min, max, what);
    if (v.ok()) *value = static_cast<int>(*v);
    return v.status();
  });
}

CLI::Option* AddInt64(CLI::App& app, const std::string& name, long long* value, long long min, long long max,
                      const std::string& help) {
  return AddParsed(app, name, help, Shown(*value), [value, min, max](const std::string& text, const std::string& what) {
    StatusOr<long long> v = ParseInteger(text, min, max, what);
    if (v.ok()) *value = *v;
    return v.status();
  });
}

CLI::Option* AddUint64(CLI::App& app, const std::string& name, uint64_t* value, const std::string& help) {
  return AddParsed(app, name, help, Shown(*value), [value](const std::string& text, const std::string& what) {
    StatusOr<long long> v = ParseInteger(text, 0, std::numeric_limits<long long>::max(), what);
    if (v.ok()) *value = static_cast<uint64_t>(*v);
    return v.status();
  });
}

CLI::Option* AddReal(CLI::App& app, const std::string& name, double* value, double min, double max,
                     const std::string& help) {
  const std::string shown = std::isfinite(*value) ? Shown(*value) : "";
  return AddParsed(app, name, help, shown, [value, min, max](const std::string& text, const std::string& what) {
    StatusOr<double> v = ParseReal(text, min, max, what);
    if (v.ok()) *value = *v;
    return v.status();
  });
}

CLI::Option* AddReals(CLI::App& app, const std::string& name, std::vector<double>* values, int count,
                      const std::string& help) {
  const std::string label = name.substr(0, name.find(','));
  CLI::Option* option = app.add_option_function<std::vector<std::string>>(
      name,
      [label, values](const std::vector<std::string>& texts) {
        values->clear();
        for (const std::string& text : texts) {
          StatusOr<double> v = ParseReal(text, -std::numeric_limits<double>::max(),
                                         std::numeric_limits<double>::max(), label);
          if (!v.ok()) throw CLI::ValidationError(label, v.status().message());
          values->push_back(*v);
        }
      },
      help);
  option->expected(count);
  return option;
}

CLI::Option* AddIntList(CLI::App& app, const std::string& name, std::vector<int>* values, long long min,
                        long long max, const std::string& help) {
  const std::string label = name.substr(0, name.find(','));
  CLI::Option* option = app.add_option_function<std::vector<std::string>>(
      name,
      [label, values, min, max](const std::vector<std::string>& texts) {
        values->clear();
        for (const std::string& text : texts) {
          StatusOr<long long> v = ParseInteger(text, min, max, label);
          if (!v.ok()) throw CLI::ValidationError(label, v.status().message());
          values->push_back(static_cast<int>(*v));
        }
      },
      help);
  option->delimiter(',');
  return option;
}

}  // namespace atex::cli
