// A Cairo drawing surface of one of the output formats, finished into bytes (PNG file bytes or SVG
// text), and the text and colour helpers the chart and the surface map share. Private to
// hardcopy_plot: only its sources include Cairo.
#pragma once

#include <cairo.h>

#include <memory>
#include <string>
#include <string_view>

#include "common/status.h"
#include "plot/chart.h"

namespace hc::plot::detail {

class Canvas {
 public:
  // kInvalidArgument for a size outside 100..8000; kInternal when Cairo cannot create the surface.
  static Result<std::unique_ptr<Canvas>> create(ImageFormat format, int width, int height);
  ~Canvas();
  Canvas(const Canvas&) = delete;
  Canvas& operator=(const Canvas&) = delete;

  cairo_t* cr() const { return cr_; }
  int width() const { return width_; }
  int height() const { return height_; }
  // Ends drawing and returns the file's bytes; kInternal naming Cairo's error when drawing failed.
  Result<std::string> finish();

 private:
  Canvas() = default;
  ImageFormat format_ = ImageFormat::kPng;
  int width_ = 0, height_ = 0;
  std::string bytes_;  // the SVG surface streams here while it draws
  cairo_surface_t* surface_ = nullptr;
  cairo_t* cr_ = nullptr;
};

enum class Align { kStart, kCentre, kEnd };

// The font every figure uses (DejaVu Sans through fontconfig's "sans-serif").
void set_font(cairo_t* cr, double size, bool bold = false);
// Width and height (ascent) of `text` in the current font.
double text_width(cairo_t* cr, std::string_view text);
double text_height(cairo_t* cr);
// Draws `text` with its anchor at (x, y): horizontally by `h`, vertically by `v` (kStart = top,
// kCentre = middle, kEnd = baseline), rotated by `angle_rad` around the anchor.
void draw_text(cairo_t* cr, std::string_view text, double x, double y, Align h, Align v,
               double angle_rad = 0);
void set_color(cairo_t* cr, const Rgb& c, double alpha = 1.0);

}  // namespace hc::plot::detail
