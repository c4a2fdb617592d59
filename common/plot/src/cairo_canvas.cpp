#include "cairo_canvas.h"

#include <cairo-svg.h>

#include <cmath>
#include <string>

namespace hc::plot::detail {
namespace {

constexpr int kMinSidePx = 100;
constexpr int kMaxSidePx = 8000;

cairo_status_t append_bytes(void* closure, const unsigned char* data, unsigned int length) {
  static_cast<std::string*>(closure)->append(reinterpret_cast<const char*>(data), length);
  return CAIRO_STATUS_SUCCESS;
}

Status cairo_error(std::string_view what, cairo_status_t status) {
  return internal_error(std::string(what) + ": " + cairo_status_to_string(status));
}

}  // namespace

Result<std::unique_ptr<Canvas>> Canvas::create(ImageFormat format, int width, int height) {
  if (width < kMinSidePx || width > kMaxSidePx || height < kMinSidePx || height > kMaxSidePx)
    return invalid_argument("image size " + std::to_string(width) + "x" + std::to_string(height) +
                            ": each side must be " + std::to_string(kMinSidePx) + ".." +
                            std::to_string(kMaxSidePx) + " pixels");
  std::unique_ptr<Canvas> c(new Canvas());
  c->format_ = format;
  c->width_ = width;
  c->height_ = height;
  c->surface_ = format == ImageFormat::kPng
                    ? cairo_image_surface_create(CAIRO_FORMAT_ARGB32, width, height)
                    : cairo_svg_surface_create_for_stream(append_bytes, &c->bytes_, width, height);
  if (cairo_status_t s = cairo_surface_status(c->surface_); s != CAIRO_STATUS_SUCCESS)
    return cairo_error("cannot create the drawing surface", s);
  c->cr_ = cairo_create(c->surface_);
  if (cairo_status_t s = cairo_status(c->cr_); s != CAIRO_STATUS_SUCCESS)
    return cairo_error("cannot draw on the surface", s);
  // A white page: PNGs are opaque and SVGs look the same on any background.
  cairo_set_source_rgb(c->cr_, 1, 1, 1);
  cairo_paint(c->cr_);
  return c;
}

Canvas::~Canvas() {
  if (cr_ != nullptr) cairo_destroy(cr_);
  if (surface_ != nullptr) cairo_surface_destroy(surface_);
}

Result<std::string> Canvas::finish() {
  if (cairo_status_t s = cairo_status(cr_); s != CAIRO_STATUS_SUCCESS)
    return cairo_error("drawing failed", s);
  cairo_destroy(cr_);
  cr_ = nullptr;
  if (format_ == ImageFormat::kPng) {
    cairo_surface_flush(surface_);
    if (cairo_status_t s = cairo_surface_write_to_png_stream(surface_, append_bytes, &bytes_);
        s != CAIRO_STATUS_SUCCESS)
      return cairo_error("PNG encoding failed", s);
  } else {
    cairo_surface_finish(surface_);  // the SVG surface writes its document now
    if (cairo_status_t s = cairo_surface_status(surface_); s != CAIRO_STATUS_SUCCESS)
      return cairo_error("SVG output failed", s);
  }
  return std::move(bytes_);
}

void set_font(cairo_t* cr, double size, bool bold) {
  cairo_select_font_face(cr, "sans-serif", CAIRO_FONT_SLANT_NORMAL,
                         bold ? CAIRO_FONT_WEIGHT_BOLD : CAIRO_FONT_WEIGHT_NORMAL);
  cairo_set_font_size(cr, size);
}

double text_width(cairo_t* cr, std::string_view text) {
  const std::string s(text);
  cairo_text_extents_t e;
  cairo_text_extents(cr, s.c_str(), &e);
  return e.x_advance;
}

double text_height(cairo_t* cr) {
  cairo_font_extents_t e;
  cairo_font_extents(cr, &e);
  return e.ascent;
}

void draw_text(cairo_t* cr, std::string_view text, double x, double y, Align h, Align v,
               double angle_rad) {
  const std::string s(text);
  const double w = text_width(cr, s);
  const double a = text_height(cr);
  const double dx = h == Align::kStart ? 0 : h == Align::kCentre ? -w / 2 : -w;
  const double dy = v == Align::kStart ? a : v == Align::kCentre ? a / 2 : 0;
  cairo_save(cr);
  cairo_translate(cr, x, y);
  cairo_rotate(cr, angle_rad);
  cairo_move_to(cr, dx, dy);
  cairo_show_text(cr, s.c_str());
  cairo_restore(cr);
}

void set_color(cairo_t* cr, const Rgb& c, double alpha) {
  cairo_set_source_rgba(cr, c.r, c.g, c.b, alpha);
}

}  // namespace hc::plot::detail
