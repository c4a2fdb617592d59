// McapWriter (see mcap_writer.h): chunks are serialised (and compressed) as a whole, then handed
// to the OS with one writev(2) each, so the file on disk is always "complete records + at most one
// partial record at the end".
#include "rig_daemon/recording/mcap_writer.h"

#include <fcntl.h>
#include <sys/uio.h>
#include <unistd.h>
#include <zlib.h>

#include <algorithm>
#include <cerrno>
#include <condition_variable>
#include <cstring>
#include <deque>
#include <limits>
#include <mutex>
#include <optional>
#include <thread>

#include <fmt/format.h>

#include "common/log.h"

namespace hc::recording {
namespace {

// CRC of a concatenation from the CRCs of its parts (zlib's crc32_combine: same CRC-32 variant as
// MCAP). Lets chunk CRCs be computed on the compression threads.
std::uint32_t crc_combine(std::uint32_t crc_a, std::uint32_t crc_b, std::uint64_t len_b) {
  return static_cast<std::uint32_t>(crc32_combine64(crc_a, crc_b, static_cast<z_off64_t>(len_b)));
}

void append_u64(Bytes& out, std::uint64_t v) {
  for (int i = 0; i < 8; ++i) out.push_back(static_cast<std::uint8_t>(v >> (8 * i)));
}
void append_u32(Bytes& out, std::uint32_t v) {
  for (int i = 0; i < 4; ++i) out.push_back(static_cast<std::uint8_t>(v >> (8 * i)));
}

// One chunk on its way to the file.
struct PendingChunk {
  // Filled by the writer thread.
  Bytes records;  // uncompressed inner records
  std::map<std::uint16_t, std::vector<std::pair<std::uint64_t, std::uint64_t>>> index;
  std::uint64_t start_time = 0;
  std::uint64_t end_time = 0;
  std::uint64_t message_count = 0;
  // Filled by process().
  Bytes header;   // Chunk opcode, length, fields up to and including the records length
  Bytes payload;  // records as stored (compressed or not)
  Bytes indexes;  // MessageIndex records
  std::vector<std::pair<std::uint16_t, std::uint64_t>> index_offsets;  // within `indexes`
  std::uint32_t crc_header = 0, crc_payload = 0, crc_indexes = 0;      // finalized CRCs
  std::uint64_t uncompressed_size = 0;
  std::string compression;
  Status status;
  bool done = false;
};

void process(PendingChunk& c, const McapWriter::Options& opt) {
  c.uncompressed_size = c.records.size();
  std::uint32_t ucrc = 0;
  if (opt.chunk_crc || (opt.data_section_crc && opt.compression == Compression::kNone))
    ucrc = crc32(c.records);
  c.compression = std::string(compression_record_name(opt.compression));
  if (opt.compression == Compression::kNone) {
    c.payload = std::move(c.records);
    c.crc_payload = ucrc;
  } else {
    auto compressed = compress(opt.compression, c.records, opt.compression_level);
    if (!compressed.ok()) {
      c.status = compressed.status();
      return;
    }
    c.payload = std::move(compressed).value();
    Bytes().swap(c.records);
    if (opt.data_section_crc) c.crc_payload = crc32(c.payload);
  }
  // Chunk record prefix + fields; content length covers everything up to the end of the payload.
  const std::uint64_t content_len = 8 + 8 + 8 + 4 + 4 + c.compression.size() + 8 + c.payload.size();
  c.header.reserve(kRecordPrefixSize + 40 + c.compression.size());
  c.header.push_back(static_cast<std::uint8_t>(Opcode::kChunk));
  append_u64(c.header, content_len);
  append_u64(c.header, c.start_time);
  append_u64(c.header, c.end_time);
  append_u64(c.header, c.uncompressed_size);
  append_u32(c.header, opt.chunk_crc ? ucrc : 0);
  append_u32(c.header, static_cast<std::uint32_t>(c.compression.size()));
  c.header.insert(c.header.end(), c.compression.begin(), c.compression.end());
  append_u64(c.header, c.payload.size());
  for (const auto& [channel, entries] : c.index) {
    c.index_offsets.emplace_back(channel, c.indexes.size());
    MessageIndex mi;
    mi.channel_id = channel;
    mi.records = entries;
    encode(mi, c.indexes);
  }
  if (opt.data_section_crc) {
    c.crc_header = crc32(c.header);
    c.crc_indexes = crc32(c.indexes);
  }
}

}  // namespace

Status McapWriter::Options::validate() const {
  if (chunk_size == 0) return invalid_argument("chunk_size must be > 0");
  if (compression == Compression::kZstd && (compression_level < 1 || compression_level > 19))
    return invalid_argument(
        fmt::format("zstd compression_level {} out of range 1..19", compression_level));
  if (compression == Compression::kLz4 && (compression_level < 0 || compression_level > 12))
    return invalid_argument(
        fmt::format("lz4 compression_level {} out of range 0..12", compression_level));
  if (compression_threads < 0 || compression_threads > 16)
    return invalid_argument(
        fmt::format("compression_threads {} out of range 0..16", compression_threads));
  return {};
}

class McapWriter::Impl {
 public:
  Impl(std::filesystem::path path, Options options)
      : path_(std::move(path)), opt_(std::move(options)) {}

