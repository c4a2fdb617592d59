// Writer + reader: round trips with every compression, index consistency, log-time ordering,
// filters, metadata / attachments, background compression identical to inline, the reference
// writer's file, and malformed files.
#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <iterator>
#include <random>

#include "common/json.h"
#include "rig_daemon/recording/mcap_reader.h"
#include "rig_daemon/recording/mcap_tools.h"
#include "rig_daemon/recording/mcap_writer.h"
#include "rig_daemon/recording/session_conventions.h"
#include "test_data.h"

namespace hc::recording {
namespace {

using testing::ScratchDir;

struct Written {
  std::uint16_t channel;
  std::uint32_t sequence;
  std::uint64_t log_time;
  std::uint64_t publish_time;
  Bytes data;
};

// A small session: a JSON force channel at "7 kHz" with jittered (sometimes backwards) times, a
// raw frame channel, metadata and an attachment. Returns what was written, in write order.
std::vector<Written> write_session(const std::filesystem::path& path, McapWriter::Options opt,
                                   int n_force = 700, int n_frames = 6) {
  auto w = McapWriter::open(path, opt);
  EXPECT_TRUE(w.ok()) << w.status().to_string();
  auto& writer = **w;
  const std::string schema =
      json_schema_for("hardcopy.Force", {{"fz", JsonFieldType::kNumber, "N"}});
  const auto sid =
      writer.add_schema("hardcopy.Force", kJsonSchemaEncoding, Bytes(schema.begin(), schema.end()))
          .value();
  const auto force =
      writer.add_channel("/ft/wrench", kJsonEncoding, sid, {{"device", "ft0"}}).value();
  const auto cam = writer.add_channel("/camera/0/raw", "application/octet-stream", 0).value();
  EXPECT_TRUE(writer.write_metadata("rig_config", {{"yaml", "cameras: 1\n"}}).ok());
  std::vector<Written> out;
  std::mt19937 rng(42);
  int frame = 0;
  for (int i = 0; i < n_force; ++i) {
    // 1/7000 s period with +-30 us jitter: log times are not monotonic across channels.
    const std::uint64_t t =
        1'000'000'000ull + static_cast<std::uint64_t>(i) * 142857ull + (rng() % 60'000);
    Bytes data = json_message(Json{{"fz", 0.01 * i}});
    EXPECT_TRUE(
        writer.write_message(force, t, t - 500, data, static_cast<std::uint32_t>(1000 + i)).ok());
    out.push_back({force, static_cast<std::uint32_t>(1000 + i), t, t - 500, data});
    if (n_frames > 0 && i % (n_force / n_frames) == 0 && frame < n_frames) {
      Bytes px(64 * 48);
      for (std::size_t k = 0; k < px.size(); ++k) px[k] = static_cast<std::uint8_t>(k + frame);
      const std::uint64_t tf = t + 7;
      EXPECT_TRUE(writer.write_message(cam, tf, tf, px).ok());
      out.push_back({cam, static_cast<std::uint32_t>(frame), tf, tf, px});
      ++frame;
    }
  }
  EXPECT_TRUE(
      writer.write_attachment("calib.yaml", "application/yaml", 5, 6, Bytes{'k', ':', '1'}).ok());
  EXPECT_TRUE(
      writer
          .write_metadata(
              kMetadataDeviceStats,
              {{"ft0.received", "700"}, {"ft0.lost", "2"}, {"ft0.late", "1"}, {"cam0.lost", "0"}})
          .ok());
  auto summary = writer.close();
  EXPECT_TRUE(summary.ok()) << summary.status().to_string();
  EXPECT_EQ(summary->message_count, out.size());
  return out;
}

class WriterReader : public ::testing::TestWithParam<Compression> {};

TEST_P(WriterReader, RoundTripIndexedAndLinear) {
  ScratchDir dir;
  const auto path = dir / "s.mcap";
  McapWriter::Options opt;
  opt.compression = GetParam();
  opt.chunk_size = 8 * 1024;  // many chunks
  const auto written = write_session(path, opt);

  auto reader = McapReader::open(path);
  ASSERT_TRUE(reader.ok()) << reader.status().to_string();
  EXPECT_TRUE(reader->summary().from_summary_section);
  EXPECT_GT(reader->summary().chunk_indexes.size(), 5u);
  for (const auto& ci : reader->summary().chunk_indexes)
    EXPECT_EQ(ci.compression, compression_record_name(GetParam()));
  ASSERT_EQ(reader->channels().size(), 2u);
  const Channel* force = reader->find_channel("/ft/wrench");
  ASSERT_NE(force, nullptr);
  EXPECT_EQ(force->metadata.at("device"), "ft0");
  ASSERT_EQ(reader->schemas().size(), 1u);

  // File order (indexed, then linear) reproduces exactly what was written.
  for (bool use_index : {true, false}) {
    SCOPED_TRACE(use_index ? "indexed" : "linear");
    ReadOptions ro;
    ro.order = ReadOrder::kFile;
    ro.use_index = use_index;
    std::size_t i = 0;
    ASSERT_TRUE(reader
                    ->read_messages(ro,
                                    [&](const MessageEvent& e) {
                                      EXPECT_LT(i, written.size());
                                      if (i >= written.size()) return false;
                                      const Written& w = written[i++];
                                      EXPECT_EQ(e.message.channel_id, w.channel);
                                      EXPECT_EQ(e.message.sequence, w.sequence);
                                      EXPECT_EQ(e.message.log_time, w.log_time);
                                      EXPECT_EQ(e.message.publish_time, w.publish_time);
                                      EXPECT_TRUE(std::equal(e.message.data.begin(),
                                                             e.message.data.end(), w.data.begin(),
                                                             w.data.end()));
                                      EXPECT_EQ(e.channel->id, w.channel);
                                      EXPECT_EQ(e.schema != nullptr, w.channel == force->id);
                                      return true;
                                    })
                    .ok());
    EXPECT_EQ(i, written.size());
  }

  // Log-time order: the stable sort of what was written (ties keep write order).
  std::vector<Written> sorted = written;
  std::stable_sort(sorted.begin(), sorted.end(),
                   [](const Written& a, const Written& b) { return a.log_time < b.log_time; });
  for (bool use_index : {true, false}) {
    ReadOptions ro;
    ro.order = ReadOrder::kLogTime;
    ro.use_index = use_index;
    std::size_t i = 0;
    ASSERT_TRUE(reader
                    ->read_messages(ro,
                                    [&](const MessageEvent& e) {
                                      EXPECT_EQ(e.message.log_time, sorted[i].log_time);
                                      EXPECT_EQ(e.message.channel_id, sorted[i].channel);
                                      EXPECT_EQ(e.message.sequence, sorted[i].sequence);
                                      ++i;
                                      return true;
                                    })
                    .ok());
    EXPECT_EQ(i, sorted.size());
  }

  // Topic and time filters.
  const std::uint64_t t0 = sorted[100].log_time, t1 = sorted[300].log_time;
  std::size_t expect = 0;
  for (const auto& w : written)
    if (w.channel == force->id && w.log_time >= t0 && w.log_time < t1) ++expect;
  ReadOptions ro;
  ro.topics = {"/ft/wrench"};
  ro.start_time = t0;
  ro.end_time = t1;
  std::size_t got = 0;
  ASSERT_TRUE(reader
                  ->read_messages(ro,
                                  [&](const MessageEvent& e) {
                                    EXPECT_EQ(e.channel->topic, "/ft/wrench");
                                    ++got;
                                    return true;
                                  })
                  .ok());
  EXPECT_EQ(got, expect);
  // Stop early.
  got = 0;
  ASSERT_TRUE(reader->read_messages({}, [&](const MessageEvent&) { return ++got < 3; }).ok());
  EXPECT_EQ(got, 3u);
  // Unknown topic.
  ReadOptions bad;
  bad.topics = {"/nope"};
  EXPECT_FALSE(reader->read_messages(bad, [](const MessageEvent&) { return true; }).ok());

  // Counts, metadata, attachment.
  auto counts = reader->message_counts();
  ASSERT_TRUE(counts.ok());
  EXPECT_EQ(counts->at(force->id), 700u);
  EXPECT_EQ(counts->at(reader->find_channel("/camera/0/raw")->id), 6u);
  auto md = reader->read_metadata();
  ASSERT_TRUE(md.ok());
  ASSERT_EQ(md->size(), 2u);
  EXPECT_EQ((*md)[0].name, "rig_config");
  EXPECT_EQ((*md)[0].metadata.at("yaml"), "cameras: 1\n");
  ASSERT_EQ(reader->summary().attachment_indexes.size(), 1u);
  auto att = reader->read_attachment(reader->summary().attachment_indexes[0]);
  ASSERT_TRUE(att.ok());
  EXPECT_EQ(att->name, "calib.yaml");
  EXPECT_EQ(att->data, (Bytes{'k', ':', '1'}));

  // Message indexes agree with the messages (no decompression needed).
  std::uint64_t indexed = 0;
  for (const auto& ci : reader->summary().chunk_indexes) {
    auto mis = reader->read_message_indexes(ci);
    ASSERT_TRUE(mis.ok());
    for (const auto& mi : *mis) indexed += mi.records.size();
  }
  EXPECT_EQ(indexed, written.size());

  // verify passes.
  auto v = verify(path);
  ASSERT_TRUE(v.ok());
  EXPECT_TRUE(v->ok) << (v->problems.empty() ? "" : v->problems[0]);
  EXPECT_EQ(v->messages_checked, written.size());
  EXPECT_EQ(v->crcs_checked,
            reader->summary().chunk_indexes.size() + 3);  // chunks, data, summary, attachment
}

INSTANTIATE_TEST_SUITE_P(AllCompressions, WriterReader,
                         ::testing::Values(Compression::kNone, Compression::kLz4,
                                           Compression::kZstd),
                         [](const auto& p) {
                           return std::string(compression_display_name(p.param));
                         });

TEST(McapWriter, BackgroundCompressionWritesIdenticalBytes) {
  ScratchDir dir;
  for (Compression c : {Compression::kZstd, Compression::kLz4}) {
    McapWriter::Options opt;
    opt.compression = c;
    opt.chunk_size = 4096;
    write_session(dir / "inline.mcap", opt);
    opt.compression_threads = 2;
    write_session(dir / "threads.mcap", opt);
    EXPECT_EQ(testing::read_bytes(dir / "inline.mcap"), testing::read_bytes(dir / "threads.mcap"));
  }
}

TEST(McapWriter, RejectsBadUse) {
  ScratchDir dir;
  McapWriter::Options opt;
  opt.chunk_size = 0;
  EXPECT_FALSE(McapWriter::open(dir / "a.mcap", opt).ok());
  opt = {};
  opt.compression_level = 40;
  EXPECT_FALSE(McapWriter::open(dir / "a.mcap", opt).ok());
  EXPECT_FALSE(McapWriter::open(dir / "no/such/dir/a.mcap", {}).ok());
  auto w = McapWriter::open(dir / "a.mcap", {});
  ASSERT_TRUE(w.ok());
  EXPECT_FALSE((*w)->add_channel("/x", "json", 5).ok());  // unknown schema
  const auto ch = (*w)->add_channel("/x", "json", 0).value();
  EXPECT_FALSE((*w)->add_channel("/x", "json", 0).ok());  // duplicate topic
  EXPECT_FALSE((*w)->write_message(ch + 1, 1, 1, Bytes{}).ok());
  EXPECT_FALSE((*w)->add_schema(Schema{0, "s", "e", {}}).ok());
  EXPECT_TRUE((*w)->write_message(ch, 1, 1, Bytes{1}).ok());
  ASSERT_TRUE((*w)->close().ok());
  EXPECT_FALSE((*w)->write_message(ch, 2, 2, Bytes{1}).ok());
  EXPECT_FALSE((*w)->close().ok());
  // exclusive refuses to overwrite.
  McapWriter::Options ex;
  ex.exclusive = true;
  EXPECT_FALSE(McapWriter::open(dir / "a.mcap", ex).ok());
}

TEST(McapWriter, EmptySessionIsValid) {
  ScratchDir dir;
  auto w = McapWriter::open(dir / "e.mcap", {});
  ASSERT_TRUE(w.ok());
  ASSERT_TRUE((*w)->close().ok());
  auto r = McapReader::open(dir / "e.mcap");
  ASSERT_TRUE(r.ok()) << r.status().to_string();
  EXPECT_TRUE(r->channels().empty());
  auto v = verify(dir / "e.mcap");
  ASSERT_TRUE(v.ok());
  EXPECT_TRUE(v->ok) << (v->problems.empty() ? "" : v->problems[0]);
}

TEST(McapWriter, EveryChunkIsOnDiskBeforeTheNextMessage) {
  // Crash safety: after a chunk closes its bytes are in the file (write(2) done), without close().
  ScratchDir dir;
  McapWriter::Options opt;
  opt.chunk_size = 1000;
  auto w = McapWriter::open(dir / "c.mcap", opt);
  ASSERT_TRUE(w.ok());
  const auto ch = (*w)->add_channel("/x", "json", 0).value();
  Bytes payload(600, 'a');
  ASSERT_TRUE((*w)->write_message(ch, 1, 1, payload).ok());
  const auto before = std::filesystem::file_size(dir / "c.mcap");
  ASSERT_TRUE((*w)->write_message(ch, 2, 2, payload).ok());  // chunk reaches 1000 B: closed
  const auto after = std::filesystem::file_size(dir / "c.mcap");
  EXPECT_GT(after, before);
  EXPECT_EQ(after, (*w)->bytes_written());
  // The file as it stands is a valid prefix: recover yields both messages.
  auto rep = recover(dir / "c.mcap", dir / "r.mcap", {});
  ASSERT_TRUE(rep.ok()) << rep.status().to_string();
  EXPECT_EQ(rep->messages_kept, 2u);
  EXPECT_EQ(rep->chunks_kept, 1u);
}

// The file written by the reference TypeScript writer (@mcap/core 2.2.2): 100 JSON messages
// {"fz": 0.1 i} at 1 s + i ms on /ft/wrench (contents read with the npm reader, see
// tests/interop/read_mcap.mjs).
TEST(McapReader, ReadsFileFromReferenceWriter) {
  const auto path = testing::shared_data("protocols/roundtrip_written_by_mcap_core_2.2.2.mcap");
  for (bool use_index : {true, false}) {
    auto reader = McapReader::open(path);
    ASSERT_TRUE(reader.ok()) << reader.status().to_string();
    EXPECT_EQ(reader->header().library, "data-scout test");
    ASSERT_NE(reader->find_channel("/ft/wrench"), nullptr);
    EXPECT_EQ(reader->schemas().at(1).name, "ForceSample");
    ReadOptions ro;
    ro.use_index = use_index;
    int i = 0;
    ASSERT_TRUE(reader
                    ->read_messages(ro,
                                    [&](const MessageEvent& e) {
                                      EXPECT_EQ(e.message.sequence, static_cast<std::uint32_t>(i));
                                      EXPECT_EQ(e.message.log_time,
                                                1'000'000'000ull +
                                                    1'000'000ull * static_cast<std::uint64_t>(i));
                                      auto j = parse_json_message(e.message.data);
                                      EXPECT_TRUE(j.ok());
                                      if (j.ok()) {
                                        EXPECT_NEAR((*j)["fz"].get<double>(), 0.1 * i, 1e-12);
                                      }
                                      ++i;
                                      return true;
                                    })
                    .ok());
    EXPECT_EQ(i, 100);
    EXPECT_EQ(reader->message_counts()->at(0), 100u);
  }
  auto v = verify(path);
  ASSERT_TRUE(v.ok());
  EXPECT_TRUE(v->ok) << (v->problems.empty() ? "" : v->problems[0]);
  EXPECT_EQ(v->crcs_checked, 3u);  // chunk, data section, summary
}

// The TenMessages conformance file (unchunked, no summary) built from the expected JSON: our
// reader reads it linearly and returns exactly the expected records.
TEST(McapReader, ReadsConformanceTenMessages) {
  auto expected =
      load_json(testing::shared_data("protocols/conformance_TenMessages.expected.json"));
  ASSERT_TRUE(expected.ok());
  Bytes file(kMagic.begin(), kMagic.end());
  std::vector<Message> want;
  Bytes data_end, footer;
  for (const Json& r : (*expected)["records"]) {
    std::map<std::string, Json> f;
    for (const Json& kv : r["fields"]) f[kv[0].get<std::string>()] = kv[1];
    auto u64 = [&](const char* k) { return std::stoull(f.at(k).get<std::string>()); };
    auto bytes = [&](const char* k) {
      Bytes b;
      for (const Json& x : f.at(k))
        b.push_back(static_cast<std::uint8_t>(std::stoul(x.get<std::string>())));
      return b;
    };
    const std::string type = r["type"];
    if (type == "Header") encode(Header{f.at("profile"), f.at("library")}, file);
    if (type == "Schema")
      encode(Schema{static_cast<std::uint16_t>(u64("id")), f.at("name"), f.at("encoding"),
                    bytes("data")},
             file);
    if (type == "Channel")
      encode(Channel{static_cast<std::uint16_t>(u64("id")),
                     static_cast<std::uint16_t>(u64("schema_id")),
                     f.at("topic"),
                     f.at("message_encoding"),
                     {{"foo", "bar"}}},
             file);
    if (type == "Message") {
      want.push_back(Message{static_cast<std::uint16_t>(u64("channel_id")),
                             static_cast<std::uint32_t>(u64("sequence")), u64("log_time"),
                             u64("publish_time"), bytes("data")});
      encode(want.back(), file);
    }
    if (type == "DataEnd")
      encode(DataEnd{static_cast<std::uint32_t>(u64("data_section_crc"))}, file);
    if (type == "Footer")
      encode(Footer{u64("summary_start"), u64("summary_offset_start"),
                    static_cast<std::uint32_t>(u64("summary_crc"))},
             file);
  }
  file.insert(file.end(), kMagic.begin(), kMagic.end());
  auto reader = McapReader::from_bytes(file, {});
  ASSERT_TRUE(reader.ok()) << reader.status().to_string();
  EXPECT_FALSE(reader->summary().from_summary_section);
  ASSERT_EQ(reader->channels().size(), 1u);
  EXPECT_EQ(reader->channels().at(1).metadata.at("foo"), "bar");
  EXPECT_EQ(reader->schemas().at(1).data, (Bytes{4, 5, 6}));
  std::vector<Message> got;
  ReadOptions ro;
  ro.order = ReadOrder::kFile;
  ASSERT_TRUE(reader
                  ->read_messages(ro,
                                  [&](const MessageEvent& e) {
                                    got.push_back(Message{
                                        e.message.channel_id, e.message.sequence,
                                        e.message.log_time, e.message.publish_time,
                                        Bytes(e.message.data.begin(), e.message.data.end())});
                                    return true;
                                  })
                  .ok());
  EXPECT_EQ(got, want);
  // The file's stored CRCs (from the conformance suite) verify.
  ScratchDir dir;
  testing::write_bytes(dir / "ten.mcap", file);
  auto v = verify(dir / "ten.mcap");
  ASSERT_TRUE(v.ok());
  EXPECT_TRUE(v->ok) << (v->problems.empty() ? "" : v->problems[0]);
  EXPECT_EQ(v->crcs_checked, 2u);
}

TEST(McapReader, MalformedFiles) {
  ScratchDir dir;
  // Not MCAP.
  testing::write_bytes(dir / "a.mcap", Bytes{'h', 'e', 'l', 'l', 'o', ' ', 'w', 'o', 'r', 'l', 'd',
                                             '!', '!', '!', '!', '!', '!', '!'});
  auto r = McapReader::open(dir / "a.mcap");
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.status().message().find("bad magic"), std::string::npos);
  EXPECT_FALSE(McapReader::open(dir / "missing.mcap").ok());
  EXPECT_EQ(McapReader::open(dir / "missing.mcap").status().code(), StatusCode::kNotFound);
  // Truncated session: refused by default, read linearly with allow_truncated.
  McapWriter::Options opt;
  opt.chunk_size = 4096;
  const auto written = write_session(dir / "s.mcap", opt);
  Bytes full = testing::read_bytes(dir / "s.mcap");
  testing::write_bytes(dir / "t.mcap", ByteSpan(full).first(full.size() / 2));
  auto t = McapReader::open(dir / "t.mcap");
  ASSERT_FALSE(t.ok());
  EXPECT_NE(t.status().message().find("recover"), std::string::npos) << t.status().message();
  McapReader::Options allow;
  allow.allow_truncated = true;
  auto t2 = McapReader::open(dir / "t.mcap", allow);
  ASSERT_TRUE(t2.ok()) << t2.status().to_string();
  EXPECT_FALSE(t2->summary().from_summary_section);
  EXPECT_GT(t2->summary().statistics->message_count, 10u);
  EXPECT_LT(t2->summary().statistics->message_count, written.size());
  // Footer pointing outside the file.
  Bytes bad = full;
  const std::size_t footer_at = bad.size() - kFooterAndMagicSize;
  bad[footer_at + 9 + 7] = 0x7F;  // summary_start high byte
  auto b = McapReader::from_bytes(bad, {});
  ASSERT_FALSE(b.ok());
  EXPECT_NE(b.status().message().find("summary_start"), std::string::npos) << b.status().message();
  // A flipped byte inside a compressed chunk: reading reports the chunk's offset.
  Bytes flip = full;
  auto good = McapReader::from_bytes(full, {});
  ASSERT_TRUE(good.ok());
  const ChunkIndex ci = good->summary().chunk_indexes[1];
  flip[ci.chunk_start_offset + ci.chunk_length - 5] ^= 0x5A;
  auto f = McapReader::from_bytes(flip, {});
  ASSERT_TRUE(f.ok());
  const Status s = f->read_messages({}, [](const MessageEvent&) { return true; });
  ASSERT_FALSE(s.ok());
  EXPECT_NE(s.message().find("offset " + std::to_string(ci.chunk_start_offset)), std::string::npos)
      << s.message();
}

}  // namespace
}  // namespace hc::recording
