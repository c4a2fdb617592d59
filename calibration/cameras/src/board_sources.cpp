#include "calibration/cameras/board_sources.h"

#include <fmt/format.h>
#include <glob.h>

#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cctype>
#include <chrono>
#include <map>
#include <optional>
#include <set>

#include "calibration/cameras/image_codecs.h"
#include "common/clock.h"
#include "common/json.h"
#include "rig_daemon/recording/foxglove_image.h"
#include "rig_daemon/recording/mcap_reader.h"
#include "rig_daemon/recording/session_conventions.h"
#include "rig_daemon/session/session_reader.h"

namespace hc::calib {

namespace {

bool valid_camera_name(const std::string& name) {
  if (name.empty() || !(std::isalpha(static_cast<unsigned char>(name[0])) || name[0] == '_'))
    return false;
  for (char c : name)
    if (!(std::isalnum(static_cast<unsigned char>(c)) || c == '_' || c == '-')) return false;
  return true;
}

std::string no_board_message(const CameraObservations& cam, int images, const BoardSpec& board,
                             const std::string& where) {
  return fmt::format("no board found: camera '{}' shows no {} in any of its {} image(s){}",
                     cam.name, board.to_string(), images, where);
}

// Trigger indexes from /session/sync: camera -> (frame sequence -> trigger index); empty without
// the channel.
using TriggerIndexes = std::map<std::string, std::map<std::uint64_t, std::int64_t>>;
Result<TriggerIndexes> read_sync_triggers(const recording::McapReader& reader,
                                          const std::string& file) {
  HC_ASSIGN_OR_RETURN(session::SessionRecords records,
                      session::read_session_records(reader, {.sync = true, .steps = false}, file));
  TriggerIndexes trigger_of;
  for (const session::SyncRecord& r : records.sync)
    for (const auto& [camera, frame] : r.frames)
      trigger_of[camera][frame] = static_cast<std::int64_t>(r.trigger_index);
  return trigger_of;
}

// A camera message (foxglove.RawImage or foxglove.CompressedImage) as a grey image.
Status decode_grey(const recording::MessageEvent& m, const std::string& where, cv::Mat& grey) {
  const std::string schema = m.schema ? m.schema->name : "";
  try {
    if (schema == recording::kCompressedImageSchemaName) {
      Result<recording::CompressedImage> ci_img =
          recording::decode_compressed_image(m.message.data);
      if (!ci_img.ok()) return ci_img.status().with_context(where);
      Result<GreyImage> decoded = decode_grey_image(ci_img->data);
      if (!decoded.ok()) return decoded.status().with_context(where);
      if (decoded->empty())
        return invalid_argument(where + ": undecodable " + ci_img->format + " image");
      cv::Mat(decoded->height, decoded->width, CV_8UC1, decoded->pixels.data()).copyTo(grey);
    } else {
      Result<recording::RawImage> raw = recording::decode_raw_image(m.message.data);
      if (!raw.ok()) return raw.status().with_context(where);
      const std::string& enc = raw->encoding;
      const int w = static_cast<int>(raw->width), h = static_cast<int>(raw->height);
      // cv::Mat header over the decoded buffer (no copy; const_cast as cv::Mat has no
      // const view).
      auto* px = const_cast<std::uint8_t*>(raw->data.data());
      if (enc == "mono8") {
        cv::Mat(h, w, CV_8UC1, px, raw->step).copyTo(grey);
      } else if (enc == "rgb8" || enc == "bgr8") {
        cv::cvtColor(cv::Mat(h, w, CV_8UC3, px, raw->step), grey,
                     enc == "rgb8" ? cv::COLOR_RGB2GRAY : cv::COLOR_BGR2GRAY);
      } else if (enc == "rgba8" || enc == "bgra8") {
        cv::cvtColor(cv::Mat(h, w, CV_8UC4, px, raw->step), grey,
                     enc == "rgba8" ? cv::COLOR_RGBA2GRAY : cv::COLOR_BGRA2GRAY);
      } else {
        return invalid_argument(where + ": unsupported image encoding '" + enc +
                                "' (mono8, rgb8, bgr8, rgba8, bgra8)");
      }
    }
  } catch (const cv::Exception& e) {
    return invalid_argument(where + ": " + e.what());
  }
  return {};
}

}  // namespace

Result<ImageSet> expand_image_set(const std::string& spec) {
  const auto eq = spec.find('=');
  if (eq == std::string::npos)
    return invalid_argument("--images '" + spec +
                            "': expected CAMERA=GLOB, e.g. left=img/left*.jpg");
  ImageSet set;
  set.camera = spec.substr(0, eq);
  const std::string pattern = spec.substr(eq + 1);
  if (!valid_camera_name(set.camera))
    return invalid_argument("--images '" + spec + "': camera name '" + set.camera +
                            "' must be letters, digits, '_' or '-' (starting with a letter)");
  if (pattern.empty()) return invalid_argument("--images '" + spec + "': empty glob");
  // POSIX glob(3): the shell may have expanded nothing (quoted patterns), so we expand here.
  glob_t g{};
  const int rc = ::glob(pattern.c_str(), 0, nullptr, &g);
  if (rc == 0)
    for (std::size_t i = 0; i < g.gl_pathc; ++i) set.files.emplace_back(g.gl_pathv[i]);
  ::globfree(&g);
  if (set.files.empty())
    return invalid_argument("--images '" + spec + "': no file matches '" + pattern + "'");
  std::sort(set.files.begin(), set.files.end());
  return set;
}

Result<int> view_number(const std::filesystem::path& file) {
  const std::string stem = file.stem().string();
  std::size_t end = stem.size();
  while (end > 0 && !std::isdigit(static_cast<unsigned char>(stem[end - 1]))) --end;
  std::size_t begin = end;
  while (begin > 0 && std::isdigit(static_cast<unsigned char>(stem[begin - 1]))) --begin;
  if (begin == end)
    return invalid_argument(file.string() +
                            ": no number in the file name (frames taken at the same moment must "
                            "share a number, e.g. left03.jpg / right03.jpg)");
  const std::string digits = stem.substr(begin, std::min<std::size_t>(end - begin, 9));
  return std::stoi(digits);
}

Result<std::vector<CameraObservations>> detect_in_images(const std::vector<ImageSet>& sets,
                                                         const BoardSpec& board,
                                                         const DetectOptions& options,
                                                         ProgressReporter* progress,
                                                         DetectionStats* stats) {
  const auto t0 = std::chrono::steady_clock::now();
  std::size_t total = 0;
  std::set<std::string> names;
  for (const ImageSet& s : sets) {
    total += s.files.size();
    if (!names.insert(s.camera).second)
      return invalid_argument("camera '" + s.camera + "' given twice");
  }
  ProgressTask task(progress, "board detection", total);
  std::vector<CameraObservations> out;
  DetectionStats st;
  for (const ImageSet& s : sets) {
    CameraObservations cam;
    cam.name = s.camera;
    std::set<int> views;
    for (const std::filesystem::path& f : s.files) {
      HC_ASSIGN_OR_RETURN(int view, view_number(f));
      if (!views.insert(view).second)
        return invalid_argument(fmt::format("{}: camera '{}' has two images with view number {}",
                                            f.string(), s.camera, view));
      HC_ASSIGN_OR_RETURN(GreyImage img, read_grey_image(f));
      if (img.empty())
        return invalid_argument(f.string() + ": unreadable image (missing or not an image file)");
      if (cam.width == 0) {
        cam.width = img.width;
        cam.height = img.height;
      } else if (cam.width != img.width || cam.height != img.height) {
        return invalid_argument(fmt::format("{}: {}x{} but camera '{}' images are {}x{}",
                                            f.string(), img.width, img.height, s.camera, cam.width,
                                            cam.height));
      }
      HC_ASSIGN_OR_RETURN(std::optional<BoardDetection> d,
                          detect_board(img.view(), board, options));
      ++st.images;
      if (d) {
        ++st.boards_found;
        cam.views.push_back({view, std::move(d->ids), std::move(d->pixels)});
      }
      task.advance();
    }
    if (cam.views.empty())
      return invalid_argument(no_board_message(cam, static_cast<int>(s.files.size()), board, ""));
    out.push_back(std::move(cam));
  }
  st.detect_time_s = seconds_since(t0);
  if (stats) *stats = st;
  return out;
}

Result<std::vector<CameraObservations>> detect_in_session(const std::filesystem::path& session,
                                                          const BoardSpec& board,
                                                          const DetectOptions& options,
                                                          ProgressReporter* progress,
                                                          DetectionStats* stats) {
  const auto t0 = std::chrono::steady_clock::now();
  const std::string file = session.string();
  HC_ASSIGN_OR_RETURN(recording::McapReader reader, recording::McapReader::open(session));
  // Camera channels.
  std::map<std::uint16_t, std::size_t> cam_of_channel;
  std::vector<CameraObservations> cams;
  std::vector<std::string> topics;
  for (const auto& [id, ch] : reader.channels()) {
    const auto kind = ch.metadata.find("kind");
    if (kind == ch.metadata.end() || kind->second != "camera") continue;
    const auto dev = ch.metadata.find("device");
    CameraObservations c;
    c.name = dev != ch.metadata.end() && !dev->second.empty() ? dev->second : ch.topic;
    if (!valid_camera_name(c.name))
      return invalid_argument(file + ": camera '" + c.name +
                              "' is not usable as a calibration key (letters, digits, '_', '-')");
    cam_of_channel[id] = cams.size();
    cams.push_back(std::move(c));
    topics.push_back(ch.topic);
  }
  if (cams.empty())
    return invalid_argument(file +
                            ": the session has no camera channel (no channel with "
                            "metadata kind=camera)");
  // Trigger indexes from /session/sync: camera -> (frame sequence -> trigger index).
  HC_ASSIGN_OR_RETURN(const TriggerIndexes trigger_of, read_sync_triggers(reader, file));
  std::uint64_t total = 0;
  if (auto counts = reader.message_counts(); counts.ok())
    for (const auto& [id, n] : *counts)
      if (cam_of_channel.count(id)) total += n;
  ProgressTask task(progress, "board detection", total);
  DetectionStats st;
  std::vector<int> frames(cams.size(), 0);
  std::vector<std::set<int>> seen(cams.size());
  std::vector<std::optional<std::uint32_t>> first_seq(cams.size());
  std::vector<std::uint32_t> prev_seq(cams.size(), 0);
  std::vector<std::uint64_t> wrap(cams.size(), 0);
  Status status;
  HC_RETURN_IF_ERROR(reader.read_messages(
      {.topics = topics, .order = recording::ReadOrder::kFile},
      [&](const recording::MessageEvent& m) {
        const std::size_t ci = cam_of_channel.at(m.channel->id);
        CameraObservations& cam = cams[ci];
        const std::string where =
            fmt::format("{}: {} message {}", file, m.channel->topic, m.message.sequence);
        cv::Mat grey;
        status = decode_grey(m, where, grey);
        if (!status.ok()) return false;
        if (cam.width == 0) {
          cam.width = grey.cols;
          cam.height = grey.rows;
        } else if (cam.width != grey.cols || cam.height != grey.rows) {
          status = invalid_argument(fmt::format("{}: frame is {}x{}, earlier frames {}x{}", where,
                                                grey.cols, grey.rows, cam.width, cam.height));
          return false;
        }
        // The sync records name a camera's frame by its frame_index (frames since the camera was
        // activated, rig_daemon/session/topics.h), the message sequence is its frame_id:
        // frame_index = frame_id unwrapped (16- or 32-bit counters) minus the session's first.
        // A record naming the sequence itself is accepted too (frame_id == frame_index).
        const std::uint32_t seq = m.message.sequence;
        if (!first_seq[ci]) {
          first_seq[ci] = seq;
          prev_seq[ci] = seq;
        }
        if (seq < prev_seq[ci]) wrap[ci] += prev_seq[ci] < 65536u ? 65536ull : (1ull << 32);
        prev_seq[ci] = seq;
        const std::uint64_t frame_index = wrap[ci] + seq - *first_seq[ci];
        std::int64_t view = seq;
        if (auto it = trigger_of.find(cam.name); it != trigger_of.end()) {
          auto t = it->second.find(seq);
          if (t == it->second.end()) t = it->second.find(frame_index);
          if (t == it->second.end()) {
            task.advance();
            return true;  // a frame no trigger claimed (before the first edge): skip
          }
          view = t->second;
        }
        ++frames[ci];
        ++st.images;
        if (!seen[ci].insert(static_cast<int>(view)).second) {
          task.advance();
          return true;  // a second frame for one trigger: keep the first
        }
        ImageView v{grey.cols, grey.rows, static_cast<int>(grey.step), 1, grey.data};
        Result<std::optional<BoardDetection>> d = detect_board(v, board, options);
        if (!d.ok()) {
          status = d.status().with_context(where);
          return false;
        }
        if (d->has_value()) {
          ++st.boards_found;
          cam.views.push_back(
              {static_cast<int>(view), std::move((*d)->ids), std::move((*d)->pixels)});
        }
        task.advance();
        return true;
      }));
  HC_RETURN_IF_ERROR(status);
  for (std::size_t i = 0; i < cams.size(); ++i)
    if (cams[i].views.empty() && frames[i] == 0 && first_seq[i])
      return invalid_argument(file + ": no frame of camera '" + cams[i].name +
                              "' belongs to a /session/sync trigger record");
  for (std::size_t i = 0; i < cams.size(); ++i)
    if (cams[i].views.empty())
      return invalid_argument(no_board_message(cams[i], frames[i], board, " in " + file));
  st.detect_time_s = seconds_since(t0);
  if (stats) *stats = st;
  return cams;
}

}  // namespace hc::calib
