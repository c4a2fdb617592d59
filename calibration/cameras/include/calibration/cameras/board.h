// Calibration boards: the pattern spec of `hardcopy calib cameras --pattern`, the board's 3-D
// corner positions, detection in an image (OpenCV chessboard / ChArUco) and an anti-aliased
// renderer of a chessboard through a CameraModel (synthetic rigs for tests and benchmarks).
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>

#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "camera/camera_model.h"
#include "common/status.h"

namespace hc::calib {

enum class BoardKind : std::uint8_t { kChessboard, kCharuco };

struct BoardSpec {
  BoardKind kind = BoardKind::kChessboard;
  // Chessboard: inner corners per row (cols) and per column (rows), as OpenCV's patternSize.
  // ChArUco: squares along x (cols) and y (rows), as cv::aruco::CharucoBoard::create.
  int cols = 0;
  int rows = 0;
  double square_m = 0.0;
  double marker_m = 0.0;   // ChArUco only
  std::string dictionary;  // ChArUco only: an OpenCV predefined name, e.g. DICT_4X4_50

  // Number of corners the board has (chessboard cols*rows, ChArUco (cols-1)*(rows-1)).
  int corner_count() const;
  // Corner `id` in the board frame (z = 0), metres. Chessboard id = row * cols + col at
  // (col, row) * square; ChArUco ids as OpenCV numbers its chessboard corners.
  Eigen::Vector3d corner(int id) const;
  std::string to_string() const;
};

// Parses "chessboard:COLSxROWS:SQUARE_M" or "charuco:COLSxROWS:SQUARE_M:MARKER_M:DICT"
// (e.g. "chessboard:9x6:0.025", "charuco:7x5:0.04:0.03:DICT_5X5_100"); kInvalidArgument saying
// which part is wrong.
Result<BoardSpec> parse_board_spec(std::string_view text);

// An 8-bit image in memory (not owned): 1 channel (grey) or 3 (RGB byte order).
struct ImageView {
  int width = 0;
  int height = 0;
  int stride = 0;  // bytes per row
  int channels = 1;
  const std::uint8_t* data = nullptr;
};

// The board corners found in one image.
struct BoardDetection {
  std::vector<int> ids;                 // corner ids (BoardSpec::corner)
  std::vector<Eigen::Vector2d> pixels;  // sub-pixel positions, OpenCV pixel convention
};

struct DetectOptions {
  // cornerSubPix winSize (half the side of the search window: OpenCV's calibration samples pass
  // Size(11, 11), a 23x23 window, and produced the reference results); reduced automatically to
  // 60 % of the corner spacing on small boards.
  int subpix_half_window = 11;
  // Fall back to cv::findChessboardCornersSB when the classic detector finds nothing (images up
  // to 1.5 Mpx; larger ones are searched at half resolution with CALIB_CB_FAST_CHECK and refined
  // at full resolution).
  bool sector_based_fallback = true;
  // Chessboard: put the corners in the canonical order (the square diagonally outside corner 0
  // is dark), so every camera numbers the corners the same way. Meaningful when cols + rows is
  // odd (otherwise the board is symmetric under a half turn); OpenCV's own order is kept when
  // false or ambiguous.
  bool canonical_order = true;
  // ChArUco: fewest interpolated corners for a detection to count.
  int min_charuco_corners = 6;
};

// Finds the board. nullopt when it is not (fully, for a chessboard) visible; kInvalidArgument on
// an unusable image view.
Result<std::optional<BoardDetection>> detect_board(const ImageView& image, const BoardSpec& board,
                                                   const DetectOptions& options = {});

// Renders a chessboard with `spec.cols x spec.rows` inner corners (one square of white margin
// around the squares, grey background) as `camera` sees it, with `supersample`^2 samples per pixel
// through the full distortion model (the pixel -> ray map is computed once per camera, so
// rendering many poses is cheap). Board pose: x_cam = camera.R * (rig_from_board * X) +
// camera.t_m. The square diagonally outside corner 0 is dark (DetectOptions::canonical_order).
// Output Mono8, stride = width.
struct RenderOptions {
  int supersample = 4;
  std::uint8_t dark = 30;
  std::uint8_t light = 225;
  std::uint8_t background = 110;
};
class ChessboardRenderer {
 public:
  ChessboardRenderer(const CameraModel& camera, const BoardSpec& spec,
                     const RenderOptions& options = {});
  std::vector<std::uint8_t> render(const Eigen::Isometry3d& rig_from_board) const;
  const CameraModel& camera() const { return camera_; }

 private:
  CameraModel camera_;
  BoardSpec spec_;
  RenderOptions options_;
  // Normalised image coordinates (x/z, y/z) at the pixel corners, (width+1) x (height+1).
  std::vector<Eigen::Vector2d> corner_rays_;
};

}  // namespace hc::calib
