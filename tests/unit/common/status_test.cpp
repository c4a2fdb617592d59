#include "common/status.h"

#include <gtest/gtest.h>

#include <memory>
#include <set>
#include <string>

namespace hc {
namespace {

TEST(Status, DefaultIsOk) {
  const Status s;
  EXPECT_TRUE(s.ok());
  EXPECT_EQ(s.code(), StatusCode::kOk);
  EXPECT_EQ(s.message(), "");
  EXPECT_EQ(s.to_string(), "ok");
  EXPECT_TRUE(Status::ok_status().ok());
}

TEST(Status, CarriesCodeAndMessage) {
  const Status s = invalid_argument("bunny.ply:12: expected 3 vertex indices, got 2");
  EXPECT_FALSE(s.ok());
  EXPECT_EQ(s.code(), StatusCode::kInvalidArgument);
  EXPECT_EQ(s.to_string(), "invalid argument: bunny.ply:12: expected 3 vertex indices, got 2");
  EXPECT_EQ(not_found("x").code(), StatusCode::kNotFound);
  EXPECT_EQ(io_error("x").code(), StatusCode::kIoError);
  EXPECT_EQ(unsupported("x").code(), StatusCode::kUnsupported);
  EXPECT_EQ(failed_precondition("x").code(), StatusCode::kFailedPrecondition);
  EXPECT_EQ(internal_error("x").code(), StatusCode::kInternal);
}

TEST(Status, EveryCodeHasItsOwnName) {
  const StatusCode codes[] = {StatusCode::kOk,          StatusCode::kInvalidArgument,
                              StatusCode::kNotFound,    StatusCode::kIoError,
                              StatusCode::kUnsupported, StatusCode::kFailedPrecondition,
                              StatusCode::kUnavailable, StatusCode::kDeadlineExceeded,
                              StatusCode::kCancelled,   StatusCode::kInternal};
  std::set<std::string_view> names;
  for (StatusCode c : codes) {
    EXPECT_NE(to_string(c), "unknown");
    names.insert(to_string(c));
  }
  EXPECT_EQ(names.size(), std::size(codes));
  EXPECT_EQ(to_string(StatusCode::kIoError), "i/o error");
}

TEST(Status, WithContextPrefixesErrorsOnly) {
  EXPECT_EQ(io_error("disk full").with_context("writing out.stl").message(),
            "writing out.stl: disk full");
  EXPECT_EQ(io_error("disk full").with_context("writing out.stl").code(), StatusCode::kIoError);
  EXPECT_TRUE(Status().with_context("anything").ok());
  EXPECT_EQ(Status().with_context("anything").message(), "");
}

TEST(Status, ParseErrorShape) {
  EXPECT_EQ(parse_error("mesh.obj", 12, "bad face").message(), "mesh.obj:12: bad face");
  EXPECT_EQ(parse_error("mesh.obj", 0, "empty file").message(), "mesh.obj: empty file");
  EXPECT_EQ(parse_error("mesh.obj", 1, "x").code(), StatusCode::kInvalidArgument);
}

TEST(Result, HoldsValueOrStatus) {
  Result<int> good = 42;
  ASSERT_TRUE(good.ok());
  EXPECT_EQ(*good, 42);
  EXPECT_TRUE(good.status().ok());

  Result<int> bad = not_found("nope");
  ASSERT_FALSE(bad.ok());
  EXPECT_EQ(bad.status().code(), StatusCode::kNotFound);
  EXPECT_EQ(bad.status().message(), "nope");
}

TEST(Result, BuiltFromOkStatusIsAnInternalError) {
  const Result<int> r = Status();
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.status().code(), StatusCode::kInternal);
}

TEST(Result, MovesOutMoveOnlyValues) {
  Result<std::unique_ptr<int>> r = std::make_unique<int>(5);
  ASSERT_TRUE(r.ok());
  std::unique_ptr<int> p = std::move(r).value();
  ASSERT_NE(p, nullptr);
  EXPECT_EQ(*p, 5);
}

Status fail_if(bool fail) { return fail ? invalid_argument("failed") : Status(); }

Status chain(bool fail, int* reached) {
  HC_RETURN_IF_ERROR(fail_if(fail));
  *reached = 1;
  return {};
}

Result<int> half(int x) {
  if (x % 2 != 0) return invalid_argument("odd");
  return x / 2;
}

Result<int> quarter(int x) {
  HC_ASSIGN_OR_RETURN(const int h, half(x));
  HC_ASSIGN_OR_RETURN(int q, half(h));
  return q;
}

TEST(StatusMacros, ReturnIfErrorStopsOnFailure) {
  int reached = 0;
  EXPECT_EQ(chain(true, &reached).message(), "failed");
  EXPECT_EQ(reached, 0);
  EXPECT_TRUE(chain(false, &reached).ok());
  EXPECT_EQ(reached, 1);
}

TEST(StatusMacros, AssignOrReturnPropagatesOrAssigns) {
  const Result<int> q = quarter(12);
  ASSERT_TRUE(q.ok());
  EXPECT_EQ(*q, 3);
  const Result<int> odd = quarter(6);  // 6 / 2 = 3 is odd
  ASSERT_FALSE(odd.ok());
  EXPECT_EQ(odd.status().message(), "odd");
}

}  // namespace
}  // namespace hc
