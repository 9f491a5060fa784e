#include "atex/status.h"

#include <gtest/gtest.h>

namespace atex {
namespace {

StatusOr<int> Half(int x) {
  if (x % 2 != 0) return MakeError(StatusCode::kInvalidArgument, "odd value ", x);
  return x / 2;
}

Status Quarter(int x, int* out) {
  ATEX_ASSIGN_OR_RETURN(int half, Half(x));
  ATEX_ASSIGN_OR_RETURN(*out, Half(half));
  return Status::Ok();
}

TEST(Status, CodesAndMessages) {
  Status s(StatusCode::kChecksumMismatch, "chunk 'GPOS' at byte 64");
  EXPECT_FALSE(s.ok());
  EXPECT_EQ(s.ToString(), "E6 checksum-mismatch: chunk 'GPOS' at byte 64");
  EXPECT_EQ(s.WithContext("scene.atex").message(), "scene.atex: chunk 'GPOS' at byte 64");
  EXPECT_TRUE(Status::Ok().ok());
  EXPECT_EQ(Status::Ok().ToString(), "OK");
}

TEST(Status, PropagatesThroughMacros) {
  int out = 0;
  EXPECT_TRUE(Quarter(8, &out).ok());
  EXPECT_EQ(out, 2);
  Status s = Quarter(6, &out);
  EXPECT_EQ(s.code(), StatusCode::kInvalidArgument);
  EXPECT_EQ(s.message(), "odd value 3");
}

TEST(Status, StatusOrFromOkStatusIsAnInternalError) {
  StatusOr<int> v(Status::Ok());
  EXPECT_FALSE(v.ok());
  EXPECT_EQ(v.status().code(), StatusCode::kInternal);
}

}  // namespace
}  // namespace atex
