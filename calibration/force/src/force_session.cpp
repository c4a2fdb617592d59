#include "calibration/force/force_session.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>

#include "common/json.h"
#include "rig_daemon/recording/mcap_reader.h"
#include "rig_daemon/recording/session_conventions.h"
#include "rig_daemon/session/codec.h"
#include "rig_daemon/session/topics.h"

namespace hc::calib {
namespace {

namespace rec = hc::recording;

std::string_view as_view(rec::ByteSpan b) {
  return {reinterpret_cast<const char*>(b.data()), b.size()};
}

// The topic of the channel with metadata kind `kind` (and device `device` when not empty).
const rec::Channel* find_device_channel(const rec::McapReader& reader, std::string_view kind,
                                        std::string_view device) {
  for (const auto& [id, ch] : reader.channels()) {
    const auto k = ch.metadata.find("kind");
    if (k == ch.metadata.end() || k->second != kind) continue;
    if (!device.empty()) {
      const auto d = ch.metadata.find("device");
      if (d == ch.metadata.end() || d->second != device) continue;
    }
    return &ch;
  }
  return nullptr;
}

std::string device_of(const rec::Channel& ch) {
  const auto d = ch.metadata.find("device");
  return d == ch.metadata.end() ? ch.topic : d->second;
}

}  // namespace

Result<ForceSession> read_force_session(const std::filesystem::path& path,
                                        const ForceSessionOptions& options) {
  const std::string name = path.string();
  HC_ASSIGN_OR_RETURN(rec::McapReader reader, rec::McapReader::open(path));
  ForceSession out;
  const rec::Channel* ft = nullptr;
  const rec::Channel* fsr = nullptr;
  if (options.want_ft) {
    ft = find_device_channel(reader, "force_torque", options.ft_device);
    if (!ft)
      return invalid_argument(fmt::format(
          "{}: no force_torque channel{} (a session of the automated protocol records one)", name,
          options.ft_device.empty() ? "" : " of device '" + options.ft_device + "'"));
    out.ft_device = device_of(*ft);
  }
  if (options.want_fsr) {
    fsr = find_device_channel(reader, "fsr", options.fsr_device);
    if (!fsr)
      return invalid_argument(
          fmt::format("{}: no fsr channel{}", name,
                      options.fsr_device.empty() ? "" : " of device '" + options.fsr_device + "'"));
    out.fsr_device = device_of(*fsr);
  }

  // Recorded device calibrations.
  HC_ASSIGN_OR_RETURN(std::vector<rec::Metadata> metadata, reader.read_metadata());
  for (const rec::Metadata& m : metadata) {
    if (m.name != rec::kMetadataCalibration) continue;
    const auto js = m.metadata.find("json");
    if (js == m.metadata.end()) continue;
    Result<Json> j = parse_json(js->second, name + ": metadata calibration");
    if (!j.ok()) return j.status();
    if (!j->is_object()) continue;
    try {  // nlohmann throws on type mismatches: a malformed record is bad input, not a crash
      if (ft && j->contains(out.ft_device)) {
        const Json& c = (*j)[out.ft_device];
        out.counts_per_n = c.value("counts_per_n", out.counts_per_n);
        out.counts_per_nm = c.value("counts_per_nm", out.counts_per_nm);
      }
      if (fsr && j->contains(out.fsr_device)) {
        const Json& c = (*j)[out.fsr_device];
        FsrPowerLaw p;
        p.full_scale = c.value("full_scale", p.full_scale);
        p.threshold = c.value("threshold", p.threshold);
        p.scale_n = c.value("scale_n", p.scale_n);
        p.exponent = c.value("exponent", p.exponent);
        out.recorded_fsr = p;
      }
    } catch (const Json::exception& e) {
      return invalid_argument(fmt::format("{}: metadata calibration: {}", name, e.what()));
    }
  }
  if (!(out.counts_per_n > 0.0) || !(out.counts_per_nm > 0.0) || !std::isfinite(out.counts_per_n) ||
      !std::isfinite(out.counts_per_nm))
    return invalid_argument(name + ": metadata calibration: counts per unit must be > 0");
  if (out.recorded_fsr &&
      (!(out.recorded_fsr->full_scale > 0.0) || !std::isfinite(out.recorded_fsr->full_scale)))
    return invalid_argument(name + ": metadata calibration: FSR full_scale must be > 0");

  rec::ReadOptions ro;
  ro.order = rec::ReadOrder::kLogTime;
  if (ft) ro.topics.push_back(ft->topic);
  if (fsr) ro.topics.push_back(fsr->topic);
  const rec::Channel* truth = nullptr;
  if (options.want_truth) {
    truth = reader.find_channel(hc::session::kGroundTruthTopic);
    if (truth) ro.topics.push_back(truth->topic);
  }
  Status error;
  const Status read = reader.read_messages(ro, [&](const rec::MessageEvent& e) {
    const std::string_view text = as_view(e.message.data);
    if (ft && e.channel->id == ft->id) {
      Result<session::WrenchSample> s = session::wrench_sample_from_json(text);
      if (!s.ok()) {
        error = s.status().with_context(
            fmt::format("{}: {} sequence {}", name, ft->topic, e.message.sequence));
        return false;
      }
      WrenchReading r;
      r.t_ns = s->host_ns;
      for (int i = 0; i < 6; ++i)
        r.w[i] = static_cast<double>(s->counts[static_cast<std::size_t>(i)]) /
                 (i < 3 ? out.counts_per_n : out.counts_per_nm);
      out.wrench.push_back(r);
    } else if (fsr && e.channel->id == fsr->id) {
      Result<session::FsrSample> s = session::fsr_sample_from_json(text);
      if (!s.ok()) {
        error = s.status().with_context(
            fmt::format("{}: {} sequence {}", name, fsr->topic, e.message.sequence));
        return false;
      }
      out.fsr.push_back({s->host_ns, static_cast<double>(s->raw), s->trigger_index});
    } else if (truth && e.channel->id == truth->id) {
      Result<session::GroundTruthRecord> t = session::ground_truth_from_json(text);
      if (!t.ok()) {
        error = t.status().with_context(
            fmt::format("{}: {} sequence {}", name, truth->topic, e.message.sequence));
        return false;
      }
      out.truth.push_back({t->host_ns, t->force_n});
    }
    return true;
  });
  HC_RETURN_IF_ERROR(read);
  HC_RETURN_IF_ERROR(error);
  if (ft && out.wrench.empty())
    return invalid_argument(fmt::format("{}: {}: no wrench samples", name, ft->topic));
  if (fsr && out.fsr.empty())
    return invalid_argument(fmt::format("{}: {}: no FSR samples", name, fsr->topic));
  const auto by_time = [](const auto& a, const auto& b) { return a.t_ns < b.t_ns; };
  std::stable_sort(out.wrench.begin(), out.wrench.end(), by_time);
  std::stable_sort(out.fsr.begin(), out.fsr.end(), by_time);
  std::stable_sort(out.truth.begin(), out.truth.end(), by_time);
  return out;
}

std::vector<FsrPair> pair_fsr_with_ft(const ForceSession& session, const FtBiasResult& bias,
                                      std::int64_t max_gap_ns) {
  std::vector<FsrPair> out;
  const auto& w = session.wrench;
  for (const FsrReading& r : session.fsr) {
    const auto it =
        std::lower_bound(w.begin(), w.end(), r.t_ns,
                         [](const WrenchReading& a, std::int64_t t) { return a.t_ns < t; });
    if (it == w.end()) continue;
    Vector6d v;
    if (it->t_ns == r.t_ns) {
      v = it->w;
    } else {
      if (it == w.begin()) continue;
      const WrenchReading& a = *std::prev(it);
      const WrenchReading& b = *it;
      if (r.t_ns - a.t_ns > max_gap_ns || b.t_ns - r.t_ns > max_gap_ns) continue;
      const double f = static_cast<double>(r.t_ns - a.t_ns) / static_cast<double>(b.t_ns - a.t_ns);
      v = a.w + f * (b.w - a.w);
    }
    const Vector6d corrected = v - bias.bias_at(r.t_ns);
    out.push_back({r.raw, corrected.head<3>().norm()});
  }
  return out;
}

std::optional<double> truth_force_at(const ForceSession& session, std::int64_t t_ns) {
  const auto& tr = session.truth;
  const auto it = std::lower_bound(tr.begin(), tr.end(), t_ns,
                                   [](const TruthForce& a, std::int64_t t) { return a.t_ns < t; });
  if (it == tr.end()) return std::nullopt;
  if (it->t_ns == t_ns) return it->force_n;
  if (it == tr.begin()) return std::nullopt;
  const TruthForce& a = *std::prev(it);
  constexpr std::int64_t kMaxGapNs = 2'000'000;
  if (t_ns - a.t_ns > kMaxGapNs || it->t_ns - t_ns > kMaxGapNs) return std::nullopt;
  const double f = static_cast<double>(t_ns - a.t_ns) / static_cast<double>(it->t_ns - a.t_ns);
  return a.force_n + f * (it->force_n - a.force_n);
}

}  // namespace hc::calib
