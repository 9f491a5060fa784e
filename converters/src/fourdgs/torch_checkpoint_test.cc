// ReadTorchStateDict on hand-built torch.save archives: layouts, dtypes,
// strided views, byte order, and hostile archives.
#include <gtest/gtest.h>

#include <bit>
#include <cmath>
#include <cstring>

#include "atex/converters/fourdgs.h"
#include "atex/zip.h"
#include "fourdgs/torch_test_util.h"

namespace atex {
namespace {

using fourdgs_testing::FloatBytes;
using fourdgs_testing::PickleBuilder;
using fourdgs_testing::StateDictArchive;
using fourdgs_testing::StateDictPickle;
using fourdgs_testing::TensorSpec;

StatusOr<TorchStateDict> Read(const std::vector<uint8_t>& archive) {
  return ReadTorchStateDict(archive.data(), archive.size(), "test.pth");
}

// An archive from a custom pickle and raw storage records.
std::vector<uint8_t> Archive(const PickleBuilder& pickle,
                             const std::vector<std::pair<std::string, std::vector<uint8_t>>>& records,
                             const std::string& byteorder = "little") {
  ZipWriter zip;
  EXPECT_TRUE(zip.Add("m/data.pkl", pickle.bytes().data(), pickle.bytes().size(), false).ok());
  if (!byteorder.empty()) {
    EXPECT_TRUE(
        zip.Add("m/byteorder", reinterpret_cast<const uint8_t*>(byteorder.data()), byteorder.size(), false).ok());
  }
  for (const auto& [name, bytes] : records)
    EXPECT_TRUE(zip.Add(StrCat("m/data/", name), bytes.data(), bytes.size(), false).ok());
  return zip.Finish();
}

// {'t': tensor over storage "0"} with the given view parameters.
PickleBuilder OneTensor(const std::string& storage_type, int64_t numel, int64_t offset,
                        const std::vector<int64_t>& shape, const std::vector<int64_t>& stride) {
  PickleBuilder p;
  p.Proto().EmptyDict().Str("t").Tensor("0", storage_type, numel, offset, shape, stride).SetItem().Stop();
  return p;
}

TEST(TorchCheckpoint, ReadsContiguousFloatTensorsInOrder) {
  const std::vector<TensorSpec> specs = {{"grid.0", {1, 2, 2, 3}, {1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12}},
                                         {"bias", {2}, {-0.5f, 0.25f}},
                                         {"scalar", {}, {3.5f}}};
  for (bool deflate : {false, true}) {
    auto state = Read(StateDictArchive(specs, "deformation/", deflate));
    ASSERT_TRUE(state.ok()) << state.status().ToString();
    ASSERT_EQ(state->tensors.size(), 3u);
    for (size_t i = 0; i < specs.size(); ++i) {
      const TorchTensor& t = state->tensors[i];
      EXPECT_EQ(t.name, specs[i].name);
      EXPECT_EQ(t.shape, specs[i].shape);
      EXPECT_EQ(t.values, specs[i].values);
      EXPECT_EQ(t.dtype, "float32");
      EXPECT_TRUE(t.floating);
    }
    EXPECT_EQ(state->Find("bias"), &state->tensors[1]);
    EXPECT_EQ(state->Find("nope"), nullptr);
  }
}

TEST(TorchCheckpoint, StridedViewsAndOffsetsAreMaterialisedRowMajor) {
  // Storage 0..11 viewed as the transpose of a [3][4] matrix, from offset 0,
  // and a [2][2] window starting at element 5 with row stride 4.
  std::vector<float> storage(12);
  for (int i = 0; i < 12; ++i) storage[i] = static_cast<float>(i);
  auto transposed = Read(Archive(OneTensor("FloatStorage", 12, 0, {4, 3}, {1, 4}), {{"0", FloatBytes(storage)}}));
  ASSERT_TRUE(transposed.ok()) << transposed.status().ToString();
  EXPECT_EQ(transposed->tensors[0].values, (std::vector<float>{0, 4, 8, 1, 5, 9, 2, 6, 10, 3, 7, 11}));
  auto window = Read(Archive(OneTensor("FloatStorage", 12, 5, {2, 2}, {4, 1}), {{"0", FloatBytes(storage)}}));
  ASSERT_TRUE(window.ok()) << window.status().ToString();
  EXPECT_EQ(window->tensors[0].values, (std::vector<float>{5, 6, 9, 10}));
}

TEST(TorchCheckpoint, OtherFloatingDtypesAreConvertedAndIntegersKeepTheirShape) {
  std::vector<uint8_t> f64;
  for (double v : {1.5, -2.25, 1e-3}) {
    const uint64_t u = std::bit_cast<uint64_t>(v);
    for (int k = 0; k < 8; ++k) f64.push_back(static_cast<uint8_t>(u >> (8 * k)));
  }
  auto d = Read(Archive(OneTensor("DoubleStorage", 3, 0, {3}, {1}), {{"0", f64}}));
  ASSERT_TRUE(d.ok()) << d.status().ToString();
  EXPECT_EQ(d->tensors[0].dtype, "float64");
  EXPECT_EQ(d->tensors[0].values, (std::vector<float>{1.5f, -2.25f, 1e-3f}));

  // float16: 1.0 = 0x3c00, -2.0 = 0xc000, 65504 = 0x7bff, smallest subnormal 2^-24 = 0x0001.
  auto h = Read(
      Archive(OneTensor("HalfStorage", 4, 0, {4}, {1}), {{"0", {0x00, 0x3c, 0x00, 0xc0, 0xff, 0x7b, 0x01, 0x00}}}));
  ASSERT_TRUE(h.ok()) << h.status().ToString();
  EXPECT_EQ(h->tensors[0].values, (std::vector<float>{1.0f, -2.0f, 65504.0f, std::ldexp(1.0f, -24)}));

  // bfloat16: the top half of float32 1.5 = 0x3fc00000.
  auto b = Read(Archive(OneTensor("BFloat16Storage", 1, 0, {1}, {1}), {{"0", {0xc0, 0x3f}}}));
  ASSERT_TRUE(b.ok()) << b.status().ToString();
  EXPECT_EQ(b->tensors[0].values, std::vector<float>{1.5f});

  auto l = Read(Archive(OneTensor("LongStorage", 2, 0, {2}, {1}), {{"0", std::vector<uint8_t>(16, 0)}}));
  ASSERT_TRUE(l.ok()) << l.status().ToString();
  EXPECT_FALSE(l->tensors[0].floating);
  EXPECT_EQ(l->tensors[0].dtype, "int64");
  EXPECT_EQ(l->tensors[0].shape, std::vector<int64_t>{2});
  EXPECT_TRUE(l->tensors[0].values.empty());
}

TEST(TorchCheckpoint, BigEndianStoragesAreSwapped) {
  std::vector<uint8_t> be;
  for (float v : {1.0f, -3.5f}) {
    const uint32_t u = std::bit_cast<uint32_t>(v);
    for (int k = 3; k >= 0; --k) be.push_back(static_cast<uint8_t>(u >> (8 * k)));
  }
  auto s = Read(Archive(OneTensor("FloatStorage", 2, 0, {2}, {1}), {{"0", be}}, "big"));
  ASSERT_TRUE(s.ok()) << s.status().ToString();
  EXPECT_EQ(s->tensors[0].values, (std::vector<float>{1.0f, -3.5f}));
  // Older archives have no byteorder record: little-endian.
  auto old = Read(Archive(OneTensor("FloatStorage", 2, 0, {2}, {1}), {{"0", FloatBytes({1.0f, -3.5f})}}, ""));
  ASSERT_TRUE(old.ok()) << old.status().ToString();
  EXPECT_EQ(old->tensors[0].values, (std::vector<float>{1.0f, -3.5f}));
  EXPECT_EQ(Read(Archive(OneTensor("FloatStorage", 2, 0, {2}, {1}), {{"0", be}}, "middle")).status().code(),
            StatusCode::kCorrupt);
}

TEST(TorchCheckpoint, HostileArchivesAreRefused) {
  const std::vector<uint8_t> twelve = FloatBytes(std::vector<float>(12, 1.0f));
  struct Case {
    const char* name;
    std::vector<uint8_t> archive;
    StatusCode code;
    const char* part;
  };
  std::vector<Case> cases = {
      {"storage record missing", Archive(OneTensor("FloatStorage", 12, 0, {12}, {1}), {}), StatusCode::kCorrupt,
       "no record m/data/0"},
      {"storage size differs from numel", Archive(OneTensor("FloatStorage", 13, 0, {12}, {1}), {{"0", twelve}}),
       StatusCode::kCorrupt, "announces 13 elements"},
      {"view beyond the storage", Archive(OneTensor("FloatStorage", 12, 4, {3, 4}, {4, 1}), {{"0", twelve}}),
       StatusCode::kCorrupt, "reaches element 15"},
      {"huge stride", Archive(OneTensor("FloatStorage", 12, 0, {5}, {int64_t{1} << 61}), {{"0", twelve}}),
       StatusCode::kLimitExceeded, "overflows"},
      {"huge shape", Archive(OneTensor("FloatStorage", 12, 0, {int64_t{1} << 40, int64_t{1} << 40}, {0, 0}),
                             {{"0", twelve}}),
       StatusCode::kLimitExceeded, "overflows"},
      {"expanded view", Archive(OneTensor("FloatStorage", 12, 0, {100}, {0}), {{"0", twelve}}),
       StatusCode::kUnsupported, "expanded"},
      {"negative stride", Archive(OneTensor("FloatStorage", 12, 11, {12}, {-1}), {{"0", twelve}}),
       StatusCode::kCorrupt, "negative"},
      {"negative offset", Archive(OneTensor("FloatStorage", 12, -1, {12}, {1}), {{"0", twelve}}),
       StatusCode::kCorrupt, "negative storage offset"},
      {"not a dict", Archive(PickleBuilder().Proto().None().Stop(), {}), StatusCode::kUnsupported, "not a dict"},
      {"value that is not a tensor", Archive(PickleBuilder().Proto().EmptyDict().Str("a").Int(1).SetItem().Stop(), {}),
       StatusCode::kUnsupported, "'a' is not a tensor"},
      {"integer key", Archive(PickleBuilder().Proto().EmptyDict().Int(1).Int(1).SetItem().Stop(), {}),
       StatusCode::kUnsupported, "not a string"},
  };
  {
    ZipWriter zip;  // two data.pkl records
    const std::vector<uint8_t> pickle = StateDictPickle({});
    EXPECT_TRUE(zip.Add("a/data.pkl", pickle.data(), pickle.size(), false).ok());
    EXPECT_TRUE(zip.Add("b/data.pkl", pickle.data(), pickle.size(), false).ok());
    cases.push_back({"two data.pkl", zip.Finish(), StatusCode::kCorrupt, "found 2"});
  }
  {
    ZipWriter zip;
    const std::string text = "hello";
    EXPECT_TRUE(zip.Add("readme.txt", reinterpret_cast<const uint8_t*>(text.data()), text.size(), false).ok());
    cases.push_back({"zip without data.pkl", zip.Finish(), StatusCode::kCorrupt, "found 0"});
  }
  cases.push_back({"not a zip", std::vector<uint8_t>(100, 'x'), StatusCode::kBadMagic, ""});
  cases.push_back({"legacy format",
                   {0x80, 0x02, 0x8a, 0x0a, 0x6c, 0xfc, 0x9c, 0x46, 0xf9, 0x20, 0x6a, 0xa8, 0x50, 0x19, 0x2e},
                   StatusCode::kUnsupported, "legacy"});
  for (const Case& c : cases) {
    auto state = Read(c.archive);
    ASSERT_FALSE(state.ok()) << c.name;
    EXPECT_EQ(state.status().code(), c.code) << c.name << ": " << state.status().ToString();
    EXPECT_NE(state.status().message().find(c.part), std::string::npos) << c.name << ": " << state.status().ToString();
    EXPECT_NE(state.status().message().find("test.pth"), std::string::npos) << c.name;
  }
}

TEST(TorchCheckpoint, SharedStorageViewsCannotMultiplyMemory) {
  // 64 tensors, each a full view of the same 1000-element storage: the
  // materialised total is bounded by the limit.
  PickleBuilder p;
  p.Proto().EmptyDict().Mark();
  for (int i = 0; i < 64; ++i) p.Str(StrCat("t", i)).Tensor("0", "FloatStorage", 1000, 0, {1000}, {1});
  p.SetItems().Stop();
  const auto archive = Archive(p, {{"0", FloatBytes(std::vector<float>(1000, 2.0f))}});
  TorchReadLimits limits;
  limits.max_elements = 20000;
  auto state = ReadTorchStateDict(archive.data(), archive.size(), "test.pth", limits);
  EXPECT_EQ(state.status().code(), StatusCode::kLimitExceeded);
  limits.max_elements = 100000;
  EXPECT_TRUE(ReadTorchStateDict(archive.data(), archive.size(), "test.pth", limits).ok());
}

TEST(TorchCheckpoint, EveryTruncationFailsCleanly) {
  const std::vector<uint8_t> archive = StateDictArchive({{"w", {2, 3}, {1, 2, 3, 4, 5, 6}}});
  for (size_t n = 0; n < archive.size(); n += 7) {
    EXPECT_FALSE(ReadTorchStateDict(archive.data(), n, "cut.pth").ok()) << n;
  }
  // Single-byte corruptions anywhere never crash (most are caught by CRCs).
  for (size_t i = 0; i < archive.size(); ++i) {
    std::vector<uint8_t> bad = archive;
    bad[i] ^= 0x5a;
    (void)ReadTorchStateDict(bad.data(), bad.size(), "flip.pth");
  }
}

}  // namespace
}  // namespace atex
