#include "rig_daemon/session/session_reader.h"

#include <fmt/format.h>

#include <string>

#include "rig_daemon/session/codec.h"
#include "rig_daemon/session/topics.h"

namespace hc::session {

namespace {

// Decodes `text` with `decode` and appends it to `out`, or returns the error with its place.
template <typename Record, typename Decode>
Status append(std::vector<Record>& out, Decode decode, std::string_view text,
              const recording::MessageEvent& e, std::string_view name) {
  Result<Record> r = decode(text);
  if (!r.ok())
    return r.status().with_context(
        fmt::format("{}: {} message {}", name, e.channel->topic, e.message.sequence));
  out.push_back(std::move(r).value());
  return {};
}

}  // namespace

Result<SessionRecords> read_session_records(const recording::McapReader& reader,
                                            const SessionRecordsOptions& options,
                                            std::string_view name) {
  SessionRecords out;
  recording::ReadOptions ro;
  ro.order = recording::ReadOrder::kLogTime;
  for (const auto& [wanted, topic] :
       {std::pair{options.sync, kSyncTopic}, std::pair{options.steps, kStepsTopic},
        std::pair{options.events, kEventsTopic},
        std::pair{options.ground_truth, kGroundTruthTopic}})
    if (wanted && reader.find_channel(topic) != nullptr) ro.topics.emplace_back(topic);
  if (ro.topics.empty()) return out;
  Status bad;
  const Status read = reader.read_messages(ro, [&](const recording::MessageEvent& e) {
    const std::string_view text(reinterpret_cast<const char*>(e.message.data.data()),
                                e.message.data.size());
    const std::string& topic = e.channel->topic;
    if (topic == kSyncTopic)
      bad = append(out.sync, sync_record_from_json, text, e, name);
    else if (topic == kStepsTopic)
      bad = append(out.steps, step_record_from_json, text, e, name);
    else if (topic == kEventsTopic)
      bad = append(out.events, event_record_from_json, text, e, name);
    else
      bad = append(out.ground_truth, ground_truth_from_json, text, e, name);
    return bad.ok();
  });
  HC_RETURN_IF_ERROR(read.with_context(std::string(name)));
  HC_RETURN_IF_ERROR(bad);
  return out;
}

}  // namespace hc::session
