// `hardcopy report`: one self-contained HTML page (no external file, script or font: every figure
// is an <img> with a data: URI) gathering figure sets — a session's, a fit's, a design's — with
// their headline numbers and captions.
#pragma once

#include <string>
#include <vector>

#include "common/status.h"
#include "figures/figure.h"

namespace hc::figures {

struct ReportOptions {
  std::string title = "Hardcopy report";
  plot::ImageFormat format = plot::ImageFormat::kSvg;  // of the embedded figures
  plot::RenderOptions render;
  std::string generator = "hardcopy";  // written in the page's <meta name="generator">
};

// The page's text. Fails when a figure cannot be drawn.
Result<std::string> report_html(const std::vector<FigureSet>& sets, const ReportOptions& options);

// Escapes & < > " ' for HTML text and attribute values.
std::string html_escape(std::string_view text);
// RFC 4648 base64 (with padding).
std::string base64(std::string_view bytes);

}  // namespace hc::figures
