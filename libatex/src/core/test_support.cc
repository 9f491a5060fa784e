#include "core/test_support.h"

#include <atomic>
#include <cstdlib>
#include <random>
#include <system_error>

namespace atex::testing {

std::filesystem::path DataDir() {
  for (const char* var : {"ATEX_DATA_DIR", "ATEX_DATA_DIR_DEFAULT"}) {
    const char* value = std::getenv(var);
    if (value != nullptr && *value != '\0' && std::filesystem::exists(value)) {
      return std::filesystem::path(value);
    }
  }
  return {};
}

bool DataRequired() {
  const char* value = std::getenv("ATEX_REQUIRE_DATA");
  return value != nullptr && std::string(value) == "1";
}

std::filesystem::path SourceDir() {
  const char* value = std::getenv("ATEX_SOURCE_DIR");
  return value ? std::filesystem::path(value) : std::filesystem::current_path();
}

TempDir::TempDir() {
  static std::atomic<int> counter{0};
  std::random_device rd;
  const char* bin = std::getenv("ATEX_BINARY_DIR");
  std::filesystem::path base = bin ? std::filesystem::path(bin) / "test_tmp" : std::filesystem::temp_directory_path();
  path_ = base / ("atex_" + std::to_string(rd()) + "_" + std::to_string(counter++));
  std::filesystem::create_directories(path_);
}

TempDir::~TempDir() {
  std::error_code ec;
  std::filesystem::remove_all(path_, ec);
}

}  // namespace atex::testing
