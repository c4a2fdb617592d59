// Board specs and detection: pattern parsing errors, ChArUco detection on an image OpenCV itself
// draws (cv::aruco::CharucoBoard::draw) seen through a known homography, chessboard corner order.
#include "calibration/cameras/board.h"

#include <gtest/gtest.h>

#include <opencv2/aruco/charuco.hpp>
#include <opencv2/imgproc.hpp>

namespace hc::calib {
namespace {

TEST(BoardSpec, Parses) {
  Result<BoardSpec> c = parse_board_spec("chessboard:9x6:0.025");
  ASSERT_TRUE(c.ok());
  EXPECT_EQ(c->kind, BoardKind::kChessboard);
  EXPECT_EQ(c->cols, 9);
  EXPECT_EQ(c->rows, 6);
  EXPECT_DOUBLE_EQ(c->square_m, 0.025);
  EXPECT_EQ(c->corner_count(), 54);
  EXPECT_EQ(c->corner(10), Eigen::Vector3d(0.025, 0.025, 0.0));  // row 1, col 1
  Result<BoardSpec> a = parse_board_spec("charuco:7x5:0.04:0.03:DICT_5X5_100");
  ASSERT_TRUE(a.ok());
  EXPECT_EQ(a->kind, BoardKind::kCharuco);
  EXPECT_EQ(a->corner_count(), 24);
  EXPECT_EQ(a->corner(0), Eigen::Vector3d(0.04, 0.04, 0.0));  // OpenCV: corners from (1,1)*square
  EXPECT_EQ(a->corner(7), Eigen::Vector3d(0.08, 0.08, 0.0));
  EXPECT_EQ(parse_board_spec(a->to_string())->dictionary, "DICT_5X5_100");
}

TEST(BoardSpec, ClearErrors) {
  const auto msg = [](const char* s) {
    Result<BoardSpec> b = parse_board_spec(s);
    EXPECT_FALSE(b.ok()) << s;
    EXPECT_EQ(b.status().code(), StatusCode::kInvalidArgument);
    return b.ok() ? std::string() : b.status().message();
  };
  EXPECT_NE(msg("circles:9x6:0.02").find("unknown board kind"), std::string::npos);
  EXPECT_NE(msg("chessboard:9x6").find("chessboard:COLSxROWS:SQUARE_M"), std::string::npos);
  EXPECT_NE(msg("chessboard:9by6:0.02").find("COLSxROWS"), std::string::npos);
  EXPECT_NE(msg("chessboard:1x6:0.02").find("out of range"), std::string::npos);
  EXPECT_NE(msg("chessboard:9x6:-1").find("square size"), std::string::npos);
  EXPECT_NE(msg("chessboard:9x6:abc").find("square size"), std::string::npos);
  EXPECT_NE(msg("charuco:7x5:0.04:0.05:DICT_5X5_100").find("marker size"), std::string::npos);
  EXPECT_NE(msg("charuco:7x5:0.04:0.03:DICT_9X9").find("unknown ArUco dictionary"),
            std::string::npos);
  EXPECT_NE(msg("charuco:20x20:0.04:0.03:DICT_4X4_50").find("needs 200 markers"),
            std::string::npos);
  EXPECT_NE(msg("charuco:7x5:0.04").find("charuco:COLSxROWS"), std::string::npos);
  EXPECT_NE(msg("").find("unknown board kind"), std::string::npos);
}

TEST(BoardDetect, CharucoOnOpenCvDrawnBoard) {
  const BoardSpec spec = *parse_board_spec("charuco:7x5:0.04:0.03:DICT_5X5_100");
  cv::Ptr<cv::aruco::CharucoBoard> board = cv::aruco::CharucoBoard::create(
      7, 5, 0.04f, 0.03f, cv::aruco::getPredefinedDictionary(cv::aruco::DICT_5X5_100));
  // 100 px per square, 50 px margin: board point (x, y) m -> (50 + 2500 x, 50 + 2500 y) px.
  cv::Mat flat;
  board->draw(cv::Size(800, 600), flat, 50, 1);
  // A perspective view of it.
  const std::vector<cv::Point2f> src = {{0, 0}, {800, 0}, {800, 600}, {0, 600}};
  const std::vector<cv::Point2f> dst = {{60, 40}, {700, 80}, {660, 560}, {90, 500}};
  const cv::Mat H = cv::getPerspectiveTransform(src, dst);
  cv::Mat img;
  cv::warpPerspective(flat, img, H, cv::Size(760, 600), cv::INTER_AREA, cv::BORDER_CONSTANT,
                      cv::Scalar(255));
  ImageView view{img.cols, img.rows, static_cast<int>(img.step), 1, img.data};
  Result<std::optional<BoardDetection>> d = detect_board(view, spec);
  ASSERT_TRUE(d.ok()) << d.status().message();
  ASSERT_TRUE(d->has_value());
  EXPECT_EQ((*d)->ids.size(), 24u);  // every inner corner
  double worst = 0.0;
  for (std::size_t i = 0; i < (*d)->ids.size(); ++i) {
    const Eigen::Vector3d X = spec.corner((*d)->ids[i]);
    std::vector<cv::Point2f> p = {
        {static_cast<float>(50 + 2500 * X.x() - 0.5), static_cast<float>(50 + 2500 * X.y() - 0.5)}};
    std::vector<cv::Point2f> q;
    cv::perspectiveTransform(p, q, H);
    worst = std::max(worst, std::hypot((*d)->pixels[i].x() - q[0].x, (*d)->pixels[i].y() - q[0].y));
  }
  // Corner positions through the homography (half-pixel conventions of draw/warp leave ~0.5 px).
  EXPECT_LT(worst, 1.0);
  // Nothing in a blank image.
  cv::Mat blank(300, 300, CV_8UC1, cv::Scalar(200));
  ImageView bv{300, 300, 300, 1, blank.data};
  Result<std::optional<BoardDetection>> none = detect_board(bv, spec);
  ASSERT_TRUE(none.ok());
  EXPECT_FALSE(none->has_value());
}

TEST(BoardDetect, BadViewAndRgb) {
  const BoardSpec spec = *parse_board_spec("chessboard:9x6:0.025");
  EXPECT_FALSE(detect_board(ImageView{}, spec).ok());
  std::vector<std::uint8_t> rgb(30 * 20 * 3, 128);
  EXPECT_FALSE(detect_board(ImageView{30, 20, 10, 3, rgb.data()}, spec).ok());  // stride too small
  Result<std::optional<BoardDetection>> d =
      detect_board(ImageView{30, 20, 90, 3, rgb.data()}, spec);
  ASSERT_TRUE(d.ok());
  EXPECT_FALSE(d->has_value());
}

}  // namespace
}  // namespace hc::calib
