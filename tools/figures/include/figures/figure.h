// A figure of the lab's view: a drawing (a chart or a surface colour map) plus the source numbers it
// shows, in SI units, so that a test (or a reader of the report) can check what is plotted against
// the session or samples file it came from. A FigureSet is what one input (a session, a samples
// file, a comparison) contributes: figures, a table of headline numbers, and extra files (VTU).
#pragma once

#include <filesystem>
#include <string>
#include <utility>
#include <variant>
#include <vector>

#include "common/json.h"
#include "common/status.h"
#include "plot/chart.h"
#include "plot/surface_map.h"

namespace hc::figures {

struct Figure {
  std::string name;     // file stem, e.g. "session_forces_loc0"
  std::string caption;  // one sentence saying what is shown
  std::variant<plot::Chart, plot::SurfaceMap> drawing;
  Json data;  // the source numbers (SI), e.g. {"points": [{"location", "depth_m", "force_n"}...]}
};

struct FigureSet {
  std::string title;                   // e.g. "Session block-20261122T120501Z.mcap"
  std::string source;                  // the input path(s)
  Json numbers = Json::object();       // headline numbers for the report table (name -> value)
  std::vector<Figure> figures;
  std::vector<std::pair<std::string, std::string>> files;  // extra outputs: name -> bytes
};

// Renders a figure into the given format.
Result<std::string> render_figure(const Figure& figure, plot::ImageFormat format,
                                  const plot::RenderOptions& options = {});

// Writes, into `dir` (created if missing), per figure NAME.png / NAME.svg (as asked), NAME.csv (the
// plotted numbers, as drawn: display units) and NAME.json ({"name", "caption", "source": data,
// "plotted": the chart's data}), plus the set's extra files and `numbers.json`. Every file is
// written atomically; a figure that cannot be drawn fails the call before any file is written.
// Returns the paths written.
Result<std::vector<std::filesystem::path>> write_figure_set(
    const FigureSet& set, const std::filesystem::path& dir,
    const std::vector<plot::ImageFormat>& formats, const plot::RenderOptions& options = {});

// "png,svg" -> formats; kInvalidArgument naming an unknown entry.
Result<std::vector<plot::ImageFormat>> parse_formats(std::string_view list);

}  // namespace hc::figures