  ~Impl() {
    stop_workers();
    if (fd_ >= 0) ::close(fd_);
  }

  Status open() {
    int flags = O_WRONLY | O_CREAT | O_CLOEXEC | (opt_.exclusive ? O_EXCL : O_TRUNC);
    fd_ = ::open(path_.c_str(), flags, 0644);
    if (fd_ < 0)
      return io_error(fmt::format("{}: cannot create: {}", path_.string(), std::strerror(errno)));
    Bytes head(kMagic.begin(), kMagic.end());
    encode(Header{opt_.profile, opt_.library}, head);
    HC_RETURN_IF_ERROR(write_plain(head));
    for (int i = 0; i < opt_.compression_threads; ++i)
      workers_.emplace_back([this] { worker_loop(); });
    return {};
  }

  Result<std::uint16_t> add_schema(std::string_view name, std::string_view encoding,
                                   ByteSpan data) {
    if (!schemas_.empty() && schemas_.rbegin()->first == 0xFFFF)
      return failed_precondition("too many schemas (max 65535)");
    Schema sc;
    sc.id = static_cast<std::uint16_t>(schemas_.empty() ? 1 : schemas_.rbegin()->first + 1);
    sc.name = std::string(name);
    sc.encoding = std::string(encoding);
    sc.data.assign(data.begin(), data.end());
    const std::uint16_t id = sc.id;
    HC_RETURN_IF_ERROR(add_schema_record(std::move(sc)));
    return id;
  }

  Status add_schema_record(Schema sc) {
    HC_RETURN_IF_ERROR(check_open());
    if (sc.id == 0) return invalid_argument("add_schema: schema id 0 is reserved");
    if (schemas_.count(sc.id) != 0)
      return invalid_argument(fmt::format("add_schema: schema id {} already exists", sc.id));
    const std::uint16_t id = sc.id;
    schemas_.emplace(id, SchemaState{std::move(sc), false});
    return {};
  }

  Result<std::uint16_t> add_channel(std::string_view topic, std::string_view message_encoding,
                                    std::uint16_t schema_id, const StringMap& metadata) {
    if (channel_count_ > 0 && max_channel_id_ == 0xFFFF)
      return failed_precondition("too many channels (max 65536)");
    Channel c;
    c.id = static_cast<std::uint16_t>(channel_count_ == 0 ? 0 : max_channel_id_ + 1);
    c.schema_id = schema_id;
    c.topic = std::string(topic);
    c.message_encoding = std::string(message_encoding);
    c.metadata = metadata;
    const std::uint16_t id = c.id;
    HC_RETURN_IF_ERROR(add_channel_record(std::move(c)));
    return id;
  }

  Status add_channel_record(Channel c) {
    HC_RETURN_IF_ERROR(check_open());
    if (c.schema_id != 0 && schemas_.count(c.schema_id) == 0)
      return invalid_argument(
          fmt::format("add_channel '{}': unknown schema id {}", c.topic, c.schema_id));
    if (c.id < channels_.size() && channels_[c.id])
      return invalid_argument(fmt::format("add_channel: channel id {} already exists", c.id));
    for (const auto& other : channels_)
      if (other && other->channel.topic == c.topic)
        return invalid_argument(fmt::format("add_channel: topic '{}' already exists", c.topic));
    if (c.id >= channels_.size()) channels_.resize(static_cast<std::size_t>(c.id) + 1);
    max_channel_id_ = channel_count_ == 0 ? c.id : std::max(max_channel_id_, c.id);
    ++channel_count_;
    const std::uint16_t id = c.id;
    channels_[id] = ChannelState{std::move(c), false, 0};
    return {};
  }

