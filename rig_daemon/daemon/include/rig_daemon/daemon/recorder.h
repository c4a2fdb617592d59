// The recorder: one session MCAP file written through the recording library's McapWriter on a
// writer thread of its own, so that the scheduler's control cycle never waits for the disk or the
// compressor. Channels and the opening metadata are registered before the thread starts; messages
// and closing metadata are queued and written in queue order (so a session recorded twice from the
// same inputs has the same bytes).
#pragma once

#include <condition_variable>
#include <cstdint>
#include <deque>
#include <filesystem>
#include <memory>
#include <mutex>
#include <string>
#include <string_view>
#include <thread>
#include <variant>

#include "common/status.h"
#include "rig_daemon/recording/mcap_records.h"
#include "rig_daemon/recording/mcap_writer.h"

namespace hc::rig {

class Recorder {
 public:
  struct Options {
    recording::Compression compression = recording::Compression::kZstd;
    // Small chunks: a crash loses at most the open one (about a second of a 7-camera capture).
    std::uint64_t chunk_size = 1u << 20;
    // The scheduler blocks when this much is queued (the disk cannot keep up): data is never
    // dropped silently.
    std::size_t max_queued_bytes = std::size_t{256} << 20;
    std::string library = "hardcopy rigd";
  };

  // Creates the file (refusing to overwrite one) and writes the Header.
  static Result<std::unique_ptr<Recorder>> open(const std::filesystem::path& path,
                                                const Options& options);
  ~Recorder();  // closes (errors logged) if close() was not called
  Recorder(const Recorder&) = delete;
  Recorder& operator=(const Recorder&) = delete;

  // ---- Before start() ----
  // A JSON channel with its JSON Schema; metadata gets "device"/"kind"/"backend".
  Result<std::uint16_t> add_json_channel(std::string_view topic, std::string_view schema_name,
                                         std::string_view json_schema,
                                         const recording::StringMap& metadata);
  // A foxglove.RawImage channel.
  Result<std::uint16_t> add_image_channel(std::string_view topic,
                                          const recording::StringMap& metadata);
  Status write_metadata_now(std::string_view name, const recording::StringMap& metadata);
  // Starts the writer thread.
  void start();

  // ---- After start(), from one producer thread ----
  void write(std::uint16_t channel, std::int64_t log_time_ns, std::int64_t publish_time_ns,
             std::uint32_t sequence, recording::Bytes data);
  void write_metadata(std::string name, recording::StringMap metadata);
  // Asks the writer to close the open chunk (so everything so far is on disk).
  void flush();
  // Drains the queue and finishes the file. The first writer error, if any.
  Result<recording::McapWriter::Summary> close();
  // The first error the writer thread met (OK so far otherwise).
  Status error() const;
  const std::filesystem::path& path() const { return path_; }
  std::uint64_t messages_queued() const { return queued_messages_; }

 private:
  Recorder(std::filesystem::path path, std::unique_ptr<recording::McapWriter> writer,
           Options options);
  struct Message {
    std::uint16_t channel;
    std::int64_t log_ns, publish_ns;
    std::uint32_t sequence;
    recording::Bytes data;
  };
  struct MetadataItem {
    std::string name;
    recording::StringMap map;
  };
  struct Flush {};
  using Item = std::variant<Message, MetadataItem, Flush>;
  void run();
  void push(Item item, std::size_t bytes);

  std::filesystem::path path_;
  std::unique_ptr<recording::McapWriter> writer_;
  Options options_;
  mutable std::mutex mutex_;
  std::condition_variable cv_;
  std::condition_variable space_cv_;
  std::deque<std::pair<Item, std::size_t>> queue_;
  std::size_t queued_bytes_ = 0;
  bool closing_ = false;
  bool closed_ = false;
  Status error_;
  std::thread thread_;
  std::uint64_t queued_messages_ = 0;
};

}  // namespace hc::rig
