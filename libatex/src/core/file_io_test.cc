#include "atex/file_io.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>

#include "core/test_support.h"

namespace atex {
namespace {

std::vector<std::string> Names(const std::filesystem::path& dir) {
  std::vector<std::string> names;
  for (const auto& e : std::filesystem::directory_iterator(dir)) names.push_back(e.path().filename().string());
  std::sort(names.begin(), names.end());
  return names;
}

TEST(FileIo, WriteThenReadGivesTheSameBytes) {
  testing::TempDir dir;
  std::vector<uint8_t> bytes(100000);
  for (size_t i = 0; i < bytes.size(); ++i) bytes[i] = static_cast<uint8_t>(i * 31);
  const std::string path = (dir / "a.bin").string();
  ASSERT_TRUE(WriteFileAtomic(path, bytes).ok());
  auto read = ReadFileBytes(path);
  ASSERT_TRUE(read.ok()) << read.status().ToString();
  EXPECT_EQ(*read, bytes);
  EXPECT_EQ(Names(dir.path()), std::vector<std::string>{"a.bin"});  // no temporary left behind
}

TEST(FileIo, EmptyFile) {
  testing::TempDir dir;
  const std::string path = (dir / "empty").string();
  ASSERT_TRUE(WriteFileAtomic(path, nullptr, 0).ok());
  auto read = ReadFileBytes(path);
  ASSERT_TRUE(read.ok());
  EXPECT_TRUE(read->empty());
}

TEST(FileIo, OverwriteReplacesTheWholeFile) {
  testing::TempDir dir;
  const std::string path = (dir / "f").string();
  ASSERT_TRUE(WriteFileAtomic(path, std::vector<uint8_t>(1000, 1)).ok());
  ASSERT_TRUE(WriteFileAtomic(path, std::vector<uint8_t>(10, 2)).ok());
  auto read = ReadFileBytes(path);
  ASSERT_TRUE(read.ok());
  EXPECT_EQ(*read, std::vector<uint8_t>(10, 2));
}

TEST(FileIo, MissingFileIsNotFound) {
  testing::TempDir dir;
  auto read = ReadFileBytes((dir / "nope").string());
  ASSERT_FALSE(read.ok());
  EXPECT_EQ(read.status().code(), StatusCode::kNotFound);
  EXPECT_NE(read.status().message().find("nope"), std::string::npos);
}

TEST(FileIo, DirectoryIsAnIoError) {
  testing::TempDir dir;
  auto read = ReadFileBytes(dir.path().string());
  ASSERT_FALSE(read.ok());
  EXPECT_EQ(read.status().code(), StatusCode::kIoError);
}

TEST(FileIo, SizeLimit) {
  testing::TempDir dir;
  const std::string path = (dir / "big").string();
  ASSERT_TRUE(WriteFileAtomic(path, std::vector<uint8_t>(1001, 0)).ok());
  auto read = ReadFileBytes(path, 1000);
  ASSERT_FALSE(read.ok());
  EXPECT_EQ(read.status().code(), StatusCode::kLimitExceeded);
  EXPECT_TRUE(ReadFileBytes(path, 1001).ok());
}

TEST(FileIo, FailedWriteLeavesTheOldFileAndNoTemporary) {
  testing::TempDir dir;
  // The destination is an existing non-empty directory: rename() must fail.
  std::filesystem::create_directories(dir / "target" / "child");
  const Status s = WriteFileAtomic((dir / "target").string(), std::vector<uint8_t>(10, 7));
  EXPECT_FALSE(s.ok());
  EXPECT_TRUE(std::filesystem::is_directory(dir / "target" / "child"));
  EXPECT_EQ(Names(dir.path()), std::vector<std::string>{"target"});
}

TEST(FileIo, MissingFolderFails) {
  testing::TempDir dir;
  const Status s = WriteFileAtomic((dir / "no" / "such" / "file").string(), std::vector<uint8_t>(3, 1));
  EXPECT_FALSE(s.ok());
  EXPECT_EQ(s.code(), StatusCode::kNotFound);
}

}  // namespace
}  // namespace atex
