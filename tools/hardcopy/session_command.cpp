// hardcopy session info | verify | recover | export
#include <fmt/format.h>

#include <string>

#include "command.h"
#include "common/json.h"
#include "rig_daemon/recording/mcap_tools.h"

namespace hc::cli {
namespace {

namespace rec = hc::recording;

std::string human_bytes(std::uint64_t b) {
  const double v = static_cast<double>(b);
  if (v >= 1e9) return fmt::format("{:.2f} GB", v / 1e9);
  if (v >= 1e6) return fmt::format("{:.2f} MB", v / 1e6);
  if (v >= 1e3) return fmt::format("{:.1f} kB", v / 1e3);
  return fmt::format("{} B", b);
}

struct InfoArgs {
  std::string input;
  bool json = false;
};

int run_info(const GlobalOptions& global, const InfoArgs& args) {
  Context ctx(global);
  auto info = rec::session_info(args.input);
  if (!info.ok()) return ctx.fail("session info", info.status());
  if (args.json) {
    (void)print_json(info->to_json());
    return kExitYes;
  }
  fmt::print("{}\n", info->path);
  fmt::print("  file        {} ({}), library '{}'{}\n", human_bytes(info->file_size),
             info->has_summary ? "indexed" : "no summary: read linearly", info->header.library,
             info->header.profile.empty() ? "" : ", profile '" + info->header.profile + "'");
  fmt::print("  messages    {} in {} chunks", info->message_count, info->chunk_count);
  for (const auto& [c, n] : info->compression_chunks) fmt::print(", {} {}", n, c);
  fmt::print("\n");
  if (info->uncompressed_bytes > 0)
    fmt::print("  data        {} uncompressed, {} stored ({:.2f}x)\n",
               human_bytes(info->uncompressed_bytes), human_bytes(info->compressed_bytes),
               info->compressed_bytes > 0 ? static_cast<double>(info->uncompressed_bytes) /
                                                static_cast<double>(info->compressed_bytes)
                                          : 0.0);
  fmt::print("  duration    {:.3f} s (log_time {} .. {} ns)\n", info->duration_s, info->start_time,
             info->end_time);
  fmt::print("  channels    {}\n", info->channels.size());
  for (const auto& c : info->channels) {
    fmt::print("    {:>3} {:<28} {:>9} msgs {:>10.2f} Hz  {} / {}\n", c.id, c.topic,
               c.message_count, c.rate_hz, c.message_encoding,
               c.schema_name.empty() ? "(no schema)" : c.schema_name);
  }
  if (!info->metadata_names.empty()) {
    fmt::print("  metadata   ");
    for (const auto& m : info->metadata_names) fmt::print(" {}", m);
    fmt::print("\n");
  }
  if (!info->attachment_names.empty()) {
    fmt::print("  attachments");
    for (const auto& a : info->attachment_names) fmt::print(" {}", a);
    fmt::print("\n");
  }
  if (!info->device_stats.empty()) {
    fmt::print("  devices     {:<20} {:>10} {:>8} {:>8} {:>10}\n", "", "received", "lost", "late",
               "incomplete");
    for (const auto& d : info->device_stats)
      fmt::print("              {:<20} {:>10} {:>8} {:>8} {:>10}\n", d.device, d.received, d.lost,
                 d.late, d.incomplete);
  }
  if (!info->session_state.empty())
    fmt::print("  session     {}{}\n", info->session_state,
               info->session_reason.empty() ? "" : " (" + info->session_reason + ")");
  return kExitYes;
}

struct VerifyArgs {
  std::string input;
  bool json = false;
};

int run_verify(const GlobalOptions& global, const VerifyArgs& args) {
  Context ctx(global);
  if (auto* p = ctx.progress()) p->begin("verify " + args.input, 0);
  auto report = rec::verify(args.input);
  if (auto* p = ctx.progress()) p->end("");
  if (!report.ok()) return ctx.fail("session verify", report.status());
  if (args.json) {
    Json j = report->to_json();
    j["file"] = args.input;
    (void)print_json(j);
  } else {
    fmt::print("{}: {} ({} chunks, {} messages, {} CRCs checked{})\n", args.input,
               report->ok ? "OK" : "FAILED", report->chunks_checked, report->messages_checked,
               report->crcs_checked, report->has_summary ? "" : ", no summary");
    for (const auto& p : report->problems) fmt::print("  {}\n", p);
  }
  return report->ok ? kExitYes : kExitNo;
}

struct RecoverArgs {
  std::string input;
  std::string output;
  std::string compression = "zstd";
  std::uint64_t chunk_size = 4u << 20;
  bool json = false;
};

int run_recover(const GlobalOptions& global, const RecoverArgs& args) {
  Context ctx(global);
  rec::McapWriter::Options opt;
  auto c = rec::parse_compression(args.compression);
  if (!c.ok()) return ctx.fail("session recover", c.status().with_context("--compression"));
  opt.compression = *c;
  opt.chunk_size = args.chunk_size;
  opt.library = std::string("hardcopy ") + HARDCOPY_VERSION + " (session recover)";
  if (auto* p = ctx.progress()) p->begin("recover " + args.input, 0);
  auto report = rec::recover(args.input, args.output, opt);
  if (auto* p = ctx.progress()) p->end("");
  if (!report.ok()) return ctx.fail("session recover", report.status());
  if (args.json) {
    Json j = report->to_json();
    j["input"] = args.input;
    j["output"] = args.output;
    (void)print_json(j);
  } else {
    fmt::print("wrote {}: {} chunks kept, {} dropped, {} messages, {} metadata, {} attachments{}\n",
               args.output, report->chunks_kept, report->chunks_dropped, report->messages_kept,
               report->metadata_kept, report->attachments_kept,
               report->input_was_complete ? " (input was complete)"
                                          : "; input stopped at " + report->stop_reason);
    if (report->messages_dropped > 0)
      fmt::print("  {} messages dropped: their channel is defined nowhere intact in the file\n",
                 report->messages_dropped);
  }
  return kExitYes;
}

struct ExportArgs {
  std::string input;
  std::string channel;
  std::string output;
  bool json = false;
};

int run_export(const GlobalOptions& global, const ExportArgs& args) {
  Context ctx(global);
  if (auto* p = ctx.progress()) p->begin("export " + args.channel, 0);
  auto report = rec::export_channel(args.input, args.channel, args.output);
  if (auto* p = ctx.progress()) p->end("");
  if (!report.ok()) return ctx.fail("session export", report.status());
  if (args.json) {
    (void)print_json(report->to_json());
  } else {
    fmt::print("exported {} messages of '{}' as {} into {} ({} files)\n", report->messages,
               report->topic, report->kind, args.output, report->files.size());
  }
  return kExitYes;
}

}  // namespace

void add_session_commands(CLI::App& app, const GlobalOptions& global, int* exit_code) {
  CLI::App* session =
      app.add_subcommand("session", "Inspect, verify, recover and export MCAP capture sessions");
  session->require_subcommand(1);

  auto info = std::make_shared<InfoArgs>();
  CLI::App* i = session->add_subcommand(
      "info",
      "Channels, schemas, message counts, duration, rates, metadata and lost samples per device.\n"
      "Exit 0 on success, 2 when the file cannot be read.");
  i->add_option("FILE", info->input, "Session file (.mcap)")->required();
  i->add_flag("--json", info->json, "Print one JSON object");
  i->callback([&global, info, exit_code] { *exit_code = run_info(global, *info); });

  auto verify = std::make_shared<VerifyArgs>();
  CLI::App* v = session->add_subcommand(
      "verify",
      "Check every CRC and cross-check every index against the records.\nExit 0 when everything "
      "checks out, 1 when a problem is found, 2 when the file cannot be read (not MCAP).");
  v->add_option("FILE", verify->input, "Session file (.mcap)")->required();
  v->add_flag("--json", verify->json, "Print one JSON object");
  v->callback([&global, verify, exit_code] { *exit_code = run_verify(global, *verify); });

  auto recover = std::make_shared<RecoverArgs>();
  CLI::App* r = session->add_subcommand(
      "recover",
      "Rewrite a session cut off by a crash (or damaged) as a valid file holding every complete "
      "chunk whose CRC checks, with a fresh summary.\nExit 0 on success, 2 on unreadable input.");
  r->add_option("FILE", recover->input, "Damaged session file (.mcap)")->required();
  r->add_option("-o,--output", recover->output, "Recovered file to write")->required();
  r->add_option("--compression", recover->compression, "Output chunk compression: zstd, lz4, none")
      ->capture_default_str();
  r->add_option("--chunk-size", recover->chunk_size, "Output chunk size, uncompressed bytes")
      ->check(kPositive)
      ->capture_default_str();
  r->add_flag("--json", recover->json, "Print one JSON object");
  r->callback([&global, recover, exit_code] { *exit_code = run_recover(global, *recover); });

  auto exp = std::make_shared<ExportArgs>();
  CLI::App* e = session->add_subcommand(
      "export",
      "Export one channel: CSV for JSON time series (fields flattened to columns), PNG per frame "
      "for foxglove.RawImage, stored bytes for foxglove.CompressedImage.\nExit 0 on success, 2 on "
      "bad input or an unknown channel.");
  e->add_option("FILE", exp->input, "Session file (.mcap)")->required();
  e->add_option("--channel", exp->channel, "Topic of the channel to export, e.g. /ft/wrench")
      ->required();
  e->add_option("-o,--output", exp->output, "Output directory (created if missing)")->required();
  e->add_flag("--json", exp->json, "Print one JSON object");
  e->callback([&global, exp, exit_code] { *exit_code = run_export(global, *exp); });
}

HC_REGISTER_COMMANDS_ORDERED(20, add_session_commands);

}  // namespace hc::cli
