#include "figures/session_figures.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <map>

#include "common/units.h"
#include "rig_daemon/recording/mcap_reader.h"
#include "rig_daemon/recording/mcap_tools.h"
#include "rig_daemon/recording/session_conventions.h"
#include "rig_daemon/session/session_reader.h"
#include "rig_daemon/session/topics.h"

namespace hc::figures {
namespace {

namespace rec = hc::recording;

// rigd's step channel (rig_daemon/session/topics.h).
using session::kStepsTopic;

std::vector<std::array<double, 3>> plan_locations(const rec::McapReader& reader) {
  std::vector<std::array<double, 3>> locs;
  Result<std::vector<rec::Metadata>> meta = reader.read_metadata();
  if (!meta.ok()) return locs;
  for (const rec::Metadata& m : *meta) {
    if (m.name != rec::kMetadataPlan) continue;
    const auto it = m.metadata.find("json");
    if (it == m.metadata.end()) continue;
    const Json plan = Json::parse(it->second, nullptr, false);
    if (!plan.is_object() || !plan.contains("locations") || !plan["locations"].is_array()) continue;
    locs.clear();
    for (const Json& l : plan["locations"]) {
      std::array<double, 3> p{};
      if (l.contains("position_m") && l["position_m"].is_array() && l["position_m"].size() == 3) {
        for (int k = 0; k < 3; ++k)
          p[k] = l["position_m"][k].is_number() ? l["position_m"][k].get<double>() : 0.0;
      }
      locs.push_back(p);
    }
  }
  return locs;
}

plot::Chart location_chart(const SessionCurves& c, int location, std::string_view session_name) {
  plot::Chart chart;
  chart.title = fmt::format("{}: location {}", session_name, location);
  chart.x.label = "probe depth from the start point (mm)";
  chart.y.label = "force (N)";
  chart.y.include_zero = true;
  std::map<int, plot::Series> by_level;
  for (const SessionStepPoint& p : c.steps) {
    if (p.location != location) continue;
    plot::Series& s = by_level[p.level];
    s.label = fmt::format("level {}", p.level);
    s.marker = plot::MarkerStyle::kCircle;
    s.x.push_back(units::m_to_mm(p.depth_m));
    s.y.push_back(p.force_n);
  }
  for (auto& [level, s] : by_level) chart.series.push_back(std::move(s));
  return chart;
}

Json step_json(const SessionStepPoint& p) {
  return Json{{"location", p.location},   {"level", p.level},
              {"step", p.step},           {"depth_m", p.depth_m},
              {"force_n", p.force_n},     {"target_force_n", p.target_force_n},
              {"host_ns", p.host_ns}};
}

}  // namespace

Result<SessionCurves> read_session_curves(const std::filesystem::path& session) {
  const std::string name = session.filename().string();
  HC_ASSIGN_OR_RETURN(rec::McapReader reader, rec::McapReader::open(session));
  if (reader.find_channel(kStepsTopic) == nullptr)
    return invalid_argument(name + ": no " + std::string(kStepsTopic) +
                            " channel (not a session recorded by rigd)");
  SessionCurves curves;
  curves.locations_m = plan_locations(reader);
  HC_ASSIGN_OR_RETURN(session::SessionRecords records,
                      session::read_session_records(reader, {.sync = false, .steps = true}, name));
  for (std::size_t i = 0; i < records.steps.size(); ++i) {
    const session::StepRecord& r = records.steps[i];
    if (!r.location) continue;  // a calibration or hand-held step
    const auto finite = [](const std::optional<double>& v) { return v && std::isfinite(*v); };
    if (!r.level || !finite(r.depth_m) || !finite(r.force_n))
      return invalid_argument(fmt::format("{}: {} message {}: an automated-press step needs level, "
                                          "depth_m and force_n (finite)",
                                          name, kStepsTopic, i));
    SessionStepPoint p;
    p.location = *r.location;
    p.level = *r.level;
    p.step = r.step;
    p.depth_m = *r.depth_m;
    p.force_n = *r.force_n;
    if (finite(r.target_force_n)) p.target_force_n = *r.target_force_n;
    p.host_ns = r.host_ns;
    curves.steps.push_back(p);
  }
  if (curves.steps.empty())
    return invalid_argument(name + ": no automated-press steps (a calibration or hand-held session "
                                   "has no force-displacement curves)");
  return curves;
}

Result<FigureSet> session_figures(const std::filesystem::path& session) {
  HC_ASSIGN_OR_RETURN(SessionCurves curves, read_session_curves(session));
  const std::string name = session.filename().string();
  FigureSet set;
  set.title = "Session " + name;
  set.source = session.string();
  std::map<int, int> last_level;  // location -> highest level recorded
  double peak = 0;
  for (const SessionStepPoint& p : curves.steps) {
    last_level[p.location] = std::max(last_level[p.location], p.level);
    peak = std::max(peak, p.force_n);
  }
  if (Result<rec::SessionInfo> info = rec::session_info(session); info.ok()) {
    set.numbers["state"] = info->session_state;
    if (!info->session_reason.empty()) set.numbers["reason"] = info->session_reason;
    set.numbers["duration_s"] = info->duration_s;
    set.numbers["messages"] = info->message_count;
    set.numbers["file_bytes"] = info->file_size;
  }
  set.numbers["steps"] = curves.steps.size();
  set.numbers["locations"] = last_level.size();
  set.numbers["peak_force_n"] = peak;

  Json all = Json::array();
  for (const SessionStepPoint& p : curves.steps) all.push_back(step_json(p));
  plot::Chart overview;
  overview.title = name + ": every location (last force level)";
  overview.x.label = "probe depth from the start point (mm)";
  overview.y.label = "force (N)";
  overview.y.include_zero = true;
  for (const auto& [loc, level] : last_level) {
    plot::Series s;
    s.label = fmt::format("location {}", loc);
    s.marker = plot::MarkerStyle::kCircle;
    for (const SessionStepPoint& p : curves.steps)
      if (p.location == loc && p.level == level) {
        s.x.push_back(units::m_to_mm(p.depth_m));
        s.y.push_back(p.force_n);
      }
    overview.series.push_back(std::move(s));
  }
  Json locations = Json::array();
  for (const auto& l : curves.locations_m) locations.push_back(l);
  set.figures.push_back(
      {"session_forces",
       "Force against the probe's depth at every probe location (its last force level), from the "
       "session's step markers.",
       overview, Json{{"session", session.string()}, {"locations_m", locations}, {"steps", all}}});
  for (const auto& [loc, level] : last_level) {
    Json steps = Json::array();
    for (const SessionStepPoint& p : curves.steps)
      if (p.location == loc) steps.push_back(step_json(p));
    set.figures.push_back({fmt::format("session_forces_loc{}", loc),
                           fmt::format("Location {}: force against depth, one curve per force "
                                       "level.",
                                       loc),
                           location_chart(curves, loc, name),
                           Json{{"session", session.string()}, {"location", loc}, {"steps", steps}}});
  }
  return set;
}

}  // namespace hc::figures
