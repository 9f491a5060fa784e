// Helpers for libatex's tests (not part of the public API).
#pragma once

#include <filesystem>
#include <string>

namespace atex::testing {

// Folder of the real third-party data (../shared/data beside the checkout), taken
// from $ATEX_DATA_DIR, else the configured default. Empty if it does not exist.
std::filesystem::path DataDir();

// Path of a file under DataDir(). When the data folder is missing, the calling
// test is skipped with a message, unless $ATEX_REQUIRE_DATA=1 (CI), where it fails.
#define ATEX_REQUIRE_DATA_FILE(var, relative)                                     \
  std::filesystem::path var = ::atex::testing::DataDir() / (relative);            \
  if (!std::filesystem::exists(var)) {                                            \
    if (::atex::testing::DataRequired()) {                                        \
      FAIL() << "real test data missing: " << var;                                \
    } else {                                                                      \
      GTEST_SKIP() << "real test data missing (set ATEX_DATA_DIR): " << var;      \
    }                                                                             \
  }

bool DataRequired();

// A fresh empty folder under the build tree (or /tmp), removed by the destructor.
class TempDir {
 public:
  TempDir();
  ~TempDir();
  TempDir(const TempDir&) = delete;
  TempDir& operator=(const TempDir&) = delete;
  const std::filesystem::path& path() const { return path_; }
  std::filesystem::path operator/(const std::string& name) const { return path_ / name; }

 private:
  std::filesystem::path path_;
};

// The repository's source folder ($ATEX_SOURCE_DIR, set by CTest).
std::filesystem::path SourceDir();

}  // namespace atex::testing