  Status write_message(std::uint16_t channel_id, std::uint64_t log_time, std::uint64_t publish_time,
                       ByteSpan data, std::optional<std::uint32_t> sequence) {
    HC_RETURN_IF_ERROR(check_open());
    if (channel_id >= channels_.size() || !channels_[channel_id])
      return invalid_argument(fmt::format("write_message: unknown channel id {}", channel_id));
    if (!chunk_) chunk_ = std::make_shared<PendingChunk>();
    PendingChunk& c = *chunk_;
    ChannelState& cs = *channels_[channel_id];
    if (!cs.written) {
      const std::uint16_t sid = cs.channel.schema_id;
      if (sid != 0) {
        SchemaState& ss = schemas_.at(sid);
        if (!ss.written) {
          encode(ss.schema, c.records);
          ss.written = true;
        }
      }
      encode(cs.channel, c.records);
      cs.written = true;
    }
    const std::uint32_t seq = sequence ? *sequence : cs.next_sequence;
    cs.next_sequence = seq + 1;
    c.index[channel_id].emplace_back(log_time, c.records.size());
    // Grow geometrically (an exact reserve per message would copy the chunk again every time).
    const std::size_t need = c.records.size() + kRecordPrefixSize + 22 + data.size();
    if (need > c.records.capacity())
      c.records.reserve(std::max<std::size_t>(
          {need, 2 * c.records.capacity(),
           static_cast<std::size_t>(std::min<std::uint64_t>(opt_.chunk_size, 64u << 20)) + 4096}));
    encode_message(channel_id, seq, log_time, publish_time, data, c.records);
    if (c.message_count == 0) {
      c.start_time = c.end_time = log_time;
    } else {
      c.start_time = std::min(c.start_time, log_time);
      c.end_time = std::max(c.end_time, log_time);
    }
    ++c.message_count;
    if (stats_.message_count == 0) {
      stats_.message_start_time = stats_.message_end_time = log_time;
    } else {
      stats_.message_start_time = std::min(stats_.message_start_time, log_time);
      stats_.message_end_time = std::max(stats_.message_end_time, log_time);
    }
    ++stats_.message_count;
    ++stats_.channel_message_counts[channel_id];
    if (c.records.size() >= opt_.chunk_size) return close_chunk();
    return {};
  }

  Status write_metadata(std::string_view name, const StringMap& metadata) {
    HC_RETURN_IF_ERROR(check_open());
    HC_RETURN_IF_ERROR(drain());
    Bytes rec;
    encode(Metadata{std::string(name), metadata}, rec);
    metadata_indexes_.push_back({offset_, rec.size(), std::string(name)});
    ++stats_.metadata_count;
    return write_plain(rec);
  }

  Status write_attachment(std::string_view name, std::string_view media_type,
                          std::uint64_t log_time, std::uint64_t create_time, ByteSpan data) {
    HC_RETURN_IF_ERROR(check_open());
    HC_RETURN_IF_ERROR(drain());
    Attachment a;
    a.log_time = log_time;
    a.create_time = create_time;
    a.name = std::string(name);
    a.media_type = std::string(media_type);
    a.data.assign(data.begin(), data.end());
    a.crc = attachment_crc(a);
    Bytes rec;
    encode(a, rec);
    attachment_indexes_.push_back(
        {offset_, rec.size(), log_time, create_time, a.data.size(), a.name, a.media_type});
    ++stats_.attachment_count;
    return write_plain(rec);
  }

  Status flush() {
    HC_RETURN_IF_ERROR(check_open());
    HC_RETURN_IF_ERROR(drain());
    if (opt_.sync_on_chunk && ::fdatasync(fd_) != 0)
      return io_error(fmt::format("{}: fdatasync: {}", path_.string(), std::strerror(errno)));
    return {};
  }

