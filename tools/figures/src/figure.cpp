#include "figures/figure.h"

#include <set>

#include "common/file_io.h"

namespace hc::figures {

Result<std::string> render_figure(const Figure& figure, plot::ImageFormat format,
                                  const plot::RenderOptions& options) {
  if (const auto* chart = std::get_if<plot::Chart>(&figure.drawing))
    return plot::render_chart(*chart, format, options);
  return plot::render_surface_map(std::get<plot::SurfaceMap>(figure.drawing), format, options);
}

Result<std::vector<std::filesystem::path>> write_figure_set(
    const FigureSet& set, const std::filesystem::path& dir,
    const std::vector<plot::ImageFormat>& formats, const plot::RenderOptions& options) {
  // Everything is rendered first, so that a figure that cannot be drawn leaves no file behind.
  std::vector<std::pair<std::filesystem::path, std::string>> out;
  std::set<std::string> names;
  for (const Figure& f : set.figures) {
    if (f.name.empty() || f.name.find_first_of("/\\") != std::string::npos)
      return invalid_argument("figure name '" + f.name + "' is not a file stem");
    if (!names.insert(f.name).second)
      return internal_error("two figures named '" + f.name + "' in '" + set.title + "'");
    for (plot::ImageFormat fmt : formats) {
      Result<std::string> bytes = render_figure(f, fmt, options);
      if (!bytes.ok()) return bytes.status().with_context("figure " + f.name);
      out.emplace_back(dir / (f.name + std::string(plot::extension(fmt))), std::move(*bytes));
    }
    Json j{{"name", f.name}, {"caption", f.caption}, {"source", f.data}};
    if (const auto* chart = std::get_if<plot::Chart>(&f.drawing)) {
      j["plotted"] = plot::chart_data_json(*chart);
      out.emplace_back(dir / (f.name + ".csv"), plot::chart_data_csv(*chart));
    }
    out.emplace_back(dir / (f.name + ".json"), j.dump(1) + "\n");
  }
  for (const auto& [name, bytes] : set.files) out.emplace_back(dir / name, bytes);
  Json numbers{{"title", set.title}, {"source", set.source}, {"numbers", set.numbers}};
  out.emplace_back(dir / "numbers.json", numbers.dump(1) + "\n");

  std::error_code ec;
  std::filesystem::create_directories(dir, ec);
  if (ec) return io_error("cannot create " + dir.string() + ": " + ec.message());
  std::vector<std::filesystem::path> written;
  for (const auto& [path, bytes] : out) {
    HC_RETURN_IF_ERROR(write_file_atomic(path, bytes));
    written.push_back(path);
  }
  return written;
}

Result<std::vector<plot::ImageFormat>> parse_formats(std::string_view list) {
  std::vector<plot::ImageFormat> formats;
  std::size_t start = 0;
  while (start <= list.size()) {
    const std::size_t comma = std::min(list.find(',', start), list.size());
    const std::string_view item = list.substr(start, comma - start);
    if (item == "png")
      formats.push_back(plot::ImageFormat::kPng);
    else if (item == "svg")
      formats.push_back(plot::ImageFormat::kSvg);
    else
      return invalid_argument("--format: unknown format '" + std::string(item) +
                              "' (expected png, svg or png,svg)");
    start = comma + 1;
  }
  std::sort(formats.begin(), formats.end());
  formats.erase(std::unique(formats.begin(), formats.end()), formats.end());
  return formats;
}

}  // namespace hc::figures
