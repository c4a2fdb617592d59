#include "figures/report.h"

#include <fmt/format.h>

#include <ctime>

namespace hc::figures {
namespace {

// The page's style: the report must read the same offline, so nothing is fetched.
constexpr std::string_view kStyle = R"(
body { font-family: "DejaVu Sans", sans-serif; margin: 2em auto; max-width: 1100px; color: #222; }
h1 { font-size: 1.6em; } h2 { font-size: 1.25em; border-bottom: 1px solid #ccc; margin-top: 2em; }
table.numbers { border-collapse: collapse; margin: 0.5em 0 1em; }
table.numbers td, table.numbers th { border: 1px solid #ddd; padding: 0.25em 0.7em; text-align: left; }
table.numbers td.v { font-family: "DejaVu Sans Mono", monospace; text-align: right; }
figure { margin: 1em 0 2em; } figure img { max-width: 100%; border: 1px solid #eee; }
figcaption { font-size: 0.92em; color: #444; margin-top: 0.3em; }
.source { font-family: "DejaVu Sans Mono", monospace; font-size: 0.85em; color: #555; }
)";

std::string format_value(const Json& v) {
  if (v.is_number_float()) return fmt::format("{:.6g}", v.get<double>());
  if (v.is_string()) return v.get<std::string>();
  return v.dump();
}

}  // namespace

std::string html_escape(std::string_view text) {
  std::string out;
  out.reserve(text.size());
  for (char c : text) {
    switch (c) {
      case '&':
        out += "&amp;";
        break;
      case '<':
        out += "&lt;";
        break;
      case '>':
        out += "&gt;";
        break;
      case '"':
        out += "&quot;";
        break;
      case '\'':
        out += "&#39;";
        break;
      default:
        out += c;
    }
  }
  return out;
}

std::string base64(std::string_view bytes) {
  static constexpr char kAlphabet[] =
      "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
  std::string out;
  out.reserve((bytes.size() + 2) / 3 * 4);
  std::size_t i = 0;
  for (; i + 2 < bytes.size(); i += 3) {
    const auto a = static_cast<unsigned char>(bytes[i]);
    const auto b = static_cast<unsigned char>(bytes[i + 1]);
    const auto c = static_cast<unsigned char>(bytes[i + 2]);
    out += kAlphabet[a >> 2];
    out += kAlphabet[((a & 3) << 4) | (b >> 4)];
    out += kAlphabet[((b & 15) << 2) | (c >> 6)];
    out += kAlphabet[c & 63];
  }
  if (i + 1 == bytes.size()) {
    const auto a = static_cast<unsigned char>(bytes[i]);
    out += kAlphabet[a >> 2];
    out += kAlphabet[(a & 3) << 4];
    out += "==";
  } else if (i + 2 == bytes.size()) {
    const auto a = static_cast<unsigned char>(bytes[i]);
    const auto b = static_cast<unsigned char>(bytes[i + 1]);
    out += kAlphabet[a >> 2];
    out += kAlphabet[((a & 3) << 4) | (b >> 4)];
    out += kAlphabet[(b & 15) << 2];
    out += '=';
  }
  return out;
}

Result<std::string> report_html(const std::vector<FigureSet>& sets, const ReportOptions& options) {
  const std::string mime =
      options.format == plot::ImageFormat::kSvg ? "image/svg+xml" : "image/png";
  std::string body;
  for (std::size_t si = 0; si < sets.size(); ++si) {
    const FigureSet& set = sets[si];
    body += fmt::format("<section id=\"set{}\">\n<h2>{}</h2>\n", si, html_escape(set.title));
    if (!set.source.empty())
      body += fmt::format("<p class=\"source\">{}</p>\n", html_escape(set.source));
    if (!set.numbers.empty()) {
      body += "<table class=\"numbers\">\n";
      for (const auto& [key, value] : set.numbers.items())
        body += fmt::format("<tr><th>{}</th><td class=\"v\">{}</td></tr>\n", html_escape(key),
                            html_escape(format_value(value)));
      body += "</table>\n";
    }
    for (const Figure& f : set.figures) {
      Result<std::string> image = render_figure(f, options.format, options.render);
      if (!image.ok()) return image.status().with_context("figure " + f.name);
      body += fmt::format(
          "<figure id=\"{}-{}\"><img alt=\"{}\" src=\"data:{};base64,{}\">"
          "<figcaption>{}</figcaption></figure>\n",
          si, html_escape(f.name), html_escape(f.name), mime, base64(*image),
          html_escape(f.caption));
    }
    for (const auto& [name, bytes] : set.files)
      body += fmt::format(
          "<p>Also: <a download=\"{0}\" href=\"data:application/octet-stream;base64,{1}\">{0}</a> "
          "({2} bytes).</p>\n",
          html_escape(name), base64(bytes), bytes.size());
    body += "</section>\n";
  }
  const std::time_t now = std::time(nullptr);
  std::tm tm{};
  gmtime_r(&now, &tm);
  char stamp[32];
  std::strftime(stamp, sizeof(stamp), "%Y-%m-%d %H:%M UTC", &tm);
  return fmt::format(
      "<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n"
      "<meta name=\"generator\" content=\"{}\">\n<title>{}</title>\n<style>{}</style>\n</head>\n"
      "<body>\n<h1>{}</h1>\n<p>Generated {} by {}.</p>\n{}</body>\n</html>\n",
      html_escape(options.generator), html_escape(options.title), kStyle,
      html_escape(options.title), stamp, html_escape(options.generator), body);
}

}  // namespace hc::figures