  Result<Summary> close() {
    HC_RETURN_IF_ERROR(check_open());
    HC_RETURN_IF_ERROR(drain());
    stop_workers();
    // DataEnd.
    Bytes tail;
    encode(DataEnd{opt_.data_section_crc ? data_crc_ : 0}, tail);
    const std::uint64_t summary_start = offset_ + tail.size();
    const std::size_t summary_at = tail.size();
    // Summary section, grouped by opcode; a SummaryOffset per non-empty group.
    std::vector<SummaryOffset> offsets;
    auto group = [&](Opcode op, auto&& emit) {
      const std::size_t before = tail.size();
      emit();
      if (tail.size() > before)
        offsets.push_back({static_cast<std::uint8_t>(op), offset_ + before, tail.size() - before});
    };
    group(Opcode::kSchema, [&] {
      for (const auto& [id, ss] : schemas_) encode(ss.schema, tail);
    });
    group(Opcode::kChannel, [&] {
      for (const auto& cs : channels_)
        if (cs) encode(cs->channel, tail);
    });
    stats_.schema_count = static_cast<std::uint16_t>(schemas_.size());
    stats_.channel_count = channel_count_;
    stats_.chunk_count = static_cast<std::uint32_t>(chunk_indexes_.size());
    group(Opcode::kStatistics, [&] { encode(stats_, tail); });
    group(Opcode::kChunkIndex, [&] {
      for (const auto& ci : chunk_indexes_) encode(ci, tail);
    });
    group(Opcode::kAttachmentIndex, [&] {
      for (const auto& ai : attachment_indexes_) encode(ai, tail);
    });
    group(Opcode::kMetadataIndex, [&] {
      for (const auto& mi : metadata_indexes_) encode(mi, tail);
    });
    const std::uint64_t summary_offset_start = offset_ + tail.size();
    for (const auto& so : offsets) encode(so, tail);
    // Footer: summary CRC covers the summary start through Footer.summary_offset_start.
    Footer footer{summary_start, summary_offset_start, 0};
    encode(footer, tail);
    const std::size_t crc_end = tail.size() - 4;
    footer.summary_crc = crc32(ByteSpan(tail.data() + summary_at, crc_end - summary_at));
    for (int i = 0; i < 4; ++i)
      tail[crc_end + static_cast<std::size_t>(i)] =
          static_cast<std::uint8_t>(footer.summary_crc >> (8 * i));
    tail.insert(tail.end(), kMagic.begin(), kMagic.end());
    HC_RETURN_IF_ERROR(write_plain(tail));
    if (opt_.sync_on_chunk && ::fdatasync(fd_) != 0)
      return io_error(fmt::format("{}: fdatasync: {}", path_.string(), std::strerror(errno)));
    if (::close(fd_) != 0) {
      fd_ = -1;
      closed_ = true;
      return io_error(fmt::format("{}: close: {}", path_.string(), std::strerror(errno)));
    }
    fd_ = -1;
    closed_ = true;
    summary_.message_count = stats_.message_count;
    summary_.chunk_count = chunk_indexes_.size();
    summary_.file_size = offset_;
    summary_.message_start_time = stats_.message_start_time;
    summary_.message_end_time = stats_.message_end_time;
    summary_.statistics = stats_;
    return summary_;
  }

  std::uint64_t bytes_written() const { return offset_; }
  const std::filesystem::path& path() const { return path_; }
  bool closed() const { return closed_; }

 private:
  Status check_open() const {
    if (closed_ || fd_ < 0)
      return failed_precondition(fmt::format("{}: writer is closed", path_.string()));
    if (!failed_.ok()) return failed_;
    return {};
  }

  // Hands the open chunk to the pipeline (or processes it here).
  Status close_chunk() {
    if (!chunk_ || chunk_->message_count == 0) return {};
    std::shared_ptr<PendingChunk> c = std::move(chunk_);
    chunk_.reset();
    if (workers_.empty()) {
      process(*c, opt_);
      return write_chunk(*c);
    }
    {
      std::unique_lock lock(mutex_);
      jobs_.push_back(c);
      in_flight_.push_back(c);
    }
    cv_jobs_.notify_one();
    // Keep at most compression_threads chunks in flight.
    while (in_flight_.size() > static_cast<std::size_t>(opt_.compression_threads))
      HC_RETURN_IF_ERROR(write_front());
    return {};
  }

