// The safe unpickler on hand-assembled protocol-2 byte strings: what
// torch.save writes is accepted; everything else is refused with the opcode
// or global and its byte offset.
#include "fourdgs/torch_pickle.h"

#include <gtest/gtest.h>

#include "fourdgs/torch_test_util.h"

namespace atex::fourdgs_internal {
namespace {

using fourdgs_testing::PickleBuilder;
using fourdgs_testing::StateDictPickle;
using fourdgs_testing::TensorSpec;

StatusOr<PyRef> Parse(const PickleBuilder& p, const PickleLimits& limits = {}) {
  return Unpickle(p.bytes().data(), p.bytes().size(), "test.pkl", limits);
}
StatusOr<PyRef> Parse(const std::vector<uint8_t>& bytes) {
  return Unpickle(bytes.data(), bytes.size(), "test.pkl");
}

TEST(TorchPickle, StateDictWithMetadataAndMemo) {
  const std::vector<uint8_t> bytes =
      StateDictPickle({{"a.weight", {2, 3}, {1, 2, 3, 4, 5, 6}}, {"poc", {4}, {1, 2, 4, 8}}});
  auto parsed = Parse(bytes);
  ASSERT_TRUE(parsed.ok()) << parsed.status().ToString();
  const PyObject& root = **parsed;
  ASSERT_EQ(root.kind, PyKind::kDict);
  ASSERT_EQ(root.entries.size(), 2u);
  EXPECT_EQ(root.entries[0].first->text, "a.weight");
  const PyObject& t = *root.entries[0].second;
  ASSERT_EQ(t.kind, PyKind::kTensor);
  EXPECT_EQ(t.shape, (std::vector<int64_t>{2, 3}));
  EXPECT_EQ(t.stride, (std::vector<int64_t>{3, 1}));
  EXPECT_EQ(t.storage_offset, 0);
  EXPECT_EQ(t.storage->text, "0");
  EXPECT_EQ(t.storage->location, "cpu");
  EXPECT_EQ(t.storage->numel, 6);
  EXPECT_EQ(t.storage->dtype, TorchDtype::kFloat32);
  EXPECT_EQ(root.entries[1].second->storage->text, "1");
}

// The exact opcode sequence CPython writes for torch.save({'w': tensor}) with
// memoised globals and strings (BINPUT / BINGET), as disassembled by pickletools.
TEST(TorchPickle, MemoisedGlobalsAndStringsAsCPythonWritesThem) {
  PickleBuilder p;
  p.Proto(2).Global("collections", "OrderedDict").Put(0).EmptyTuple().Reduce().Put(1).Mark();
  for (int i = 0; i < 2; ++i) {
    p.Str(i == 0 ? "x" : "y").Put(2 + 10 * i);
    if (i == 0) {
      p.Global("torch._utils", "_rebuild_tensor_v2").Put(3);
    } else {
      p.Get(3);
    }
    p.Mark().Mark();
    if (i == 0) {
      p.Str("storage").Put(4).Global("torch", "FloatStorage").Put(5);
    } else {
      p.Get(4).Get(5);
    }
    p.Str(std::to_string(i));
    if (i == 0) {
      p.Str("cpu").Put(7);
    } else {
      p.Get(7);
    }
    p.Int(3).TupleFromMark().Put(8 + 10 * i).PersId();
    p.Int(0).Int(3).Tuple(1).Int(1).Tuple(1).Bool(false).Get(0).EmptyTuple().Reduce().TupleFromMark().Reduce();
  }
  p.SetItems().Stop();
  auto parsed = Parse(p);
  ASSERT_TRUE(parsed.ok()) << parsed.status().ToString();
  ASSERT_EQ((*parsed)->entries.size(), 2u);
  EXPECT_EQ((*parsed)->entries[1].second->storage->location, "cpu");
}

TEST(TorchPickle, IntegersOfEveryWidth) {
  for (int64_t v : {int64_t{0}, int64_t{255}, int64_t{256}, int64_t{65535}, int64_t{65536}, int64_t{-1},
                    int64_t{-129}, int64_t{2147483647}, int64_t{2147483648}, int64_t{-2147483649},
                    int64_t{1} << 40, int64_t{-1} << 50}) {
    PickleBuilder p;
    p.Proto().Int(v).Stop();
    auto parsed = Parse(p);
    ASSERT_TRUE(parsed.ok()) << v << ": " << parsed.status().ToString();
    EXPECT_EQ((*parsed)->kind, PyKind::kInt);
    EXPECT_EQ((*parsed)->integer, v);
  }
  PickleBuilder big;  // LONG1 of 9 bytes
  big.Proto().Op(0x8a).Op(9).Raw({1, 2, 3, 4, 5, 6, 7, 8, 9}).Stop();
  EXPECT_EQ(Parse(big).status().code(), StatusCode::kUnsupported);
}

TEST(TorchPickle, ParameterRebuildAndOtherStorageTypes) {
  PickleBuilder p;
  p.Proto().EmptyDict().Str("p").Global("torch._utils", "_rebuild_parameter");
  p.Tensor("k", "DoubleStorage", 4, 1, {3}, {1});
  p.Bool(true).Global("collections", "OrderedDict").EmptyTuple().Reduce().Tuple(3).Reduce();
  p.SetItem().Stop();
  auto parsed = Parse(p);
  ASSERT_TRUE(parsed.ok()) << parsed.status().ToString();
  const PyObject& t = *(*parsed)->entries[0].second;
  EXPECT_EQ(t.kind, PyKind::kTensor);
  EXPECT_EQ(t.storage->dtype, TorchDtype::kFloat64);
  EXPECT_EQ(t.storage_offset, 1);
}

struct Refusal {
  const char* name;
  PickleBuilder pickle;
  StatusCode code;
  const char* message_part;
};

TEST(TorchPickle, RefusesWhatTorchSaveDoesNotWrite) {
  std::vector<Refusal> cases;
  cases.push_back({"os.system global", PickleBuilder().Proto().Global("os", "system"), StatusCode::kUnsupported,
                   "'os.system'"});
  cases.push_back({"builtins.eval", PickleBuilder().Proto().Global("builtins", "eval"), StatusCode::kUnsupported,
                   "byte 2"});
  cases.push_back({"torch global that is not a storage", PickleBuilder().Proto().Global("torch", "load"),
                   StatusCode::kUnsupported, "torch.load"});
  cases.push_back({"INST", PickleBuilder().Proto().Op('i'), StatusCode::kUnsupported, "('i')"});
  cases.push_back({"BINFLOAT", PickleBuilder().Proto().Op('G'), StatusCode::kUnsupported, "opcode 0x47"});
  cases.push_back({"APPEND", PickleBuilder().Proto().EmptyList().Int(1).Op('a'), StatusCode::kUnsupported,
                   "byte 5"});
  cases.push_back({"STACK_GLOBAL", PickleBuilder().Proto().Op(0x93), StatusCode::kUnsupported, "0x93"});
  cases.push_back({"PROTO 1", PickleBuilder().Proto(1).Stop(), StatusCode::kUnsupported, "PROTO 1"});
  cases.push_back({"PROTO not first", PickleBuilder().None().Proto(2), StatusCode::kUnsupported, "byte 1"});
  cases.push_back({"REDUCE of a storage type",
                   PickleBuilder().Proto().Global("torch", "FloatStorage").EmptyTuple().Reduce(),
                   StatusCode::kUnsupported, "FloatStorage"});
  cases.push_back({"OrderedDict with arguments",
                   PickleBuilder().Proto().Global("collections", "OrderedDict").EmptyList().Tuple(1).Reduce(),
                   StatusCode::kUnsupported, "arguments"});
  cases.push_back({"persistent id that is not a storage",
                   PickleBuilder().Proto().Mark().Str("module").Str("x").TupleFromMark().PersId(),
                   StatusCode::kUnsupported, "persistent id"});
  cases.push_back({"BUILD on a tensor-like value", PickleBuilder().Proto().Int(1).EmptyDict().Build(),
                   StatusCode::kUnsupported, "BUILD"});
  cases.push_back({"truncated string", PickleBuilder().Proto().Op('X').Raw({100, 0, 0, 0, 'a'}),
                   StatusCode::kTruncated, "byte 2"});
  cases.push_back({"truncated BININT", PickleBuilder().Proto().Op('J').Raw({1, 2}), StatusCode::kTruncated,
                   "needs 4"});
  cases.push_back({"no STOP", PickleBuilder().Proto().None(), StatusCode::kTruncated, "without STOP"});
  cases.push_back({"GLOBAL without newline", PickleBuilder().Proto().Op('c').Raw({'o', 's'}),
                   StatusCode::kTruncated, "newline"});
  cases.push_back({"GET of an unknown memo entry", PickleBuilder().Proto().Get(7), StatusCode::kCorrupt,
                   "memo entry 7"});
  cases.push_back({"STOP with two values", PickleBuilder().Proto().None().None().Stop(), StatusCode::kCorrupt,
                   "2 values"});
  cases.push_back({"bytes after STOP", PickleBuilder().Proto().None().Stop().None(), StatusCode::kCorrupt,
                   "after STOP"});
  cases.push_back({"stack underflow", PickleBuilder().Proto().Tuple(2), StatusCode::kCorrupt, "underflow"});
  cases.push_back({"TUPLE without MARK", PickleBuilder().Proto().None().TupleFromMark(), StatusCode::kCorrupt,
                   "MARK"});
  cases.push_back({"pop through a MARK", PickleBuilder().Proto().None().Mark().Tuple(1), StatusCode::kCorrupt,
                   "underflow"});
  cases.push_back({"SETITEM on a tuple", PickleBuilder().Proto().EmptyTuple().Int(1).Int(2).SetItem(),
                   StatusCode::kCorrupt, "not a dict"});
  cases.push_back({"SETITEMS with an odd count",
                   PickleBuilder().Proto().EmptyDict().Mark().Int(1).SetItems(), StatusCode::kCorrupt, "odd"});
  cases.push_back({"dict inserted into itself",
                   PickleBuilder().Proto().EmptyDict().Put(0).Int(1).Get(0).SetItem(), StatusCode::kCorrupt,
                   "itself"});
  // A dict modified after it was stored in a tuple (would allow cycles).
  cases.push_back({"SETITEM after sealing",
                   PickleBuilder().Proto().EmptyDict().Put(0).Tuple(1).Get(0).Int(1).Int(2).SetItem(),
                   StatusCode::kUnsupported, "already stored"});
  cases.push_back({"_rebuild_tensor_v2 with few arguments",
                   PickleBuilder().Proto().Global("torch._utils", "_rebuild_tensor_v2").Int(1).Tuple(1).Reduce(),
                   StatusCode::kUnsupported, "_rebuild_tensor_v2"});
  cases.push_back({"negative numel",
                   PickleBuilder().Proto().Mark().Str("storage").Global("torch", "FloatStorage").Str("0").Str("cpu")
                       .Int(-4).TupleFromMark().PersId(),
                   StatusCode::kCorrupt, "negative"});
  for (const Refusal& c : cases) {
    auto parsed = Parse(c.pickle);
    EXPECT_FALSE(parsed.ok()) << c.name;
    if (parsed.ok()) continue;
    EXPECT_EQ(parsed.status().code(), c.code) << c.name << ": " << parsed.status().ToString();
    EXPECT_NE(parsed.status().message().find(c.message_part), std::string::npos)
        << c.name << ": " << parsed.status().ToString();
    EXPECT_NE(parsed.status().message().find("test.pkl: byte"), std::string::npos) << c.name;
  }
}

TEST(TorchPickle, LimitsOnDepthObjectsAndMemo) {
  PickleBuilder deep;
  deep.Proto().None();
  for (int i = 0; i < 40; ++i) deep.Tuple(1);
  deep.Stop();
  auto parsed = Parse(deep);
  EXPECT_EQ(parsed.status().code(), StatusCode::kLimitExceeded);

  PickleBuilder many;
  many.Proto().Mark();
  for (int i = 0; i < 200; ++i) many.None();
  many.TupleFromMark().Stop();
  PickleLimits small;
  small.max_objects = 100;
  EXPECT_EQ(Parse(many, small).status().code(), StatusCode::kLimitExceeded);
  EXPECT_TRUE(Parse(many).ok());

  PickleBuilder memo;
  memo.Proto().None();
  for (uint32_t i = 0; i < 50; ++i) memo.Put(1000 + i * 7919);
  memo.Stop();
  small.max_memo = 10;
  EXPECT_EQ(Parse(memo, small).status().code(), StatusCode::kLimitExceeded);
  EXPECT_TRUE(Parse(memo).ok());
}

TEST(TorchPickle, EveryTruncationOfARealStateDictFailsCleanly) {
  const std::vector<uint8_t> bytes = StateDictPickle({{"w", {2, 2}, {1, 2, 3, 4}}});
  for (size_t n = 0; n < bytes.size(); ++n) {
    auto parsed = Unpickle(bytes.data(), n, "cut.pkl");
    EXPECT_FALSE(parsed.ok()) << n;
  }
  EXPECT_TRUE(Unpickle(bytes.data(), bytes.size(), "whole.pkl").ok());
}

}  // namespace
}  // namespace atex::fourdgs_internal
