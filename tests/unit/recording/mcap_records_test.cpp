// MCAP record codec: byte-exact against records written by the reference TypeScript writer
// (@mcap/core 2.2.2, ../shared/data/protocols/roundtrip_written_by_mcap_core_2.2.2.mcap) and the
// spec's conformance file TenMessages (its expected CRCs); round trips of every record type;
// malformed input.
#include <gtest/gtest.h>

#include <fstream>
#include <iterator>

#include "common/json.h"
#include "rig_daemon/recording/mcap_records.h"
#include "test_data.h"

namespace hc::recording {
namespace {

Bytes bytes_of(std::string_view s) { return Bytes(s.begin(), s.end()); }

const std::filesystem::path kPeerFile =
    testing::shared_data("protocols/roundtrip_written_by_mcap_core_2.2.2.mcap");

TEST(Crc32, StandardCheckValue) {
  // CRC-32/ISO-HDLC check value of "123456789" (the catalogue value every CRC-32 lists).
  EXPECT_EQ(crc32(bytes_of("123456789")), 0xCBF43926u);
  EXPECT_EQ(crc32(Bytes{}), 0u);
  // Incremental == one shot, across the 8-byte slicing boundary.
  Bytes data(1001);
  for (std::size_t i = 0; i < data.size(); ++i) data[i] = static_cast<std::uint8_t>(i * 7 + 3);
  std::uint32_t st = kCrc32Init;
  st = crc32_update(st, ByteSpan(data).first(13));
  st = crc32_update(st, ByteSpan(data).subspan(13));
  EXPECT_EQ(crc32_final(st), crc32(data));
}

// Walks the top-level records of the peer file.
std::vector<std::pair<std::uint64_t, RecordView>> records_of(const Bytes& file) {
  std::vector<std::pair<std::uint64_t, RecordView>> out;
  std::uint64_t off = 8;
  while (off + 8 < file.size()) {
    auto r = next_record(ByteSpan(file).subspan(off), off);
    EXPECT_TRUE(r.ok()) << r.status().to_string();
    if (!r.ok()) break;
    out.emplace_back(off, *r);
    off += r->size;
    if (r->opcode == static_cast<std::uint8_t>(Opcode::kFooter)) break;
  }
  return out;
}

// Decoding then re-encoding each record of the peer's file gives the same bytes.
TEST(McapRecords, ByteExactAgainstReferenceWriter) {
  const Bytes file = testing::read_bytes(kPeerFile);
  ASSERT_GT(file.size(), 100u);
  const auto recs = records_of(file);
  // Opcode sequence as written by @mcap/core 2.2.2 (inspected: header, one chunk, its message
  // index, data end, schema, channel, statistics, chunk index, 4 summary offsets, footer).
  std::vector<std::uint8_t> ops;
  for (const auto& [off, r] : recs) ops.push_back(r.opcode);
  EXPECT_EQ(ops, (std::vector<std::uint8_t>{1, 6, 7, 15, 3, 4, 11, 8, 14, 14, 14, 14, 2}));
  int checked = 0;
  for (const auto& [off, r] : recs) {
    const Bytes original(file.begin() + static_cast<std::ptrdiff_t>(off),
                         file.begin() + static_cast<std::ptrdiff_t>(off + r.size));
    Bytes again;
    switch (static_cast<Opcode>(r.opcode)) {
      case Opcode::kHeader:
        encode(decode_header(r.content).value(), again);
        break;
      case Opcode::kChunk:
        encode(decode_chunk(r.content).value(), again);
        break;
      case Opcode::kMessageIndex:
        encode(decode_message_index(r.content).value(), again);
        break;
      case Opcode::kDataEnd:
        encode(decode_data_end(r.content).value(), again);
        break;
      case Opcode::kSchema:
        encode(decode_schema(r.content).value(), again);
        break;
      case Opcode::kChannel:
        encode(decode_channel(r.content).value(), again);
        break;
      case Opcode::kStatistics:
        encode(decode_statistics(r.content).value(), again);
        break;
      case Opcode::kChunkIndex:
        encode(decode_chunk_index(r.content).value(), again);
        break;
      case Opcode::kSummaryOffset:
        encode(decode_summary_offset(r.content).value(), again);
        break;
      case Opcode::kFooter:
        encode(decode_footer(r.content).value(), again);
        break;
      default:
        continue;
    }
    EXPECT_EQ(again, original) << opcode_name(r.opcode) << " at " << off;
    ++checked;
  }
  EXPECT_EQ(checked, 13);

  // Field values of the peer's records.
  const Header h = decode_header(recs[0].second.content).value();
  EXPECT_EQ(h.library, "data-scout test");
  EXPECT_EQ(h.profile, "");
  const Schema s = decode_schema(recs[4].second.content).value();
  EXPECT_EQ(s.id, 1);
  EXPECT_EQ(s.name, "ForceSample");
  EXPECT_EQ(s.encoding, "jsonschema");
  const Channel c = decode_channel(recs[5].second.content).value();
  EXPECT_EQ(c.id, 0);
  EXPECT_EQ(c.topic, "/ft/wrench");
  EXPECT_EQ(c.message_encoding, "json");
  const Statistics st = decode_statistics(recs[6].second.content).value();
  EXPECT_EQ(st.message_count, 100u);
  EXPECT_EQ(st.chunk_count, 1u);
  EXPECT_EQ(st.message_start_time, 1'000'000'000u);
  EXPECT_EQ(st.message_end_time, 1'099'000'000u);
  // The peer's CRCs agree with ours: chunk uncompressed CRC, data section CRC and summary CRC.
  const Chunk chunk = decode_chunk(recs[1].second.content).value();
  EXPECT_EQ(chunk.compression, "");
  EXPECT_EQ(crc32(chunk.records), chunk.uncompressed_crc);
  const DataEnd de = decode_data_end(recs[3].second.content).value();
  EXPECT_EQ(crc32(ByteSpan(file).first(recs[3].first)), de.data_section_crc);
  const Footer f = decode_footer(recs.back().second.content).value();
  EXPECT_EQ(f.summary_start, recs[4].first);
  EXPECT_EQ(f.summary_offset_start, recs[8].first);
  EXPECT_EQ(
      crc32(ByteSpan(file).subspan(f.summary_start, recs.back().first + 9 + 16 - f.summary_start)),
      f.summary_crc);
}

// The spec's conformance file "TenMessages" (no chunks, no summary): its records encoded by us
// give exactly the CRCs the conformance suite expects (data section CRC and Footer summary CRC in
// conformance_TenMessages.expected.json), so our encoding of these records is byte-exact.
TEST(McapRecords, ConformanceTenMessagesCrcs) {
  auto expected =
      load_json(testing::shared_data("protocols/conformance_TenMessages.expected.json"));
  ASSERT_TRUE(expected.ok()) << expected.status().to_string();
  Bytes file(kMagic.begin(), kMagic.end());
  std::uint32_t want_data_crc = 0, want_summary_crc = 0;
  for (const Json& r : (*expected)["records"]) {
    std::map<std::string, Json> f;
    for (const Json& kv : r["fields"]) f[kv[0].get<std::string>()] = kv[1];
    const std::string type = r["type"];
    auto u64 = [&](const char* k) { return std::stoull(f.at(k).get<std::string>()); };
    auto data = [&](const char* k) {
      Bytes b;
      for (const Json& x : f.at(k))
        b.push_back(static_cast<std::uint8_t>(std::stoul(x.get<std::string>())));
      return b;
    };
    if (type == "Header") {
      encode(Header{f.at("profile"), f.at("library")}, file);
    } else if (type == "Schema") {
      encode(Schema{static_cast<std::uint16_t>(u64("id")), f.at("name"), f.at("encoding"),
                    data("data")},
             file);
    } else if (type == "Channel") {
      StringMap md;
      for (auto it = f.at("metadata").begin(); it != f.at("metadata").end(); ++it)
        md[it.key()] = it.value();
      encode(Channel{static_cast<std::uint16_t>(u64("id")),
                     static_cast<std::uint16_t>(u64("schema_id")), f.at("topic"),
                     f.at("message_encoding"), md},
             file);
    } else if (type == "Message") {
      encode(Message{static_cast<std::uint16_t>(u64("channel_id")),
                     static_cast<std::uint32_t>(u64("sequence")), u64("log_time"),
                     u64("publish_time"), data("data")},
             file);
    } else if (type == "DataEnd") {
      want_data_crc = static_cast<std::uint32_t>(u64("data_section_crc"));
    } else if (type == "Footer") {
      want_summary_crc = static_cast<std::uint32_t>(u64("summary_crc"));
      EXPECT_EQ(u64("summary_start"), 0u);
    }
  }
  EXPECT_EQ(crc32(file), want_data_crc);  // 406842951 in the expected JSON
  Bytes footer;
  encode(Footer{0, 0, 0}, footer);
  EXPECT_EQ(crc32(ByteSpan(footer).first(footer.size() - 4)), want_summary_crc);  // 1875167664
}

template <typename T, typename Enc, typename Dec>
void round_trip(const T& value, Enc enc, Dec dec, Opcode op) {
  Bytes b;
  enc(value, b);
  auto r = next_record(b);
  ASSERT_TRUE(r.ok());
  EXPECT_EQ(r->opcode, static_cast<std::uint8_t>(op));
  EXPECT_EQ(r->size, b.size());
  auto back = dec(r->content);
  ASSERT_TRUE(back.ok()) << back.status().to_string();
  EXPECT_EQ(*back, value);
  // Every strict prefix of the content is malformed: a clear error, never a crash. (Statistics
  // and similar end in a map whose empty form is 4 bytes, so a prefix cut inside is detected.)
  for (std::size_t n = 0; n < r->content.size(); ++n) {
    auto cut = dec(r->content.first(n));
    EXPECT_FALSE(cut.ok()) << opcode_name(static_cast<std::uint8_t>(op)) << " prefix " << n;
  }
}

TEST(McapRecords, RoundTripEveryRecordType) {
  auto e = [](const auto& v, Bytes& b) { encode(v, b); };
  round_trip(Header{"ros2", "hardcopy 1.0"}, e, decode_header, Opcode::kHeader);
  round_trip(Footer{123, 456, 0xDEADBEEF}, e, decode_footer, Opcode::kFooter);
  round_trip(Schema{7, "foxglove.RawImage", "protobuf", {1, 2, 3, 0, 255}}, e, decode_schema,
             Opcode::kSchema);
  round_trip(Channel{3, 7, "/cam/0", "protobuf", {{"a", "b"}, {"serial", "123"}}}, e,
             decode_channel, Opcode::kChannel);
  round_trip(Chunk{10, 20, 5, 0x1234, "zstd", {9, 8, 7}}, e, decode_chunk, Opcode::kChunk);
  round_trip(MessageIndex{3, {{10, 0}, {12, 40}}}, e, decode_message_index, Opcode::kMessageIndex);
  round_trip(ChunkIndex{10, 20, 100, 200, {{0, 300}, {3, 340}}, 80, "lz4", 150, 400}, e,
             decode_chunk_index, Opcode::kChunkIndex);
  Attachment a{5, 6, "calib.yaml", "application/yaml", bytes_of("K: [1,2,3]"), 0};
  a.crc = attachment_crc(a);
  round_trip(a, e, decode_attachment, Opcode::kAttachment);
  round_trip(AttachmentIndex{1, 2, 3, 4, 5, "n", "m"}, e, decode_attachment_index,
             Opcode::kAttachmentIndex);
  round_trip(Statistics{100, 2, 3, 1, 4, 5, 10, 99, {{0, 60}, {1, 40}}}, e, decode_statistics,
             Opcode::kStatistics);
  round_trip(Metadata{"rig_config", {{"yaml", "cameras: 7"}}}, e, decode_metadata,
             Opcode::kMetadata);
  round_trip(MetadataIndex{50, 60, "plan"}, e, decode_metadata_index, Opcode::kMetadataIndex);
  round_trip(SummaryOffset{0x08, 1000, 500}, e, decode_summary_offset, Opcode::kSummaryOffset);
  round_trip(DataEnd{0xCAFEBABE}, e, decode_data_end, Opcode::kDataEnd);
}

TEST(McapRecords, MessageKeepsTrailingBytesAsData) {
  Message m{2, 9, 1000, 999, {}};  // empty payload is legal
  Bytes b;
  encode(m, b);
  EXPECT_EQ(b.size(), 9u + 22u);
  auto back = decode_message(next_record(b)->content);
  ASSERT_TRUE(back.ok());
  EXPECT_EQ(*back, m);
}

TEST(McapRecords, MalformedLengths) {
  // A string length pointing past the record.
  Bytes b;
  encode(Header{"p", "lib"}, b);
  b[9] = 0xFF;  // profile length 255 (+ the rest) > content
  auto h = decode_header(next_record(b)->content);
  ASSERT_FALSE(h.ok());
  EXPECT_NE(h.status().message().find("profile"), std::string::npos) << h.status().message();
  // A record length larger than the buffer.
  Bytes rec;
  encode(DataEnd{1}, rec);
  rec[1] = 0x10;
  auto r = next_record(rec, 1234);
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.status().message().find("offset 1234"), std::string::npos) << r.status().message();
  // A huge declared length (2^63) does not allocate: it is rejected against the bytes present.
  rec[8] = 0x80;
  EXPECT_FALSE(next_record(rec).ok());
  // MessageIndex array length not a multiple of 16.
  Bytes mi;
  encode(MessageIndex{1, {{1, 2}}}, mi);
  mi[9 + 2] = 15;
  EXPECT_FALSE(decode_message_index(next_record(mi)->content).ok());
  // Chunk whose records length exceeds the content.
  Bytes ch;
  encode(Chunk{0, 0, 3, 0, "", {1, 2, 3}}, ch);
  ch[ch.size() - 3 - 8] = 200;
  EXPECT_FALSE(decode_chunk(next_record(ch)->content).ok());
}

TEST(McapCompression, RoundTripAndErrors) {
  Bytes data(200000);
  for (std::size_t i = 0; i < data.size(); ++i)
    data[i] = static_cast<std::uint8_t>((i / 100) ^ (i % 7));
  for (Compression c : {Compression::kNone, Compression::kLz4, Compression::kZstd}) {
    SCOPED_TRACE(std::string(compression_display_name(c)));
    auto z = compress(c, data, c == Compression::kZstd ? 1 : 0);
    ASSERT_TRUE(z.ok());
    if (c != Compression::kNone) {
      EXPECT_LT(z->size(), data.size() / 4);
    }
    auto back = decompress(compression_record_name(c), *z, data.size(), 1u << 30);
    ASSERT_TRUE(back.ok()) << back.status().to_string();
    EXPECT_EQ(*back, data);
    // Wrong declared size.
    EXPECT_FALSE(decompress(compression_record_name(c), *z, data.size() + 1, 1u << 30).ok());
    EXPECT_FALSE(decompress(compression_record_name(c), *z, data.size() - 1, 1u << 30).ok());
    // Above the caller's limit: refused before allocating.
    EXPECT_FALSE(decompress(compression_record_name(c), *z, data.size(), data.size() - 1).ok());
    if (c != Compression::kNone) {
      // Truncated and corrupted streams.
      EXPECT_FALSE(decompress(compression_record_name(c), ByteSpan(*z).first(z->size() / 2),
                              data.size(), 1u << 30)
                       .ok());
      Bytes bad = *z;
      bad[0] ^= 0xFF;  // breaks the frame magic
      EXPECT_FALSE(decompress(compression_record_name(c), bad, data.size(), 1u << 30).ok());
      // A size no stream this short could expand to.
      EXPECT_FALSE(
          decompress(compression_record_name(c), ByteSpan(*z).first(10), 1ull << 33, 1ull << 40)
              .ok());
    }
  }
  EXPECT_FALSE(decompress("bz2", Bytes{1}, 1, 10).ok());
  EXPECT_FALSE(parse_compression("gzip").ok());
  EXPECT_EQ(parse_compression("none").value(), Compression::kNone);
  EXPECT_EQ(parse_compression("").value(), Compression::kNone);
  EXPECT_EQ(parse_compression("lz4").value(), Compression::kLz4);
}

}  // namespace
}  // namespace hc::recording
