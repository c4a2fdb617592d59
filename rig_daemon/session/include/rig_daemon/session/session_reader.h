// Reading a session's own records back (session_records.h) in one pass over its MCAP file: what
// tracking, camera calibration and the session tools read instead of parsing the channels by hand.
// Device streams (frames, samples) are read with the MCAP reader and the codecs of codec.h.
#pragma once

#include <string_view>
#include <vector>

#include "common/status.h"
#include "rig_daemon/recording/mcap_reader.h"
#include "rig_daemon/session/session_records.h"

namespace hc::session {

// Which of the session's channels to read (an absent channel gives no records, not an error).
struct SessionRecordsOptions {
  bool sync = true;
  bool steps = true;
  bool events = false;
  bool ground_truth = false;
};

// Each in log-time order.
struct SessionRecords {
  std::vector<SyncRecord> sync;
  std::vector<StepRecord> steps;
  std::vector<EventRecord> events;
  std::vector<GroundTruthRecord> ground_truth;
};

// Reads and decodes the chosen channels in one pass. The first record that does not decode stops
// it: kInvalidArgument "NAME: TOPIC message SEQUENCE: hardcopy.TYPE: KEY: what was expected".
Result<SessionRecords> read_session_records(const recording::McapReader& reader,
                                            const SessionRecordsOptions& options,
                                            std::string_view name);

}  // namespace hc::session
