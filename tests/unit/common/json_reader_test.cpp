// The checked JSON reader: values of every kind, and every malformed input refused with a message
// naming the document, the key path, what was expected and what was there.
#include "common/json_reader.h"

#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <optional>
#include <string>
#include <vector>

namespace hc {
namespace {

Json doc() {
  return Json::parse(R"({
    "name": "block", "count": 3, "ratio": 0.25, "on": true, "nothing": null,
    "position_m": [1, 2.5, -3], "list": [1, 2, 3, 4],
    "examples": [{"node": 2, "force_n": [0, 0, -1]}, {"node": -1, "force_n": [0, "x", 1]}],
    "big": 18446744073709551615, "negative": -5, "cameras": {"cam0": {"w": 1}, "cam1": {"w": 2}}
  })");
}

void expect_message(const Status& s, std::string_view exact) {
  EXPECT_EQ(s.code(), StatusCode::kInvalidArgument);
  EXPECT_EQ(s.message(), exact);
}

TEST(JsonReader, ReadsValuesOfEveryKind) {
  const Json j = doc();
  const JsonNode root(j, "d.json");
  std::string name;
  int count = 0;
  double ratio = 0;
  bool on = false;
  Eigen::Vector3d p;
  std::vector<int> list;
  std::uint64_t big = 0;
  std::int64_t negative = 0;
  EXPECT_TRUE(root.get("name", name).ok());
  EXPECT_TRUE(root.get("count", count, Bounds::between(1, 10)).ok());
  EXPECT_TRUE(root.get("ratio", ratio, Bounds::positive()).ok());
  EXPECT_TRUE(root.get("on", on).ok());
  EXPECT_TRUE(root.get("position_m", p).ok());
  EXPECT_TRUE(root.get("list", list).ok());
  EXPECT_TRUE(root.get("big", big).ok());
  EXPECT_TRUE(root.get("negative", negative).ok());
  EXPECT_EQ(name, "block");
  EXPECT_EQ(count, 3);
  EXPECT_EQ(ratio, 0.25);
  EXPECT_TRUE(on);
  EXPECT_EQ(p, Eigen::Vector3d(1, 2.5, -3));
  EXPECT_EQ(list, (std::vector<int>{1, 2, 3, 4}));
  EXPECT_EQ(big, std::numeric_limits<std::uint64_t>::max());  // exact above int64's range
  EXPECT_EQ(negative, -5);

  // Absent and null optionals leave the default; optional<T> reads null as nullopt.
  double absent = 7;
  EXPECT_TRUE(root.optional("missing", absent).ok());
  EXPECT_TRUE(root.optional("nothing", absent).ok());
  EXPECT_EQ(absent, 7);
  std::optional<double> maybe = 1.0;
  EXPECT_TRUE(root.member("nothing")->read(maybe).ok());
  EXPECT_FALSE(maybe);
  EXPECT_TRUE(std::isnan(*root.member("nothing")->number_or_null()));

  const Result<std::vector<std::pair<std::string, JsonNode>>> cams =
      root.member("cameras")->entries();
  ASSERT_TRUE(cams.ok());
  ASSERT_EQ(cams->size(), 2u);
  EXPECT_EQ((*cams)[1].first, "cam1");
  EXPECT_EQ((*cams)[1].second.path(), "cameras.cam1");
  EXPECT_EQ(*(*cams)[1].second.member("w")->integer<int>(), 2);

  const JsonNode examples = *root.member("examples");
  EXPECT_EQ(examples.size(), 2u);
  EXPECT_EQ(*examples[0].member("node")->index(5), 2u);
  EXPECT_TRUE(root.only_keys({"name", "count", "ratio", "on", "nothing", "position_m", "list",
                              "examples", "big", "negative", "cameras"})
                  .ok());
}

TEST(JsonReader, MessagesNameDocumentPathExpectedAndFound) {
  const Json j = doc();
  const JsonNode root(j, "d.json");
  const JsonNode examples = *root.member("examples");
  int i = 0;
  double d = 0;
  bool b = false;
  std::string s;
  Eigen::Vector3d v;
  std::array<double, 2> two{};
  std::uint8_t small = 0;
  expect_message(root.get("absent", d), "d.json: missing key 'absent'");
  expect_message(root.get("name", d), "d.json: name: expected a number, got \"block\"");
  expect_message(root.get("ratio", d, Bounds::greater_than(1)),
                 "d.json: ratio: expected a number > 1, got 0.25");
  expect_message(root.get("ratio", i), "d.json: ratio: expected an integer, got 0.25");
  expect_message(root.get("count", i, Bounds::between(5, 9)),
                 "d.json: count: expected an integer in [5, 9], got 3");
  expect_message(root.get("negative", small),
                 "d.json: negative: expected an integer in [0, 255], got -5");
  expect_message(root.get("big", i),
                 "d.json: big: expected an integer in [-2147483648, 2147483647], got "
                 "18446744073709551615");
  expect_message(root.get("count", b), "d.json: count: expected true or false, got 3");
  expect_message(root.get("count", s), "d.json: count: expected a string, got 3");
  expect_message(root.get("name", s, {"box", "mesh"}),
                 "d.json: name: expected one of \"box\", \"mesh\", got \"block\"");
  expect_message(root.get("list", v), "d.json: list: expected an array of 3 numbers, got 4");
  expect_message(root.get("list", two), "d.json: list: expected an array of 2 entries, got 4");
  expect_message(examples[1].get("force_n", v),
                 "d.json: examples[1].force_n[1]: expected a number, got \"x\"");
  expect_message(examples[1].member("node")->index(5).status(),
                 "d.json: examples[1].node: index -1 is negative");
  expect_message(examples[0].member("node")->index(2).status(),
                 "d.json: examples[0].node: index 2 is out of range (there are 2)");
  expect_message(root.member("name")->member("x").status(),
                 "d.json: name: expected an object, got \"block\"");
  expect_message(root.member("name")->expect_array(),
                 "d.json: name: expected an array, got \"block\"");
  expect_message(root.member("list")->expect_array(5),
                 "d.json: list: expected at least 5 entries, got 4");
  expect_message(examples[0].only_keys({"node"}), "d.json: examples[0]: unknown key 'force_n'");
  expect_message(root.member("on")->number_or_null().status(),
                 "d.json: on: expected a number or null, got true");
  const Json not_object = Json::array();
  expect_message(JsonNode(not_object, "e.json").expect_object(),
                 "e.json: expected an object, got an array");
}

TEST(JsonReader, RefusesWhatParsingCannotProduceButCodeCan) {
  // A document built in memory may hold a non-finite double, which JSON cannot.
  const Json j = {{"x", std::numeric_limits<double>::infinity()}};
  double d = 0;
  expect_message(JsonNode(j, "m").get("x", d), "m: x: expected a finite number");
  // Long strings are shortened in messages.
  const Json long_string = {{"s", std::string(100, 'a')}};
  const Status s = JsonNode(long_string, "m").get("s", d);
  EXPECT_LT(s.message().size(), 80u) << s.message();
}

TEST(JsonReader, FailedReadsLeaveTheTargetUntouched) {
  const Json j = Json::parse(R"({"v": [1, "x", 3], "a": [1, 2, "y"]})");
  const JsonNode root(j, "d.json");
  std::vector<int> v{9};
  std::array<int, 3> a{7, 7, 7};
  EXPECT_FALSE(root.get("v", v).ok());
  EXPECT_FALSE(root.get("a", a).ok());
  EXPECT_EQ(v, (std::vector<int>{9}));
  EXPECT_EQ(a, (std::array<int, 3>{7, 7, 7}));
}

}  // namespace
}  // namespace hc
