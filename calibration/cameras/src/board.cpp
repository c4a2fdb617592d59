#include "calibration/cameras/board.h"

#include <fmt/format.h>

#include <opencv2/aruco/charuco.hpp>
#include <opencv2/calib3d.hpp>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <charconv>
#include <cmath>
#include <utility>

namespace hc::calib {

namespace {

struct DictName {
  const char* name;
  int id;
};
constexpr DictName kDictionaries[] = {
    {"DICT_4X4_50", cv::aruco::DICT_4X4_50},
    {"DICT_4X4_100", cv::aruco::DICT_4X4_100},
    {"DICT_4X4_250", cv::aruco::DICT_4X4_250},
    {"DICT_4X4_1000", cv::aruco::DICT_4X4_1000},
    {"DICT_5X5_50", cv::aruco::DICT_5X5_50},
    {"DICT_5X5_100", cv::aruco::DICT_5X5_100},
    {"DICT_5X5_250", cv::aruco::DICT_5X5_250},
    {"DICT_5X5_1000", cv::aruco::DICT_5X5_1000},
    {"DICT_6X6_50", cv::aruco::DICT_6X6_50},
    {"DICT_6X6_100", cv::aruco::DICT_6X6_100},
    {"DICT_6X6_250", cv::aruco::DICT_6X6_250},
    {"DICT_6X6_1000", cv::aruco::DICT_6X6_1000},
    {"DICT_7X7_50", cv::aruco::DICT_7X7_50},
    {"DICT_7X7_100", cv::aruco::DICT_7X7_100},
    {"DICT_7X7_250", cv::aruco::DICT_7X7_250},
    {"DICT_7X7_1000", cv::aruco::DICT_7X7_1000},
    {"DICT_ARUCO_ORIGINAL", cv::aruco::DICT_ARUCO_ORIGINAL},
};

std::optional<int> dictionary_id(std::string_view name) {
  for (const DictName& d : kDictionaries)
    if (name == d.name) return d.id;
  return std::nullopt;
}

std::vector<std::string_view> split(std::string_view s, char sep) {
  std::vector<std::string_view> out;
  std::size_t start = 0;
  for (;;) {
    const std::size_t p = s.find(sep, start);
    out.push_back(
        s.substr(start, p == std::string_view::npos ? std::string_view::npos : p - start));
    if (p == std::string_view::npos) break;
    start = p + 1;
  }
  return out;
}

std::optional<int> parse_int(std::string_view s) {
  int v = 0;
  const auto [ptr, ec] = std::from_chars(s.data(), s.data() + s.size(), v);
  if (ec != std::errc() || ptr != s.data() + s.size()) return std::nullopt;
  return v;
}

std::optional<double> parse_double(std::string_view s) {
  double v = 0.0;
  const auto [ptr, ec] = std::from_chars(s.data(), s.data() + s.size(), v);
  if (ec != std::errc() || ptr != s.data() + s.size() || !std::isfinite(v)) return std::nullopt;
  return v;
}

cv::Ptr<cv::aruco::CharucoBoard> make_charuco(const BoardSpec& b) {
  return cv::aruco::CharucoBoard::create(
      b.cols, b.rows, static_cast<float>(b.square_m), static_cast<float>(b.marker_m),
      cv::aruco::getPredefinedDictionary(*dictionary_id(b.dictionary)));
}

double bilinear(const cv::Mat& grey, const cv::Point2f& p) {
  cv::Mat patch;
  cv::getRectSubPix(grey, cv::Size(3, 3), p, patch, CV_32F);
  return cv::mean(patch)[0];
}

}  // namespace

int BoardSpec::corner_count() const {
  return kind == BoardKind::kChessboard ? cols * rows : (cols - 1) * (rows - 1);
}

Eigen::Vector3d BoardSpec::corner(int id) const {
  if (kind == BoardKind::kChessboard) return {(id % cols) * square_m, (id / cols) * square_m, 0.0};
  // OpenCV 4.6 CharucoBoard: chessboardCorners[id] = ((x + 1) s, (y + 1) s, 0), id = y (X-1) + x.
  return {(id % (cols - 1) + 1) * square_m, (id / (cols - 1) + 1) * square_m, 0.0};
}

std::string BoardSpec::to_string() const {
  if (kind == BoardKind::kChessboard)
    return fmt::format("chessboard:{}x{}:{}", cols, rows, square_m);
  return fmt::format("charuco:{}x{}:{}:{}:{}", cols, rows, square_m, marker_m, dictionary);
}

Result<BoardSpec> parse_board_spec(std::string_view text) {
  const std::string where = fmt::format("pattern '{}'", text);
  const std::vector<std::string_view> parts = split(text, ':');
  BoardSpec b;
  if (parts[0] == "chessboard") {
    b.kind = BoardKind::kChessboard;
    if (parts.size() != 3)
      return invalid_argument(where +
                              ": expected chessboard:COLSxROWS:SQUARE_M, e.g. "
                              "chessboard:9x6:0.025");
  } else if (parts[0] == "charuco") {
    b.kind = BoardKind::kCharuco;
    if (parts.size() != 5)
      return invalid_argument(where +
                              ": expected charuco:COLSxROWS:SQUARE_M:MARKER_M:DICT, e.g. "
                              "charuco:7x5:0.04:0.03:DICT_5X5_100");
  } else {
    return invalid_argument(where + ": unknown board kind '" + std::string(parts[0]) +
                            "' (expected chessboard or charuco)");
  }
  const std::vector<std::string_view> size = split(parts[1], 'x');
  const auto cols = size.size() == 2 ? parse_int(size[0]) : std::nullopt;
  const auto rows = size.size() == 2 ? parse_int(size[1]) : std::nullopt;
  if (!cols || !rows)
    return invalid_argument(where + ": size '" + std::string(parts[1]) +
                            "' is not COLSxROWS (two integers, e.g. 9x6)");
  const int min_size = b.kind == BoardKind::kChessboard ? 2 : 3;
  if (*cols < min_size || *rows < min_size || *cols > 200 || *rows > 200)
    return invalid_argument(
        fmt::format("{}: size {}x{} out of range ({} to 200 {} per side)", where, *cols, *rows,
                    min_size, b.kind == BoardKind::kChessboard ? "inner corners" : "squares"));
  b.cols = *cols;
  b.rows = *rows;
  const auto square = parse_double(parts[2]);
  if (!square || *square <= 0.0 || *square > 10.0)
    return invalid_argument(where + ": square size '" + std::string(parts[2]) +
                            "' must be a positive length in metres (e.g. 0.025)");
  b.square_m = *square;
  if (b.kind == BoardKind::kCharuco) {
    const auto marker = parse_double(parts[3]);
    if (!marker || *marker <= 0.0 || *marker >= b.square_m)
      return invalid_argument(where + ": marker size '" + std::string(parts[3]) +
                              "' must be positive and smaller than the square");
    b.marker_m = *marker;
    b.dictionary = std::string(parts[4]);
    const auto dict = dictionary_id(b.dictionary);
    if (!dict)
      return invalid_argument(where + ": unknown ArUco dictionary '" + b.dictionary +
                              "' (OpenCV names such as DICT_4X4_50, DICT_5X5_100, "
                              "DICT_6X6_250, DICT_ARUCO_ORIGINAL)");
    const int markers = (b.cols * b.rows) / 2;
    const int capacity = cv::aruco::getPredefinedDictionary(*dict)->bytesList.rows;
    if (markers > capacity)
      return invalid_argument(fmt::format("{}: the board needs {} markers but {} has {}", where,
                                          markers, b.dictionary, capacity));
  }
  return b;
}

Result<std::optional<BoardDetection>> detect_board(const ImageView& image, const BoardSpec& board,
                                                   const DetectOptions& options) {
  if (image.data == nullptr || image.width <= 0 || image.height <= 0 ||
      (image.channels != 1 && image.channels != 3) || image.stride < image.width * image.channels)
    return invalid_argument("detect_board: unusable image view");
  cv::Mat grey;
  try {
    // cv::Mat over caller memory (no copy); const_cast because cv::Mat has no const view type.
    const cv::Mat view(image.height, image.width, image.channels == 1 ? CV_8UC1 : CV_8UC3,
                       const_cast<std::uint8_t*>(image.data),
                       static_cast<std::size_t>(image.stride));
    if (image.channels == 3)
      cv::cvtColor(view, grey, cv::COLOR_RGB2GRAY);
    else
      grey = view;

    BoardDetection det;
    if (board.kind == BoardKind::kChessboard) {
      const cv::Size pattern(board.cols, board.rows);
      std::vector<cv::Point2f> corners;
      // As OpenCV's samples/cpp/stereo_calib.cpp and calibration.cpp (the reference results).
      // Like stereo_calib.cpp, a second try on the image upscaled 2x (helps small or blurred
      // boards); the corners are refined on the original image either way.
      bool found = false;
      if (static_cast<double>(grey.cols) * grey.rows > 1.5e6) {
        // Large images: find the board on a half-resolution copy (4x fewer pixels; FAST_CHECK
        // rejects frames without a board quickly), then refine the corners on the full image.
        cv::Mat half;
        cv::pyrDown(grey, half);
        found = cv::findChessboardCorners(
            half, pattern, corners,
            cv::CALIB_CB_ADAPTIVE_THRESH | cv::CALIB_CB_NORMALIZE_IMAGE | cv::CALIB_CB_FAST_CHECK);
        // pyrDown: half-resolution pixel centre x_h is full-resolution 2 x_h + 0.5.
        if (found)
          for (cv::Point2f& p : corners) p = 2.0f * p + cv::Point2f(0.5f, 0.5f);
        else
          corners.clear();
      }
      for (int scale = 1; scale <= 2 && !found && grey.total() <= 1.5e6; ++scale) {
        cv::Mat scaled = grey;
        if (scale > 1) {
          if (static_cast<double>(grey.cols) * grey.rows > 4e6) break;  // large images: no upscale
          cv::resize(grey, scaled, cv::Size(), scale, scale, cv::INTER_LINEAR);
        }
        found = cv::findChessboardCorners(
            scaled, pattern, corners, cv::CALIB_CB_ADAPTIVE_THRESH | cv::CALIB_CB_NORMALIZE_IMAGE);
        if (found && scale > 1)
          for (cv::Point2f& p : corners) p *= 1.0f / static_cast<float>(scale);
      }
      if (found) {
        // Window side (2 half + 1) at most ~1.2 corner spacings: OpenCV's Size(11, 11) on boards
        // whose corners are >= 20 px apart (the reference runs), smaller on tiny boards.
        double spacing = 1e9;
        for (int r = 0; r < board.rows; ++r)
          for (int c = 0; c + 1 < board.cols; ++c) {
            const cv::Point2f d = corners[static_cast<std::size_t>(r * board.cols + c + 1)] -
                                  corners[static_cast<std::size_t>(r * board.cols + c)];
            spacing = std::min(spacing, static_cast<double>(std::hypot(d.x, d.y)));
          }
        const int half = std::max(
            2, std::min(options.subpix_half_window, static_cast<int>(std::floor(spacing * 0.6))));
        cv::cornerSubPix(
            grey, corners, cv::Size(half, half), cv::Size(-1, -1),
            cv::TermCriteria(cv::TermCriteria::COUNT + cv::TermCriteria::EPS, 30, 0.01));
      } else if (options.sector_based_fallback && grey.total() <= 1.5e6) {
        // (Not on large images: the sector-based detector takes seconds on an empty frame.)
        corners.clear();
        found = cv::findChessboardCornersSB(
            grey, pattern, corners,
            cv::CALIB_CB_NORMALIZE_IMAGE | cv::CALIB_CB_EXHAUSTIVE | cv::CALIB_CB_ACCURACY);
      }
      if (!found || corners.size() != static_cast<std::size_t>(board.corner_count()))
        return std::optional<BoardDetection>();
      if (options.canonical_order && (board.cols + board.rows) % 2 == 1) {
        // Centres of square (0,0) (outside corner 0, dark by convention) and (1,0) (light).
        const cv::Point2f p0 = corners[0];
        const cv::Point2f ex = corners[1] - p0;
        const cv::Point2f ey = corners[static_cast<std::size_t>(board.cols)] - p0;
        const cv::Point2f s00 = p0 - 0.5f * ex - 0.5f * ey;
        const cv::Point2f s10 = p0 + 0.5f * ex - 0.5f * ey;
        const cv::Rect2f inside(0.f, 0.f, static_cast<float>(grey.cols - 1),
                                static_cast<float>(grey.rows - 1));
        if (inside.contains(s00) && inside.contains(s10) &&
            bilinear(grey, s00) > bilinear(grey, s10))
          std::reverse(corners.begin(), corners.end());
      }
      det.ids.resize(corners.size());
      det.pixels.resize(corners.size());
      for (std::size_t i = 0; i < corners.size(); ++i) {
        det.ids[i] = static_cast<int>(i);
        det.pixels[i] = Eigen::Vector2d(corners[i].x, corners[i].y);
      }
    } else {
      const cv::Ptr<cv::aruco::CharucoBoard> cb = make_charuco(board);
      std::vector<std::vector<cv::Point2f>> marker_corners, rejected;
      std::vector<int> marker_ids;
      const cv::Ptr<cv::aruco::DetectorParameters> params = cv::aruco::DetectorParameters::create();
      params->cornerRefinementMethod = cv::aruco::CORNER_REFINE_NONE;
      cv::aruco::detectMarkers(grey, cb->dictionary, marker_corners, marker_ids, params, rejected);
      if (marker_ids.empty()) return std::optional<BoardDetection>();
      std::vector<cv::Point2f> ch_corners;
      std::vector<int> ch_ids;
      // Without camera parameters OpenCV interpolates through local homographies, then refines
      // with cornerSubPix.
      cv::aruco::interpolateCornersCharuco(marker_corners, marker_ids, grey, cb, ch_corners,
                                           ch_ids);
      if (static_cast<int>(ch_ids.size()) < options.min_charuco_corners)
        return std::optional<BoardDetection>();
      for (std::size_t i = 0; i < ch_ids.size(); ++i) {
        det.ids.push_back(ch_ids[i]);
        det.pixels.emplace_back(ch_corners[i].x, ch_corners[i].y);
      }
    }
    return std::optional<BoardDetection>(std::move(det));
  } catch (const cv::Exception& e) {
    return invalid_argument(std::string("board detection (OpenCV): ") + e.what());
  }
}

ChessboardRenderer::ChessboardRenderer(const CameraModel& camera, const BoardSpec& spec,
                                       const RenderOptions& options)
    : camera_(camera), spec_(spec), options_(options) {
  const int w = camera.width + 1, h = camera.height + 1;
  corner_rays_.resize(static_cast<std::size_t>(w) * static_cast<std::size_t>(h));
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x)
      corner_rays_[static_cast<std::size_t>(y) * static_cast<std::size_t>(w) +
                   static_cast<std::size_t>(x)] =
          camera.undistort_to_normalized(Eigen::Vector2d(x - 0.5, y - 0.5));
}

