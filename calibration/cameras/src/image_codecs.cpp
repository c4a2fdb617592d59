#include "calibration/cameras/image_codecs.h"

#include <dlfcn.h>

#include <algorithm>
#include <opencv2/imgcodecs.hpp>
#include <string>

namespace hc::calib {
namespace {

// The two entry points, by their Itanium C++ ABI names (OpenCV 4: `nm -D` of the library lists
// them); dlsym fails, and says so, should a future OpenCV change their signatures.
using Imread = cv::Mat (*)(const std::string&, int);
using Imdecode = cv::Mat (*)(cv::InputArray, int);
constexpr const char* kImreadSymbol =
    "_ZN2cv6imreadERKNSt7__cxx1112basic_stringIcSt11char_traitsIcESaIcEEEi";
constexpr const char* kImdecodeSymbol = "_ZN2cv8imdecodeERKNS_11_InputArrayEi";

struct Codecs {
  Imread imread = nullptr;
  Imdecode imdecode = nullptr;
  std::string error;  // why they are missing
};

const Codecs& codecs() {
  static const Codecs loaded = [] {
    Codecs c;
    // The soname first (the loader's search path, as linking would have found it), then the file
    // CMake found at configure time.
    void* handle = nullptr;
    std::string tried;
    for (const char* name : {HC_OPENCV_IMGCODECS_SONAME, HC_OPENCV_IMGCODECS_PATH}) {
      handle = ::dlopen(name, RTLD_NOW | RTLD_LOCAL);
      if (handle != nullptr) break;
      const char* why = ::dlerror();
      tried += std::string(tried.empty() ? "" : "; ") + (why != nullptr ? why : name);
    }
    if (handle == nullptr) {
      c.error = "OpenCV's image codecs could not be loaded (" + tried +
                "); install libopencv-imgcodecs406 (scripts/setup does)";
      return c;
    }
    // The handle stays open for the process's lifetime.
    c.imread = reinterpret_cast<Imread>(::dlsym(handle, kImreadSymbol));
    c.imdecode = reinterpret_cast<Imdecode>(::dlsym(handle, kImdecodeSymbol));
    if (c.imread == nullptr || c.imdecode == nullptr)
      c.error = std::string("OpenCV's image codecs lack cv::imread or cv::imdecode: ") +
                HC_OPENCV_IMGCODECS_SONAME + " is not the OpenCV 4 this was built with";
    return c;
  }();
  return loaded;
}

// Packs a grey cv::Mat (rows may be padded) into a GreyImage.
GreyImage packed(const cv::Mat& m) {
  GreyImage g;
  if (m.empty() || m.type() != CV_8UC1) return g;
  g.width = m.cols;
  g.height = m.rows;
  g.pixels.resize(static_cast<std::size_t>(m.cols) * static_cast<std::size_t>(m.rows));
  for (int r = 0; r < m.rows; ++r)
    std::copy_n(m.ptr<std::uint8_t>(r), m.cols,
                g.pixels.begin() + static_cast<std::ptrdiff_t>(r) * m.cols);
  return g;
}

}  // namespace

Result<GreyImage> read_grey_image(const std::filesystem::path& file) {
  const Codecs& c = codecs();
  if (!c.error.empty()) return failed_precondition(c.error);
  try {
    return packed(c.imread(file.string(), cv::IMREAD_GRAYSCALE));
  } catch (const cv::Exception& e) {
    return invalid_argument(file.string() + ": unreadable image: " + e.what());
  }
}

Result<GreyImage> decode_grey_image(std::span<const std::uint8_t> bytes) {
  const Codecs& c = codecs();
  if (!c.error.empty()) return failed_precondition(c.error);
  if (bytes.empty()) return GreyImage{};
  // cv::Mat has no const view; imdecode only reads.
  const cv::Mat buffer(1, static_cast<int>(bytes.size()), CV_8UC1,
                       const_cast<std::uint8_t*>(bytes.data()));
  try {
    return packed(c.imdecode(buffer, cv::IMREAD_GRAYSCALE));
  } catch (const cv::Exception& e) {
    return invalid_argument(std::string("undecodable image: ") + e.what());
  }
}

}  // namespace hc::calib
