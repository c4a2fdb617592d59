// hardcopy demo: the main job on the embedded default. Until the rig and FEM exist, it is the
// printability pass a lab runs on incoming models: check every mesh in a folder, repair what can be
// repaired (self-intersections included), and write print-ready 3MF files, with a summary table.
#include <fmt/format.h>

#include <algorithm>
#include <chrono>
#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include "command.h"
#include "common/json.h"
#include "common/mesh_io.h"
#include "fabrication/printability/mesh_check.h"
#include "fabrication/printability/mesh_repair.h"

namespace hc::cli {
namespace {

namespace fs = std::filesystem;

struct DemoArgs {
  std::string data_dir;
  std::string out_dir = "out/demo";
  bool json = false;
};

struct Row {
  std::string file;
  std::string status;  // "printable", "repaired", "not printable", or the read error
  fabrication::MeshCheckReport report;
  std::string output;
  std::int64_t resolved_self_intersecting_pairs = 0;
  double seconds = 0.0;
};

bool is_mesh_file(const fs::path& p) { return mesh_format_from_path(p).ok(); }

Row process(const fs::path& file, const fs::path& out_dir, ProgressReporter* progress) {
  const auto start = std::chrono::steady_clock::now();
  Row row;
  row.file = file.filename().string();
  Result<TriangleMesh> mesh = read_mesh(file);
  if (!mesh.ok()) {
    row.status = "unreadable: " + mesh.status().message();
    return row;
  }
  fabrication::MeshCheckOptions check;
  check.progress = progress;
  Result<fabrication::MeshCheckReport> report = fabrication::check_mesh(*mesh, check);
  if (!report.ok()) {
    row.status = "check failed: " + report.status().message();
    return row;
  }
  row.report = *report;
  row.status = "printable";
  if (!report->printable) {
    fabrication::MeshRepairOptions repair;
    // Only meshes that failed the check get here, so the stage that may move the surface (within
    // the default self_intersection_max_deviation) never touches a printable one.
    repair.resolve_self_intersections = true;
    repair.progress = progress;
    fabrication::MeshRepairSummary summary;
    if (Status s = fabrication::repair_mesh(repair, &*mesh, &summary); !s.ok()) {
      row.status = "repair failed: " + s.message();
      return row;
    }
    row.report = summary.after;
    row.resolved_self_intersecting_pairs = summary.resolved_self_intersecting_pairs;
    row.status = summary.printable ? "repaired" : "not printable";
  }
  if (row.report.printable) {
    // Print files carry millimetres; the corpus models are unit-less, so they are taken as mm.
    std::string stem = file.filename().string();
    stem = stem.substr(0, stem.find('.'));
    const fs::path out = out_dir / (stem + ".3mf");
    std::vector<MeshPart> parts{{stem, std::move(*mesh), "", std::nullopt}};
    if (Status s = write_3mf(out, parts); !s.ok())
      row.status = "write failed: " + s.message();
    else
      row.output = out.string();
  }
  row.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return row;
}

int run_demo(const GlobalOptions& global, const DemoArgs& args) {
  Context ctx(global);
  std::error_code ec;
  if (!fs::is_directory(args.data_dir, ec))
    return ctx.fail("demo", not_found(fmt::format("{}: no such directory", args.data_dir)));
  std::vector<fs::path> files;
  for (const auto& e : fs::directory_iterator(args.data_dir, ec))
    if (e.is_regular_file() && is_mesh_file(e.path())) files.push_back(e.path());
  std::sort(files.begin(), files.end());
  if (files.empty())
    return ctx.fail("demo", not_found(fmt::format("{}: holds no mesh files", args.data_dir)));
  fs::create_directories(args.out_dir, ec);
  if (ec)
    return ctx.fail("demo",
                    io_error(fmt::format("{}: cannot create: {}", args.out_dir, ec.message())));

  std::vector<Row> rows;
  for (const auto& f : files) rows.push_back(process(f, args.out_dir, ctx.progress()));

  if (args.json) {
    Json j = Json::array();
    for (const auto& r : rows) {
      Json o = fabrication::to_json(r.report);
      o["file"] = r.file;
      o["status"] = r.status;
      o["output"] = r.output;
      o["resolved_self_intersecting_pairs"] = r.resolved_self_intersecting_pairs;
      o["time_s"] = r.seconds;
      j.push_back(std::move(o));
    }
    (void)hc::print_json(j);
  } else {
    fmt::print("{:<24} {:>9} {:>5} {:>8} {:>8} {:>6} {:>14}  {:<14} {}\n", "mesh", "triangles",
               "comp", "boundary", "misorie", "genus", "volume", "verdict", "output");
    for (const auto& r : rows) {
      const auto& m = r.report;
      fmt::print("{:<24} {:>9} {:>5} {:>8} {:>8} {:>6} {:>14.6g}  {:<14} {}\n", r.file, m.triangles,
                 m.components, m.boundary_edges, m.misoriented_edges,
                 m.genus ? std::to_string(*m.genus) : "-", m.volume, r.status, r.output);
    }
  }
  const bool all_read = std::all_of(rows.begin(), rows.end(), [](const Row& r) {
    return r.status == "printable" || r.status == "repaired" || r.status == "not printable";
  });
  return all_read ? kExitYes : kExitBadInput;
}

}  // namespace

void add_demo_command(CLI::App& app, const GlobalOptions& global, int* exit_code) {
  auto args = std::make_shared<DemoArgs>();
  CLI::App* d = app.add_subcommand(
      "demo", "Check every mesh in a folder, repair what can be repaired, write print-ready 3MF");
  d->add_option("--data", args->data_dir, "Folder of meshes")->required();
  d->add_option("--out", args->out_dir, "Where the 3MF files go")->capture_default_str();
  d->add_flag("--json", args->json, "Print a JSON array, one object per mesh");
  d->callback([&global, args, exit_code] { *exit_code = run_demo(global, *args); });
}

HC_REGISTER_COMMANDS_ORDERED(1000, add_demo_command);

}  // namespace hc::cli
