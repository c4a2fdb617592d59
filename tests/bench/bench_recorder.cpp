// Recorder throughput: the automated rig's worst case -- 7 cameras x 1600x1200 Mono8 at 15 fps
// (foxglove.RawImage, 201.6 MB/s of pixels) plus a 6-axis F/T at 7 kHz and an FSR at 1 kHz (JSON
// messages) -- written through McapWriter with no / lz4 / zstd chunk compression, inline or on
// background threads. Reported next to `dd` sequential write speed to the same disk, measured in
// the same run (conv=fdatasync, like our file which is fdatasync'ed before the clock stops).
//
//   bench_recorder [--benchmark_filter=...]    (HARDCOPY_BENCH_DIR: where to write; default .)
//
// Counters: capture_MBps = message bytes handed to the writer per second; file_MBps = bytes on disk
// per second; dd_MBps; vs_dd = file_MBps / dd_MBps; realtime = capture seconds per wall second
// (>= 1 means the rig's data rate is sustained); cpu_pct = process CPU time / wall time (200 % =
// both cores busy).
#include <benchmark/benchmark.h>
#include <fcntl.h>
#include <sys/resource.h>
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <random>
#include <regex>
#include <string>

#include "common/json.h"
#include "rig_daemon/recording/foxglove_image.h"
#include "rig_daemon/recording/mcap_writer.h"
#include "rig_daemon/recording/session_conventions.h"

