// Fuzzes the JSON decoders of the rig's time-series messages and the session's own records
// (rig_daemon/session/codec.h): any
// input must give a value or an error, never a crash; a decoded value re-encodes and decodes to
// the same text.
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <string_view>

#include "rig_daemon/session/codec.h"

namespace {
template <typename T, typename Decode>
void round_trip(std::string_view text, Decode decode) {
  hc::Result<T> first = decode(text);
  if (!first.ok()) return;
  const std::string again = hc::session::to_json(*first);
  hc::Result<T> second = decode(again);
  if (!second.ok() || hc::session::to_json(*second) != again) std::abort();
}
}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string_view text(reinterpret_cast<const char*>(data), size);
  using namespace hc::session;
  round_trip<TriggerEdge>(text, trigger_edge_from_json);
  round_trip<FsrSample>(text, fsr_sample_from_json);
  round_trip<WrenchSample>(text, wrench_sample_from_json);
  round_trip<ArmState>(text, arm_state_from_json);
  round_trip<ArmCommand>(text, arm_command_from_json);
  round_trip<SyncRecord>(text, sync_record_from_json);
  round_trip<StepRecord>(text, step_record_from_json);
  round_trip<EventRecord>(text, event_record_from_json);
  round_trip<GroundTruthRecord>(text, ground_truth_from_json);
  return 0;
}