std::vector<std::uint8_t> ChessboardRenderer::render(
    const Eigen::Isometry3d& rig_from_board) const {
  const int W = camera_.width, H = camera_.height;
  std::vector<std::uint8_t> out(static_cast<std::size_t>(W) * static_cast<std::size_t>(H),
                                options_.background);
  // camera_from_board = [Rc | tc]; board plane z = 0 maps to normalised coordinates by the
  // homography [r1 r2 tc]; its inverse takes a ray to board coordinates.
  Eigen::Isometry3d cam_from_rig = Eigen::Isometry3d::Identity();
  cam_from_rig.linear() = camera_.R;
  cam_from_rig.translation() = camera_.t_m;
  const Eigen::Isometry3d cb = cam_from_rig * rig_from_board;
  Eigen::Matrix3d Hm;
  Hm.col(0) = cb.linear().col(0);
  Hm.col(1) = cb.linear().col(1);
  Hm.col(2) = cb.translation();
  const Eigen::Matrix3d Hinv = Hm.inverse();
  const double s = spec_.square_m;
  const int ns = std::max(1, options_.supersample);
  const std::size_t w1 = static_cast<std::size_t>(W) + 1;
  // Board coordinates (u, v) of every pixel corner; NaN when the ray misses the board's front.
  std::vector<Eigen::Vector2d> uv(corner_rays_.size());
  for (std::size_t i = 0; i < corner_rays_.size(); ++i) {
    const Eigen::Vector3d ray(corner_rays_[i].x(), corner_rays_[i].y(), 1.0);
    const Eigen::Vector3d b = Hinv * ray;
    // The ray must hit the plane in front of the camera (b.z() > 0 means positive depth).
    // Only the front is printed: seen from behind (the board's +z axis, pointing away from the
    // front's viewer, facing the camera) the board is blank.
    if (b.z() <= 0.0)
      uv[i] = Eigen::Vector2d(NAN, NAN);
    else
      uv[i] = Eigen::Vector2d(b.x() / b.z(), b.y() / b.z());
  }
  const bool from_behind = cb.linear().col(2).dot(cb.translation()) < 0.0;
  const double u_lo = -2.0 * s, u_hi = (spec_.cols + 1) * s;
  const double v_lo = -2.0 * s, v_hi = (spec_.rows + 1) * s;
  const auto shade = [&](double u, double v) -> double {
    if (!(u >= u_lo && u < u_hi && v >= v_lo && v < v_hi)) return options_.background;
    const long a = static_cast<long>(std::floor(u / s)) + 1;  // square index 0..cols
    const long b = static_cast<long>(std::floor(v / s)) + 1;
    if (from_behind || a < 0 || b < 0 || a > spec_.cols || b > spec_.rows)
      return options_.light;  // margin (or the blank back)
    return ((a + b) % 2 == 0) ? options_.dark : options_.light;
  };
  for (int y = 0; y < H; ++y) {
    for (int x = 0; x < W; ++x) {
      const std::size_t i00 = static_cast<std::size_t>(y) * w1 + static_cast<std::size_t>(x);
      const Eigen::Vector2d& c00 = uv[i00];
      const Eigen::Vector2d& c10 = uv[i00 + 1];
      const Eigen::Vector2d& c01 = uv[i00 + w1];
      const Eigen::Vector2d& c11 = uv[i00 + w1 + 1];
      if (!(c00.allFinite() && c10.allFinite() && c01.allFinite() && c11.allFinite())) continue;
      // Whole pixel inside one square (or outside the board): no supersampling needed.
      const double umin = std::min({c00.x(), c10.x(), c01.x(), c11.x()});
      const double umax = std::max({c00.x(), c10.x(), c01.x(), c11.x()});
      const double vmin = std::min({c00.y(), c10.y(), c01.y(), c11.y()});
      const double vmax = std::max({c00.y(), c10.y(), c01.y(), c11.y()});
      double value;
      if (std::floor(umin / s) == std::floor(umax / s) &&
          std::floor(vmin / s) == std::floor(vmax / s)) {
        value = shade(0.5 * (umin + umax), 0.5 * (vmin + vmax));
      } else {
        double sum = 0.0;
        for (int sy = 0; sy < ns; ++sy) {
          const double fy = (sy + 0.5) / ns;
          for (int sx = 0; sx < ns; ++sx) {
            const double fx = (sx + 0.5) / ns;
            // Bilinear interpolation of the board coordinates inside the pixel (the projective
            // and distortion curvature over one pixel is far below the sample spacing).
            const Eigen::Vector2d p =
                (1 - fy) * ((1 - fx) * c00 + fx * c10) + fy * ((1 - fx) * c01 + fx * c11);
            sum += shade(p.x(), p.y());
          }
        }
        value = sum / (ns * ns);
      }
      out[static_cast<std::size_t>(y) * static_cast<std::size_t>(W) + static_cast<std::size_t>(x)] =
          static_cast<std::uint8_t>(std::clamp(std::lround(value), 0L, 255L));
    }
  }
  return out;
}

}  // namespace hc::calib
