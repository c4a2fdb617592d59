// JSON codecs of the time-series messages: round trips, and malformed input rejected with a message
// naming the field.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>

#include "rig_daemon/session/codec.h"

namespace hc::session {
namespace {

TEST(Codec, RoundTripsEveryMessage) {
  TriggerEdge e;
  e.index = 12;
  e.line = 3;
  e.rising = false;
  e.host_ns = 1'234'567'890'123;
  e.device_stamp_ns = 42;
  e.device_counter = 99;
  Result<TriggerEdge> e2 = trigger_edge_from_json(to_json(e));
  ASSERT_TRUE(e2.ok()) << e2.status().to_string();
  EXPECT_EQ(to_json(*e2), to_json(e));
  EXPECT_EQ(e2->device_stamp_ns, 42);

  FsrSample f;
  f.raw = 4095;
  f.force_n = 12.5;
  f.channel = 2;
  f.sequence = 7;
  f.host_ns = -5;  // host times may precede the clock's origin in tests
  f.trigger_index = 6;
  Result<FsrSample> f2 = fsr_sample_from_json(to_json(f));
  ASSERT_TRUE(f2.ok()) << f2.status().to_string();
  EXPECT_EQ(to_json(*f2), to_json(f));
  EXPECT_FALSE(f2->device_stamp_ns);

  WrenchSample w;
  w.counts = {1,
              -2,
              3,
              -4,
              std::numeric_limits<std::int32_t>::max(),
              std::numeric_limits<std::int32_t>::min()};
  w.force_n = {0.1, -0.2, 35.0};
  w.torque_nm = {1e-3, 0.0, std::numeric_limits<double>::quiet_NaN()};
  w.rdt_sequence = 0xFFFFFFFFu;
  w.sequence = 1ull << 52;
  Result<WrenchSample> w2 = wrench_sample_from_json(to_json(w));
  ASSERT_TRUE(w2.ok()) << w2.status().to_string();
  EXPECT_EQ(w2->counts, w.counts);
  EXPECT_EQ(w2->rdt_sequence, 0xFFFFFFFFu);
  EXPECT_EQ(w2->sequence, 1ull << 52);
  EXPECT_TRUE(std::isnan(w2->torque_nm[2]));  // JSON null
  EXPECT_EQ(w2->force_n[2], 35.0);

  ArmState a;
  a.pose = {0.01, -0.02, 0.15, 0.5};
  a.target = {0.0, 0.0, 0.05, 0.0};
  a.motion = ArmMotion::kFault;
  a.fault_code = 2;
  a.fault = "stall \"quoted\"";
  a.homed = true;
  Result<ArmState> a2 = arm_state_from_json(to_json(a));
  ASSERT_TRUE(a2.ok()) << a2.status().to_string();
  EXPECT_EQ(to_json(*a2), to_json(a));
  EXPECT_EQ(a2->fault, a.fault);

  ArmCommand c;
  c.type = ArmCommand::Type::kSetSpeed;
  c.speed_m_s = 0.01;
  c.sequence = 3;
  Result<ArmCommand> c2 = arm_command_from_json(to_json(c));
  ASSERT_TRUE(c2.ok()) << c2.status().to_string();
  EXPECT_EQ(c2->type, ArmCommand::Type::kSetSpeed);
  EXPECT_EQ(to_json(*c2), to_json(c));
}

TEST(Codec, SchemasAreJsonDocumentsNamingTheirType) {
  for (const MessageSchema* s :
       {&trigger_edge_schema(), &fsr_sample_schema(), &wrench_sample_schema(), &arm_state_schema(),
        &arm_command_schema(), &sync_record_schema(), &step_record_schema(),
        &event_record_schema(), &ground_truth_schema()}) {
    EXPECT_TRUE(s->name.starts_with("hardcopy."));
    EXPECT_NE(s->json_schema.find(std::string("\"title\": \"") + std::string(s->name) + "\""),
              std::string::npos)
        << s->name;
  }
}

void expect_rejected(const Status& s, std::string_view mentions) {
  EXPECT_EQ(s.code(), StatusCode::kInvalidArgument);
  EXPECT_NE(s.message().find(mentions), std::string::npos) << s.message();
}

TEST(Codec, MalformedMessagesAreRejected) {
  expect_rejected(trigger_edge_from_json("").status(), "not a JSON object");
  expect_rejected(trigger_edge_from_json("[1, 2]").status(), "not a JSON object");
  expect_rejected(trigger_edge_from_json("{\"index\": 1").status(), "not a JSON object");
  expect_rejected(
      trigger_edge_from_json(R"({"line":0,"rising":true,"host_ns":0,"device_counter":0})").status(),
      "index");
  expect_rejected(trigger_edge_from_json(
                      R"({"index":-1,"line":0,"rising":true,"host_ns":0,"device_counter":0})")
                      .status(),
                  "index");
  expect_rejected(trigger_edge_from_json(
                      R"({"index":1,"line":0,"rising":"yes","host_ns":0,"device_counter":0})")
                      .status(),
                  "rising");
  expect_rejected(
      fsr_sample_from_json(R"({"raw":5000000000,"force_n":1,"channel":0,"sequence":0,"host_ns":0})")
          .status(),
      "raw");  // above 2^32 - 1
  expect_rejected(wrench_sample_from_json(
                      R"({"counts":[1,2,3],"force_n":[0,0,0],"torque_nm":[0,0,0],"rdt_sequence":0,)"
                      R"("ft_sequence":0,"status":0,"sequence":0,"host_ns":0})")
                      .status(),
                  "counts");
  expect_rejected(wrench_sample_from_json(
                      R"({"counts":[1,2,3,4,5,6],"force_n":[0,"x",0],"torque_nm":[0,0,0],)"
                      R"("rdt_sequence":0,"ft_sequence":0,"status":0,"sequence":0,"host_ns":0})")
                      .status(),
                  "force_n");
  expect_rejected(arm_state_from_json(R"({"pose":{"x_m":0,"y_m":0,"z_m":0,"yaw_rad":0},)"
                                      R"("target":{"x_m":0,"y_m":0,"z_m":0,"yaw_rad":0},)"
                                      R"("joints":[0,0,0,0],"speed_m_s":0,"motion":"dancing",)"
                                      R"("homed":true,"fault_code":0,"fault":"",)"
                                      R"("command_sequence":0,"sequence":0,"host_ns":0})")
                      .status(),
                  "dancing");
  expect_rejected(arm_state_from_json(R"({"pose":{"x_m":0}})").status(), "y_m");
  expect_rejected(
      arm_command_from_json(R"({"type":"jump","target":{},"speed_m_s":0,"sequence":0})").status(),
      "jump");
}

// The session's own records (session_records.h): what the daemon writes reads back the same.
TEST(Codec, RoundTripsTheSessionRecords) {
  SyncRecord y;
  y.trigger_index = 41;
  y.edge_host_ns = 9'000'000'123;
  y.complete = false;
  y.frames = {{"cam0", 40}, {"cam1", 39}};
  y.missing_cameras = {"cam2"};
  y.ft_sequence = 7001;
  y.ft_error_ns = -120'000;
  y.force_n = {0.1, -0.2, 4.5};
  Result<SyncRecord> y2 = sync_record_from_json(to_json(y));
  ASSERT_TRUE(y2.ok()) << y2.status().to_string();
  EXPECT_EQ(to_json(*y2), to_json(y));
  EXPECT_EQ(y2->frames.at("cam1"), 39u);
  EXPECT_FALSE(y2->fsr_sequence);

  StepRecord press;
  press.host_ns = 5;
  press.step = 3;
  press.trigger_indices = {10, 11};
  press.location = 2;
  press.level = 1;
  press.target_force_n = 5.0;
  press.force_n = 5.04;
  press.depth_m = 0.0021;
  press.pose = ArmPose{0.01, -0.02, 0.0479, 0.0};
  Result<StepRecord> press2 = step_record_from_json(to_json(press));
  ASSERT_TRUE(press2.ok()) << press2.status().to_string();
  EXPECT_EQ(to_json(*press2), to_json(press));
  EXPECT_DOUBLE_EQ(press2->pose->z_m, 0.0479);
  StepRecord board;
  board.step = 1;
  board.trigger_indices = {0};
  board.board_pose = 0;
  Result<StepRecord> board2 = step_record_from_json(to_json(board));
  ASSERT_TRUE(board2.ok()) << board2.status().to_string();
  EXPECT_FALSE(board2->location);
  EXPECT_EQ(board2->board_pose, 0);

  EventRecord trip;
  trip.host_ns = 77;
  trip.kind = "over_force";
  trip.message = "force 31 N over the limit of 30 N";
  trip.detected_ns = 70;
  trip.stop_sent_ns = 72;
  trip.sample_host_ns = 69;
  trip.force_n = 31.0;
  trip.latency_ns = 3;
  Result<EventRecord> trip2 = event_record_from_json(to_json(trip));
  ASSERT_TRUE(trip2.ok()) << trip2.status().to_string();
  EXPECT_EQ(to_json(*trip2), to_json(trip));

  GroundTruthRecord t;
  t.host_ns = 123;
  t.trigger_index = 4;
  t.probe = {0.0, 0.0, 0.05, 0.3};
  t.indentation_m = 0.001;
  t.force_n = 2.5;
  t.markers_m = {{0.0, 0.0, 0.05}, {0.003, 0.0, 0.0499}};
  t.probe_tip_m = {0.0, 0.0, 0.049};
  t.probe_axis = {0.0, 0.0, 1.0};
  t.probe_radius_m = 0.005;
  t.shaft_markers_m = {Eigen::Vector3d(0, 0, 0.11), Eigen::Vector3d(0, 0, 0.16)};
  t.shaft_marker_radius_m = 0.0025;
  t.cameras["cam0"] = {{1}, {}, false};
  t.board = GroundTruthRecord::Board{2, 9, 6, 0.006, Eigen::Matrix3d::Identity(),
                                     Eigen::Vector3d(0.0, 0.0, 0.05)};
  Result<GroundTruthRecord> t2 = ground_truth_from_json(to_json(t));
  ASSERT_TRUE(t2.ok()) << t2.status().to_string();
  EXPECT_EQ(to_json(*t2), to_json(t));
  EXPECT_EQ(t2->cameras.at("cam0").occluded, std::vector<std::uint32_t>{1});
  EXPECT_EQ(t2->board->cols, 9);
}

TEST(Codec, MalformedSessionRecordsAreRejected) {
  expect_rejected(sync_record_from_json(R"({"trigger_index":1,"edge_host_ns":0,"complete":true,)"
                                        R"("frames":{"cam0":-1},"missing_cameras":[]})")
                      .status(),
                  "frames.cam0");
  expect_rejected(sync_record_from_json(R"({"trigger_index":1,"edge_host_ns":0,"complete":true,)"
                                        R"("frames":{},"missing_cameras":[],"ft_sequence":3})")
                      .status(),
                  "ft_error_ns");
  expect_rejected(step_record_from_json(R"({"host_ns":0,"step":1})").status(), "trigger_indices");
  expect_rejected(
      step_record_from_json(R"({"host_ns":0,"step":1,"trigger_indices":[0],"location":-2})")
          .status(),
      "location");
  expect_rejected(event_record_from_json(R"({"host_ns":0,"kind":"log"})").status(), "message");
  expect_rejected(ground_truth_from_json(R"({"host_ns":0})").status(), "probe");
  expect_rejected(
      ground_truth_from_json(
          R"({"host_ns":0,"probe":{"x_m":0,"y_m":0,"z_m":0,"yaw_rad":0},"indentation_m":0,)"
          R"("force_n":0,"markers_m":[[0,0]],"probe_tip_m":[0,0,0],"probe_axis":[0,0,1],)"
          R"("probe_radius_m":0.005,"probe_shown":true,"shaft_markers_m":[[0,0,0],[0,0,0]],)"
          R"("shaft_marker_radius_m":0.002,"cameras":{}})")
          .status(),
      "markers_m[0]");
}

}  // namespace
}  // namespace hc::session