namespace {

namespace rec = hc::recording;

constexpr int kCameras = 7;
constexpr std::uint32_t kWidth = 1600, kHeight = 1200;  // Basler piA1600 AOI
constexpr int kFps = 15;
constexpr int kFtHz = 7000;  // ATI Net F/T RDT maximum rate
constexpr int kFsrHz = 1000;
constexpr int kCaptureSeconds = 2;

std::filesystem::path bench_dir() {
  const char* d = std::getenv("HARDCOPY_BENCH_DIR");
  return d != nullptr ? std::filesystem::path(d) : std::filesystem::current_path();
}

// `dd` sequential write of `mb` MiB with fdatasync, MB/s parsed from its summary line.
double dd_mbps(const std::filesystem::path& dir, int mb) {
  const auto file = dir / "bench_recorder_dd.tmp";
  const std::string cmd = "dd if=/dev/zero of=" + file.string() +
                          " bs=4M count=" + std::to_string(mb / 4) + " conv=fdatasync 2>&1";
  FILE* p = ::popen(cmd.c_str(), "r");
  std::string out;
  if (p != nullptr) {
    char buf[512];
    while (std::fgets(buf, sizeof buf, p) != nullptr) out += buf;
    ::pclose(p);
  }
  std::filesystem::remove(file);
  // "... copied, 0.5 s, 840 MB/s" (GB/s on fast disks).
  std::smatch m;
  if (std::regex_search(out, m, std::regex(R"(([0-9.,]+) (kB|MB|GB)/s)"))) {
    std::string num = m[1];
    for (char& c : num)
      if (c == ',') c = '.';
    const double v = std::stod(num);
    return m[2] == "GB" ? v * 1000 : m[2] == "kB" ? v / 1000 : v;
  }
  return 0;
}

double cpu_seconds() {
  rusage ru{};
  ::getrusage(RUSAGE_SELF, &ru);
  return static_cast<double>(ru.ru_utime.tv_sec + ru.ru_stime.tv_sec) +
         1e-6 * static_cast<double>(ru.ru_utime.tv_usec + ru.ru_stime.tv_usec);
}

// Camera-like frames: a smooth shading, dark marker dots, and +-2 LSB sensor noise that changes
// every frame (so compression sees what a real camera gives, not a constant image).
struct FrameSource {
  std::vector<rec::Bytes> base;
  rec::Bytes noise;
  FrameSource() {
    std::mt19937 rng(7);
    noise.resize(kWidth * kHeight + 4096);
    for (auto& n : noise) n = static_cast<std::uint8_t>(rng() % 5);
    for (int c = 0; c < kCameras; ++c) {
      rec::Bytes img(kWidth * kHeight);
      for (std::uint32_t y = 0; y < kHeight; ++y)
        for (std::uint32_t x = 0; x < kWidth; ++x) {
          int v = 60 + static_cast<int>((x + y + 37u * static_cast<std::uint32_t>(c)) % 400) / 4;
          const int dx = static_cast<int>(x % 40) - 20, dy = static_cast<int>(y % 40) - 20;
          if (dx * dx + dy * dy < 16) v = 20;  // marker dot
          img[y * kWidth + x] = static_cast<std::uint8_t>(v);
        }
      base.push_back(std::move(img));
    }
  }
  void frame(int camera, int index, rec::Bytes& px) const {
    px = base[static_cast<std::size_t>(camera)];
    const std::size_t off = static_cast<std::size_t>(index * 131 + camera * 17) % 4096;
    for (std::size_t i = 0; i < px.size(); ++i)
      px[i] = static_cast<std::uint8_t>(px[i] + noise[off + i]);
  }
};

const FrameSource& frames() {
  static const FrameSource f;
  return f;
}

void BM_RecordRig(benchmark::State& state) {
  const auto compression = static_cast<rec::Compression>(state.range(0));
  const int threads = static_cast<int>(state.range(1));
  const auto dir = bench_dir();
  const auto path = dir / "bench_recorder.mcap";
  // Pre-render the frames outside the timed region (the cameras deliver them).
  std::vector<rec::Bytes> pixels(kCameras * kFps);
  for (int c = 0; c < kCameras; ++c)
    for (int f = 0; f < kFps; ++f)
      frames().frame(c, f, pixels[static_cast<std::size_t>(c * kFps + f)]);
  const double dd = dd_mbps(dir, 512);

  double wall = 0, cpu = 0;
  std::uint64_t capture_bytes = 0, file_bytes = 0;
  for (auto _ : state) {
    const auto t0 = std::chrono::steady_clock::now();
    const double c0 = cpu_seconds();
    rec::McapWriter::Options opt;
    opt.compression = compression;
    opt.compression_level = compression == rec::Compression::kZstd ? 1 : 0;
    opt.compression_threads = threads;
    opt.chunk_size = 8u << 20;
    auto w = rec::McapWriter::open(path, opt);
    if (!w.ok()) {
      state.SkipWithError(w.status().to_string().c_str());
      return;
    }
    auto& writer = **w;
    const auto s_img =
        writer.add_schema(rec::kRawImageSchemaName, rec::kProtobufEncoding, rec::raw_image_schema())
            .value();
    const std::string js = rec::json_schema_for("hardcopy.Wrench", {});
    const auto s_json = writer
                            .add_schema("hardcopy.Wrench", rec::kJsonSchemaEncoding,
                                        rec::Bytes(js.begin(), js.end()))
                            .value();
    std::vector<std::uint16_t> cams;
    for (int c = 0; c < kCameras; ++c)
      cams.push_back(
          writer.add_channel("/cam" + std::to_string(c) + "/image", rec::kProtobufEncoding, s_img)
              .value());
    const auto ft = writer.add_channel("/ft0/wrench", rec::kJsonEncoding, s_json).value();
    const auto fsr = writer.add_channel("/fsr0/samples", rec::kJsonEncoding, s_json).value();
    rec::Bytes msg;
    capture_bytes = 0;
    // Messages interleaved in time order, as the recorder receives them: per 1/7000 s one F/T
    // sample, every 7th an FSR sample, and the camera frames on their 15 Hz ticks.
    const std::uint64_t ft_period = 1'000'000'000ull / kFtHz;
    for (int s = 0; s < kCaptureSeconds; ++s) {
      for (int i = 0; i < kFtHz; ++i) {
        const std::uint64_t t = static_cast<std::uint64_t>(s) * 1'000'000'000ull +
                                static_cast<std::uint64_t>(i) * ft_period;
        const hc::Json sample{
            {"fx", 0.001 * i}, {"fy", -0.002 * i}, {"fz", 12.5 + 0.0001 * i},       {"tx", 0.01},
            {"ty", 0.02},      {"tz", 0.03},       {"rdt_sequence", s * kFtHz + i}, {"status", 0}};
        msg = rec::json_message(sample);
        capture_bytes += msg.size();
        (void)writer.write_message(ft, t, t, msg);
        if (i % (kFtHz / kFsrHz) == 0) {
          msg = rec::json_message(hc::Json{{"raw", 512 + i % 100}, {"sequence", i}});
          capture_bytes += msg.size();
          (void)writer.write_message(fsr, t, t, msg);
        }
        if (i % (kFtHz / kFps) == 0) {
          const int f = i / (kFtHz / kFps);
          if (f >= kFps) continue;
          for (int c = 0; c < kCameras; ++c) {
            const auto& px = pixels[static_cast<std::size_t>(c * kFps + f)];
            rec::encode_raw_image_view(static_cast<std::int64_t>(t), "cam", kWidth, kHeight,
                                       "mono8", kWidth, px, msg);
            capture_bytes += msg.size();
            (void)writer.write_message(cams[static_cast<std::size_t>(c)], t, t, msg);
          }
        }
      }
    }
    auto summary = writer.close();
    // Same durability as dd's conv=fdatasync.
    const int fd = ::open(path.c_str(), O_RDONLY);
    if (fd >= 0) {
      ::fdatasync(fd);
      ::close(fd);
    }
    wall = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    cpu = cpu_seconds() - c0;
    file_bytes = summary.ok() ? summary->file_size : 0;
    state.SetIterationTime(wall);
  }
  std::filesystem::remove(path);
  state.counters["capture_MBps"] = static_cast<double>(capture_bytes) / 1e6 / wall;
  state.counters["file_MBps"] = static_cast<double>(file_bytes) / 1e6 / wall;
  state.counters["dd_MBps"] = dd;
  state.counters["vs_dd"] = dd > 0 ? static_cast<double>(file_bytes) / 1e6 / wall / dd : 0;
  state.counters["ratio"] =
      file_bytes > 0 ? static_cast<double>(capture_bytes) / static_cast<double>(file_bytes) : 0;
  state.counters["realtime"] = kCaptureSeconds / wall;
  state.counters["cpu_pct"] = 100.0 * cpu / wall;
  state.SetLabel(std::string(rec::compression_display_name(compression)) +
                 (threads > 0 ? " +" + std::to_string(threads) + " threads" : " inline"));
}

BENCHMARK(BM_RecordRig)
    ->Args({static_cast<int>(rec::Compression::kNone), 0})
    ->Args({static_cast<int>(rec::Compression::kLz4), 0})
    ->Args({static_cast<int>(rec::Compression::kLz4), 2})
    ->Args({static_cast<int>(rec::Compression::kZstd), 0})
    ->Args({static_cast<int>(rec::Compression::kZstd), 2})
    ->Iterations(1)
    ->UseManualTime()
    ->Unit(benchmark::kMillisecond);

}  // namespace

BENCHMARK_MAIN();
