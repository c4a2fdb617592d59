// Where board observations come from for `hardcopy calib cameras`: image files per camera (views
// numbered by the number in their file names) or a recorded session (camera channels, frames
// grouped by trigger index).
#pragma once

#include <filesystem>
#include <string>
#include <vector>

#include "calibration/cameras/board.h"
#include "calibration/cameras/calibrate.h"
#include "common/progress.h"
#include "common/status.h"

namespace hc::calib {

struct DetectionStats {
  int images = 0;        // images (frames) looked at
  int boards_found = 0;  // images the board was found in
  double detect_time_s = 0.0;
};

// One camera's images: "CAMERA=GLOB" as given on the command line.
struct ImageSet {
  std::string camera;
  std::vector<std::filesystem::path> files;  // sorted
};

// Parses "NAME=GLOB" and expands the glob (POSIX glob(3), sorted). kInvalidArgument on a missing
// '=', an empty or invalid camera name (letters, digits, '_', '-'; a letter or '_' first), or a
// glob that matches nothing.
Result<ImageSet> expand_image_set(const std::string& spec);

// The view number of an image: the last run of digits in its file name stem ("left03.jpg" -> 3).
Result<int> view_number(const std::filesystem::path& file);

// Detects the board in every image. kInvalidArgument naming the file on an unreadable image, on two
// images of one camera with the same view number, or when a camera's images differ in size.
// A camera whose images show no board at all is an error too ("no board found in ...").
Result<std::vector<CameraObservations>> detect_in_images(const std::vector<ImageSet>& sets,
                                                         const BoardSpec& board,
                                                         const DetectOptions& options,
                                                         ProgressReporter* progress,
                                                         DetectionStats* stats = nullptr);

// Reads a recorded session: camera channels are those whose metadata has kind=camera (name from
// metadata "device", else the topic); frames are foxglove.RawImage (mono8, rgb8, bgr8, rgba8,
// bgra8) or foxglove.CompressedImage. A frame's view is its trigger index from /session/sync
// (frames{camera: frame_index}, matched to the message sequence = frame_id unwrapped from the
// session's first frame, or to the sequence itself) when the session has one, else the message
// sequence. kInvalidArgument
// when the session has no camera channel, a frame cannot be decoded, or no board is found.
Result<std::vector<CameraObservations>> detect_in_session(const std::filesystem::path& session,
                                                          const BoardSpec& board,
                                                          const DetectOptions& options,
                                                          ProgressReporter* progress,
                                                          DetectionStats* stats = nullptr);

}  // namespace hc::calib