  Status write_front() {
    std::shared_ptr<PendingChunk> c;
    {
      std::unique_lock lock(mutex_);
      c = in_flight_.front();
      cv_done_.wait(lock, [&] { return c->done; });
      in_flight_.pop_front();
    }
    return write_chunk(*c);
  }

  // Closes the open chunk and writes every chunk in flight.
  Status drain() {
    HC_RETURN_IF_ERROR(close_chunk());
    while (!in_flight_.empty()) HC_RETURN_IF_ERROR(write_front());
    return {};
  }

  void worker_loop() {
    while (true) {
      std::shared_ptr<PendingChunk> c;
      {
        std::unique_lock lock(mutex_);
        cv_jobs_.wait(lock, [&] { return stop_ || !jobs_.empty(); });
        if (jobs_.empty()) return;
        c = jobs_.front();
        jobs_.pop_front();
      }
      process(*c, opt_);
      {
        std::unique_lock lock(mutex_);
        c->done = true;
      }
      cv_done_.notify_all();
    }
  }

  void stop_workers() {
    {
      std::unique_lock lock(mutex_);
      stop_ = true;
    }
    cv_jobs_.notify_all();
    for (auto& t : workers_) t.join();
    workers_.clear();
  }

  Status write_chunk(PendingChunk& c) {
    if (!c.status.ok()) return fail(c.status);
    const std::uint64_t chunk_start = offset_;
    const std::uint64_t chunk_length = c.header.size() + c.payload.size();
    ChunkIndex ci;
    ci.message_start_time = c.start_time;
    ci.message_end_time = c.end_time;
    ci.chunk_start_offset = chunk_start;
    ci.chunk_length = chunk_length;
    for (const auto& [channel, rel] : c.index_offsets)
      ci.message_index_offsets[channel] = chunk_start + chunk_length + rel;
    ci.message_index_length = c.indexes.size();
    ci.compression = c.compression;
    ci.compressed_size = c.payload.size();
    ci.uncompressed_size = c.uncompressed_size;
    iovec iov[3] = {{c.header.data(), c.header.size()},
                    {c.payload.data(), c.payload.size()},
                    {c.indexes.data(), c.indexes.size()}};
    HC_RETURN_IF_ERROR(write_all(iov, 3));
    if (opt_.data_section_crc) {
      data_crc_ = crc_combine(data_crc_, c.crc_header, c.header.size());
      data_crc_ = crc_combine(data_crc_, c.crc_payload, c.payload.size());
      data_crc_ = crc_combine(data_crc_, c.crc_indexes, c.indexes.size());
    }
    summary_.uncompressed_bytes += c.uncompressed_size;
    summary_.compressed_bytes += c.payload.size();
    chunk_indexes_.push_back(std::move(ci));
    if (opt_.sync_on_chunk && ::fdatasync(fd_) != 0)
      return fail(io_error(fmt::format("{}: fdatasync: {}", path_.string(), std::strerror(errno))));
    return {};
  }

  Status write_plain(const Bytes& b) {
    iovec iov{const_cast<std::uint8_t*>(b.data()), b.size()};  // writev takes non-const iovecs
    HC_RETURN_IF_ERROR(write_all(&iov, 1));
    if (opt_.data_section_crc) data_crc_ = crc_combine(data_crc_, crc32(b), b.size());
    return {};
  }

  Status write_all(iovec* iov, int count) {
    std::uint64_t total = 0;
    for (int i = 0; i < count; ++i) total += iov[i].iov_len;
    std::uint64_t done = 0;
    int first = 0;
    while (done < total) {
      const ssize_t n = ::writev(fd_, iov + first, count - first);
      if (n < 0) {
        if (errno == EINTR) continue;
        return fail(io_error(fmt::format("{}: write at offset {}: {}", path_.string(),
                                         offset_ + done, std::strerror(errno))));
      }
      done += static_cast<std::uint64_t>(n);
      std::size_t left = static_cast<std::size_t>(n);
      while (first < count && left >= iov[first].iov_len) {
        left -= iov[first].iov_len;
        ++first;
      }
      if (first < count) {
        iov[first].iov_base = static_cast<std::uint8_t*>(iov[first].iov_base) + left;
        iov[first].iov_len -= left;
      }
    }
    offset_ += total;
    return {};
  }

