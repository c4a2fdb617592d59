#include "common/json.h"

#include <fmt/format.h>
#include <gtest/gtest.h>

#include <cstdio>
#include <fstream>
#include <limits>
#include <regex>
#include <string>

#include "test_data.h"

namespace hc {
namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
constexpr double kInf = std::numeric_limits<double>::infinity();

TEST(Json, VectorsAreFlatArrays) {
  EXPECT_EQ(eigen_to_json(Eigen::Vector3d(1.5, -2, 3)).dump(), "[1.5,-2.0,3.0]");
  EXPECT_EQ(eigen_to_json(Eigen::RowVector2f(0.5f, 4.0f)).dump(), "[0.5,4.0]");
  EXPECT_EQ(eigen_to_json(Eigen::Vector3i(1, 2, 3)).dump(), "[1,2,3]");
  Eigen::VectorXd dynamic(4);
  dynamic << 1, 2, 3, 4;
  EXPECT_EQ(eigen_to_json(dynamic).dump(), "[1.0,2.0,3.0,4.0]");
  EXPECT_EQ(eigen_to_json(Eigen::VectorXd()).dump(), "[]");
  // Implicit conversion through nlohmann's serializer gives the same.
  const Json j = Eigen::Vector3d(1, 2, 3);
  EXPECT_EQ(j, eigen_to_json(Eigen::Vector3d(1, 2, 3)));
}

TEST(Json, MatricesAreArraysOfRows) {
  Eigen::Matrix<double, 2, 3> m;
  m << 1, 2, 3, 4, 5, 6;
  EXPECT_EQ(eigen_to_json(m).dump(), "[[1.0,2.0,3.0],[4.0,5.0,6.0]]");
  // A #V by 3 matrix keeps its shape with a single row.
  Eigen::MatrixXd one_vertex(1, 3);
  one_vertex << 7, 8, 9;
  EXPECT_EQ(eigen_to_json(one_vertex).dump(), "[[7.0,8.0,9.0]]");
  // Expressions work too; a row of a matrix is a row vector.
  EXPECT_EQ(eigen_to_json(m.row(1)).dump(), "[4.0,5.0,6.0]");
  EXPECT_EQ(eigen_to_json(m.transpose()).dump(), "[[1.0,4.0],[2.0,5.0],[3.0,6.0]]");
  Eigen::MatrixXi faces(2, 3);
  faces << 0, 1, 2, 2, 1, 3;
  EXPECT_EQ(eigen_to_json(faces).dump(), "[[0,1,2],[2,1,3]]");
  const Json j = Eigen::Matrix2d(Eigen::Matrix2d::Identity());
  EXPECT_EQ(j.dump(), "[[1.0,0.0],[0.0,1.0]]");
}

TEST(Json, NonFiniteNumbersBecomeNull) {
  EXPECT_TRUE(finite_or_null(kNaN).is_null());
  EXPECT_TRUE(finite_or_null(kInf).is_null());
  EXPECT_TRUE(finite_or_null(-kInf).is_null());
  EXPECT_EQ(finite_or_null(0.25), Json(0.25));
  EXPECT_EQ(eigen_to_json(Eigen::Vector3d(kNaN, 1, kInf)).dump(), "[null,1.0,null]");
  // Values that bypass the helpers are still written as null (nlohmann's serializer does it).
  EXPECT_EQ(Json(kNaN).dump(), "null");
  EXPECT_EQ(dump_json(Json{{"x", kInf}}), "{\n  \"x\": null\n}\n");
}

TEST(Json, BoxesHaveMinAndMax) {
  const Eigen::AlignedBox3d box(Eigen::Vector3d(-1, 0, 0.5), Eigen::Vector3d(1, 2, 3));
  EXPECT_EQ(box_to_json(box).dump(), R"({"max":[1.0,2.0,3.0],"min":[-1.0,0.0,0.5]})");
  const Json j = box;
  EXPECT_EQ(j, box_to_json(box));
  EXPECT_TRUE(box_to_json(Eigen::AlignedBox3d()).is_null());
}

TEST(Json, StatusAsJson) {
  EXPECT_EQ(status_to_json(Status()).dump(), R"({"ok":true})");
  EXPECT_EQ(status_to_json(not_found("rig.yaml: no such file")).dump(),
            R"({"code":"not_found","message":"rig.yaml: no such file","ok":false})");
}

TEST(Json, StatusCodeNamesAreIdentifiers) {
  const std::regex identifier("[a-z_]+");
  for (int c = 0; c <= static_cast<int>(StatusCode::kInternal); ++c) {
    const std::string name(status_code_name(static_cast<StatusCode>(c)));
    EXPECT_TRUE(std::regex_match(name, identifier)) << name;
    EXPECT_NE(name, "unknown");
  }
  EXPECT_EQ(status_code_name(StatusCode::kInvalidArgument), "invalid_argument");
  EXPECT_EQ(status_code_name(StatusCode::kIoError), "io_error");
}

TEST(Json, DumpIsPrettyWithTrailingNewline) {
  const Json j = {{"a", 1}, {"b", {true, nullptr}}, {"c", "text"}};
  EXPECT_EQ(dump_json(j),
            "{\n  \"a\": 1,\n  \"b\": [\n    true,\n    null\n  ],\n  \"c\": \"text\"\n}\n");
}

TEST(Json, InvalidUtf8IsReplacedNotThrown) {
  const Json j = std::string("bad\xff name");
  EXPECT_EQ(dump_json(j), "\"bad\xEF\xBF\xBD name\"\n");  // U+FFFD
}

TEST(Json, PrintWritesTheDump) {
  std::FILE* file = std::tmpfile();
  ASSERT_NE(file, nullptr);
  const Json j = {{"mesh", "bunny.stl"}, {"watertight", true}};
  ASSERT_TRUE(print_json(j, file).ok());
  std::rewind(file);
  char buffer[256] = {};
  const std::size_t n = std::fread(buffer, 1, sizeof(buffer) - 1, file);
  std::fclose(file);
  EXPECT_EQ(std::string(buffer, n), dump_json(j));
}

TEST(Json, PrintReportsAFailingStream) {
  std::FILE* read_only = std::fopen("/dev/null", "r");
  ASSERT_NE(read_only, nullptr);
  const Status s = print_json(Json{{"a", 1}}, read_only);
  std::fclose(read_only);
  EXPECT_EQ(s.code(), StatusCode::kIoError);
  EXPECT_NE(s.message().find("cannot write JSON output"), std::string::npos);
}

TEST(Json, ParsesValidText) {
  const Result<Json> j = parse_json(R"({"forces_n": [1.5, 2], "name": "probe"})", "s.json");
  ASSERT_TRUE(j.ok()) << j.status().to_string();
  EXPECT_EQ((*j)["forces_n"][0], 1.5);
  EXPECT_EQ((*j)["name"], "probe");
}

// nlohmann reports its own "line L, column C" in what(); ours comes from the byte offset, so the
// two must agree.
std::pair<int, int> nlohmann_position(std::string_view text) {
  try {
    const Json parsed = Json::parse(text);
    ADD_FAILURE() << "nlohmann accepted " << parsed.dump();
  } catch (const Json::parse_error& e) {
    int line = 0, column = 0;
    const std::string what = e.what();
    const auto at = what.find("at line ");
    if (at != std::string::npos &&
        std::sscanf(what.c_str() + at, "at line %d, column %d", &line, &column) == 2)
      return {line, column};
  }
  return {0, 0};
}

TEST(Json, ParseErrorsNameLineAndColumn) {
  struct Case {
    std::string text;
    std::string prefix;
  };
  const Case cases[] = {
      {R"({"a": tru})", "x.json:1:10: invalid JSON: syntax error while parsing value"},
      {"{\n  \"a\": 1,\n  \"b\": ]\n}",
       "x.json:3:8: invalid JSON: syntax error while parsing value"},
      {"[1, 2,\n", "x.json:2:1: invalid JSON: syntax error while parsing value"},
      {"", "x.json:1:1: invalid JSON: syntax error while parsing value"},
      {"{\"a\": 1} x", "x.json:1:10: invalid JSON: syntax error while parsing value"},
  };
  for (const Case& c : cases) {
    const Result<Json> j = parse_json(c.text, "x.json");
    ASSERT_FALSE(j.ok()) << c.text;
    EXPECT_EQ(j.status().code(), StatusCode::kInvalidArgument);
    EXPECT_EQ(j.status().message().rfind(c.prefix, 0), 0u) << j.status().message();
    const auto [line, column] = nlohmann_position(c.text);
    EXPECT_EQ(j.status().message().rfind(fmt::format("x.json:{}:{}: ", line, column), 0), 0u)
        << j.status().message() << " vs nlohmann line " << line << " column " << column;
  }
}

TEST(Json, NestingIsLimited) {
  const auto nested = [](int depth) {
    return std::string(static_cast<std::size_t>(depth), '[') +
           std::string(static_cast<std::size_t>(depth), ']');
  };
  EXPECT_TRUE(parse_json(nested(kMaxJsonDepth), "ok.json").ok());
  const Result<Json> deep = parse_json("\n  " + nested(kMaxJsonDepth + 1), "deep.json");
  ASSERT_FALSE(deep.ok());
  EXPECT_EQ(deep.status().message(),
            fmt::format("deep.json:2:{}: invalid JSON: nested deeper than {} levels",
                        kMaxJsonDepth + 3, kMaxJsonDepth));
  // Brackets inside strings (escaped quotes included) are text, not nesting.
  const std::string in_string = "[\"\\\"" + std::string(1000, '[') + "\"]";
  const Result<Json> text = parse_json(in_string, "s.json");
  ASSERT_TRUE(text.ok()) << text.status().to_string();
  EXPECT_EQ((*text)[0].get<std::string>().size(), 1001u);
}

TEST(Json, NumberOverflowIsAnError) {
  const Result<Json> j = parse_json("[1e500]", "big.json");
  ASSERT_FALSE(j.ok());
  EXPECT_EQ(j.status().message(), "big.json: invalid JSON: number overflow parsing '1e500'");
}

TEST(Json, LoadsFiles) {
  testing::ScratchDir dir;
  std::ofstream(dir / "m.json") << R"({"youngs_modulus_pa": 1.2e6})";
  const Result<Json> j = load_json(dir / "m.json");
  ASSERT_TRUE(j.ok()) << j.status().to_string();
  EXPECT_EQ((*j)["youngs_modulus_pa"], 1.2e6);

  std::ofstream(dir / "bad.json") << "{\n,}";
  const Result<Json> bad = load_json(dir / "bad.json");
  ASSERT_FALSE(bad.ok());
  EXPECT_EQ(bad.status().message().rfind((dir / "bad.json").string() + ":2:1: ", 0), 0u)
      << bad.status().message();

  const Result<Json> missing = load_json(dir / "none.json");
  ASSERT_FALSE(missing.ok());
  EXPECT_EQ(missing.status().code(), StatusCode::kNotFound);
}

}  // namespace
}  // namespace hc
