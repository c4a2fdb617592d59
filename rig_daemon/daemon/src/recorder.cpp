#include "rig_daemon/daemon/recorder.h"

#include <algorithm>

#include "common/log.h"
#include "rig_daemon/recording/foxglove_image.h"
#include "rig_daemon/recording/session_conventions.h"

namespace hc::rig {

namespace rec = hc::recording;

Result<std::unique_ptr<Recorder>> Recorder::open(const std::filesystem::path& path,
                                                 const Options& options) {
  rec::McapWriter::Options w;
  w.compression = options.compression;
  w.chunk_size = options.chunk_size;
  w.library = options.library;
  w.exclusive = true;
  HC_ASSIGN_OR_RETURN(std::unique_ptr<rec::McapWriter> writer, rec::McapWriter::open(path, w));
  return std::unique_ptr<Recorder>(new Recorder(path, std::move(writer), options));
}

Recorder::Recorder(std::filesystem::path path, std::unique_ptr<rec::McapWriter> writer,
                   Options options)
    : path_(std::move(path)), writer_(std::move(writer)), options_(std::move(options)) {}

Recorder::~Recorder() {
  if (!closed_) {
    Result<rec::McapWriter::Summary> s = close();
    if (!s.ok()) log::get("rig")->warn("closing {}: {}", path_.string(), s.status().to_string());
  }
}

Result<std::uint16_t> Recorder::add_json_channel(std::string_view topic,
                                                 std::string_view schema_name,
                                                 std::string_view json_schema,
                                                 const rec::StringMap& metadata) {
  const auto* p = reinterpret_cast<const std::uint8_t*>(json_schema.data());
  HC_ASSIGN_OR_RETURN(std::uint16_t schema,
                      writer_->add_schema(schema_name, rec::kJsonSchemaEncoding,
                                          rec::ByteSpan(p, json_schema.size())));
  return writer_->add_channel(topic, rec::kJsonEncoding, schema, metadata);
}

Result<std::uint16_t> Recorder::add_image_channel(std::string_view topic,
                                                  const rec::StringMap& metadata) {
  HC_ASSIGN_OR_RETURN(std::uint16_t schema,
                      writer_->add_schema(rec::kRawImageSchemaName, rec::kProtobufEncoding,
                                          rec::raw_image_schema()));
  return writer_->add_channel(topic, rec::kProtobufEncoding, schema, metadata);
}

Status Recorder::write_metadata_now(std::string_view name, const rec::StringMap& metadata) {
  return writer_->write_metadata(name, metadata);
}

void Recorder::start() {
  thread_ = std::thread([this] { run(); });
}

void Recorder::push(Item item, std::size_t bytes) {
  std::unique_lock lock(mutex_);
  space_cv_.wait(lock, [&] {
    return queued_bytes_ + bytes <= options_.max_queued_bytes || queue_.empty() || !error_.ok();
  });
  queued_bytes_ += bytes;
  queue_.emplace_back(std::move(item), bytes);
  lock.unlock();
  cv_.notify_one();
}

void Recorder::write(std::uint16_t channel, std::int64_t log_time_ns, std::int64_t publish_time_ns,
                     std::uint32_t sequence, rec::Bytes data) {
  const std::size_t bytes = data.size() + 32;
  ++queued_messages_;
  push(Message{channel, log_time_ns, publish_time_ns, sequence, std::move(data)}, bytes);
}

void Recorder::write_metadata(std::string name, rec::StringMap metadata) {
  push(MetadataItem{std::move(name), std::move(metadata)}, 256);
}

void Recorder::flush() { push(Flush{}, 0); }

void Recorder::run() {
  while (true) {
    std::unique_lock lock(mutex_);
    cv_.wait(lock, [&] { return !queue_.empty() || closing_; });
    if (queue_.empty()) return;  // closing and drained
    auto [item, bytes] = std::move(queue_.front());
    queue_.pop_front();
    const bool failed = !error_.ok();
    lock.unlock();
    Status s;
    if (!failed) {
      if (auto* m = std::get_if<Message>(&item)) {
        // Host monotonic ns are positive; a negative device stamp would be a backend bug.
        s = writer_->write_message(
            m->channel, static_cast<std::uint64_t>(m->log_ns),
            static_cast<std::uint64_t>(std::max<std::int64_t>(0, m->publish_ns)), m->data,
            m->sequence);
      } else if (auto* md = std::get_if<MetadataItem>(&item)) {
        s = writer_->write_metadata(md->name, md->map);
      } else {
        s = writer_->flush();
      }
    }
    lock.lock();
    queued_bytes_ -= bytes;
    if (!s.ok() && error_.ok()) error_ = s;
    lock.unlock();
    space_cv_.notify_all();
  }
}

Result<rec::McapWriter::Summary> Recorder::close() {
  if (closed_) return failed_precondition("recorder already closed");
  {
    std::lock_guard lock(mutex_);
    closing_ = true;
  }
  cv_.notify_all();
  if (thread_.joinable()) thread_.join();
  closed_ = true;
  Result<rec::McapWriter::Summary> summary = writer_->close();
  std::lock_guard lock(mutex_);
  if (!error_.ok()) return error_;
  return summary;
}

Status Recorder::error() const {
  std::lock_guard lock(mutex_);
  return error_;
}

}  // namespace hc::rig