  Status fail(Status s) {
    if (failed_.ok()) failed_ = s;
    return s;
  }

  std::filesystem::path path_;
  Options opt_;
  int fd_ = -1;
  bool closed_ = false;
  Status failed_;  // a write error makes the writer refuse further work
  std::uint64_t offset_ = 0;
  std::uint32_t data_crc_ = 0;  // finalized CRC of the bytes written so far (crc of "" is 0)
  struct SchemaState {
    Schema schema;
    bool written = false;  // already in the data section
  };
  struct ChannelState {
    Channel channel;
    bool written = false;
    std::uint32_t next_sequence = 0;
  };
  std::map<std::uint16_t, SchemaState> schemas_;
  std::vector<std::optional<ChannelState>> channels_;  // by id
  std::uint32_t channel_count_ = 0;
  std::uint16_t max_channel_id_ = 0;
  std::shared_ptr<PendingChunk> chunk_;
  Statistics stats_;
  std::vector<ChunkIndex> chunk_indexes_;
  std::vector<MetadataIndex> metadata_indexes_;
  std::vector<AttachmentIndex> attachment_indexes_;
  Summary summary_;
  // Compression pipeline.
  std::vector<std::thread> workers_;
  std::mutex mutex_;
  std::condition_variable cv_jobs_, cv_done_;
  std::deque<std::shared_ptr<PendingChunk>> jobs_, in_flight_;
  bool stop_ = false;
};

Result<std::unique_ptr<McapWriter>> McapWriter::open(const std::filesystem::path& path,
                                                     const Options& options) {
  HC_RETURN_IF_ERROR(options.validate());
  auto impl = std::make_unique<Impl>(path, options);
  HC_RETURN_IF_ERROR(impl->open());
  return std::unique_ptr<McapWriter>(new McapWriter(std::move(impl)));
}

McapWriter::McapWriter(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}

McapWriter::~McapWriter() {
  if (impl_ && !impl_->closed()) {
    auto r = impl_->close();
    if (!r.ok())
      log::get("recording")
          ->warn("{}: closing MCAP writer: {}", impl_->path().string(), r.status().to_string());
  }
}

Result<std::uint16_t> McapWriter::add_schema(std::string_view name, std::string_view encoding,
                                             ByteSpan data) {
  return impl_->add_schema(name, encoding, data);
}
Result<std::uint16_t> McapWriter::add_channel(std::string_view topic,
                                              std::string_view message_encoding,
                                              std::uint16_t schema_id, const StringMap& metadata) {
  return impl_->add_channel(topic, message_encoding, schema_id, metadata);
}
Status McapWriter::add_schema(const Schema& schema) { return impl_->add_schema_record(schema); }
Status McapWriter::add_channel(const Channel& channel) {
  return impl_->add_channel_record(channel);
}
Status McapWriter::write_message(std::uint16_t channel_id, std::uint64_t log_time_ns,
                                 std::uint64_t publish_time_ns, ByteSpan data,
                                 std::uint32_t sequence) {
  return impl_->write_message(channel_id, log_time_ns, publish_time_ns, data, sequence);
}
Status McapWriter::write_message(std::uint16_t channel_id, std::uint64_t log_time_ns,
                                 std::uint64_t publish_time_ns, ByteSpan data) {
  return impl_->write_message(channel_id, log_time_ns, publish_time_ns, data, std::nullopt);
}
Status McapWriter::write_metadata(std::string_view name, const StringMap& metadata) {
  return impl_->write_metadata(name, metadata);
}
Status McapWriter::write_attachment(std::string_view name, std::string_view media_type,
                                    std::uint64_t log_time_ns, std::uint64_t create_time_ns,
                                    ByteSpan data) {
  return impl_->write_attachment(name, media_type, log_time_ns, create_time_ns, data);
}
Status McapWriter::flush() { return impl_->flush(); }
Result<McapWriter::Summary> McapWriter::close() { return impl_->close(); }
std::uint64_t McapWriter::bytes_written() const { return impl_->bytes_written(); }
const std::filesystem::path& McapWriter::path() const { return impl_->path(); }

}  // namespace hc::recording
