#include "rig_daemon/replay/replay.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "rig_daemon/recording/mcap_reader.h"

namespace hc::devices {

class ReplaySession::Impl {
 public:
  explicit Impl(recording::McapReader r) : reader(std::move(r)) {}
  recording::McapReader reader;
  std::mutex mutex;  // one read at a time: devices may read from several threads
};

Status ReplaySession::Options::validate() const {
  if (!(speed > 0.0 && speed <= 1e6)) return invalid_argument("replay: speed must be in (0, 1e6]");
  return {};
}

ReplaySession::~ReplaySession() = default;

Result<std::shared_ptr<ReplaySession>> ReplaySession::open(const std::filesystem::path& path,
                                                           const Options& options) {
  HC_RETURN_IF_ERROR(options.validate());
  HC_ASSIGN_OR_RETURN(recording::McapReader reader, recording::McapReader::open(path));
  std::shared_ptr<ReplaySession> s(new ReplaySession());
  s->options_ = options;
  HC_ASSIGN_OR_RETURN(auto counts, reader.message_counts());
  for (const auto& [id, ch] : reader.channels()) {
    auto dev = ch.metadata.find("device");
    auto kind = ch.metadata.find("kind");
    if (dev == ch.metadata.end() || kind == ch.metadata.end()) continue;
    const std::optional<DeviceKind> k = device_kind_from_string(kind->second);
    if (!k) continue;  // session channels, ground truth
    if (*k == DeviceKind::kArm && ch.topic.ends_with("/command")) continue;
    Stream st;
    st.device = dev->second;
    st.kind = *k;
    auto backend = ch.metadata.find("backend");
    if (backend != ch.metadata.end()) st.backend = backend->second;
    st.topic = ch.topic;
    st.channel_id = id;
    auto schema = reader.schemas().find(ch.schema_id);
    if (schema != reader.schemas().end()) st.schema = schema->second.name;
    auto count = counts.find(id);
    st.messages = count == counts.end() ? 0 : count->second;
    s->streams_.push_back(std::move(st));
  }
  // Session time span from the chunk indexes of the file (all channels; good enough for pacing).
  std::int64_t lo = std::numeric_limits<std::int64_t>::max(), hi = 0;
  for (const auto& ci : reader.summary().chunk_indexes) {
    lo = std::min<std::int64_t>(lo, static_cast<std::int64_t>(ci.message_start_time));
    hi = std::max<std::int64_t>(hi, static_cast<std::int64_t>(ci.message_end_time));
  }
  if (reader.summary().chunk_indexes.empty()) {
    // No index: one pass over the messages.
    Status st = reader.read_messages({}, [&](const recording::MessageEvent& m) {
      lo = std::min<std::int64_t>(lo, static_cast<std::int64_t>(m.message.log_time));
      hi = std::max<std::int64_t>(hi, static_cast<std::int64_t>(m.message.log_time));
      return true;
    });
    HC_RETURN_IF_ERROR(st);
  }
  s->start_ns_ = lo == std::numeric_limits<std::int64_t>::max() ? 0 : lo;
  s->end_ns_ = hi;
  s->impl_ = std::make_unique<Impl>(std::move(reader));
  return s;
}

Result<std::shared_ptr<ReplaySession>> ReplaySession::open(const std::filesystem::path& path) {
  return open(path, Options{});
}

const ReplaySession::Stream* ReplaySession::find(std::string_view device, DeviceKind kind) const {
  for (const Stream& s : streams_)
    if (s.device == device && s.kind == kind) return &s;
  return nullptr;
}

Status ReplaySession::read(const Stream& stream, std::int64_t from_ns, std::int64_t to_ns,
                           const std::function<bool(const Message&)>& visit) const {
  if (to_ns <= from_ns) return {};
  recording::ReadOptions filter;
  filter.topics = {stream.topic};
  filter.start_time = static_cast<std::uint64_t>(std::max<std::int64_t>(0, from_ns));
  filter.end_time = static_cast<std::uint64_t>(std::max<std::int64_t>(0, to_ns));
  filter.order = recording::ReadOrder::kLogTime;
  std::lock_guard lock(impl_->mutex);
  Message m;
  return impl_->reader.read_messages(filter, [&](const recording::MessageEvent& e) {
    m.log_time_ns = static_cast<std::int64_t>(e.message.log_time);
    m.publish_time_ns = static_cast<std::int64_t>(e.message.publish_time);
    m.sequence = e.message.sequence;
    m.data.assign(e.message.data.begin(), e.message.data.end());
    return visit(m);
  });
}

void ReplaySession::anchor(const Clock& clock) {
  std::lock_guard lock(mutex_);
  if (!anchor_ns_) anchor_ns_ = clock.now_ns();
}

std::int64_t ReplaySession::due_clock_ns(std::int64_t recorded_ns) const {
  std::lock_guard lock(mutex_);
  const std::int64_t a = anchor_ns_.value_or(0);
  return a + static_cast<std::int64_t>(
                 std::ceil(static_cast<double>(recorded_ns - start_ns_) / options_.speed));
}

std::int64_t ReplaySession::recorded_ns_at(std::int64_t clock_ns) const {
  std::lock_guard lock(mutex_);
  const std::int64_t a = anchor_ns_.value_or(0);
  return start_ns_ +
         static_cast<std::int64_t>(std::floor(static_cast<double>(clock_ns - a) * options_.speed));
}

}  // namespace hc::devices
