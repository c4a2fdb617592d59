// Mesh reading speed on a ~1M-triangle closed mesh (a finely tessellated torus), against the speed
// of reading the same file and discarding it (`cat FILE > /dev/null`), so the ratio shows how far
// the parser is from the I/O limit. MB/s is file bytes over wall time. Both baselines run: `cat`
// itself (process start included) and an in-process read() loop.
//
//   bench_mesh_io --benchmark_min_time=2
#include <benchmark/benchmark.h>
#include <fcntl.h>
#include <unistd.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <numbers>
#include <string>
#include <vector>

#include "common/file_io.h"
#include "common/mesh_io.h"

namespace {

// Major circle of radius 1 swept by a minor circle of radius 0.3: 2 * major * minor triangles,
// every vertex shared by six of them, no boundary.
constexpr int kMajorSegments = 1000;
constexpr int kMinorSegments = 500;

hc::TriangleMesh torus() {
  constexpr double kMajorRadius = 1.0;
  constexpr double kMinorRadius = 0.3;
  hc::TriangleMesh m;
  m.vertices.resize(kMajorSegments * kMinorSegments, 3);
  m.triangles.resize(2 * kMajorSegments * kMinorSegments, 3);
  auto id = [](int i, int j) {
    return (i % kMajorSegments) * kMinorSegments + (j % kMinorSegments);
  };
  for (int i = 0; i < kMajorSegments; ++i) {
    const double u = 2 * std::numbers::pi * i / kMajorSegments;
    for (int j = 0; j < kMinorSegments; ++j) {
      const double v = 2 * std::numbers::pi * j / kMinorSegments;
      const double r = kMajorRadius + kMinorRadius * std::cos(v);
      m.vertices.row(id(i, j)) << r * std::cos(u), r * std::sin(u), kMinorRadius * std::sin(v);
      const int t = 2 * id(i, j);
      m.triangles.row(t) << id(i, j), id(i + 1, j), id(i + 1, j + 1);
      m.triangles.row(t + 1) << id(i, j), id(i + 1, j + 1), id(i, j + 1);
    }
  }
  return m;
}

// The usual binary PLY from scanners and other tools: float xyz, uchar/int face lists.
std::string float_ply(const hc::TriangleMesh& m) {
  std::string out =
      "ply\nformat binary_little_endian 1.0\nelement vertex " + std::to_string(m.num_vertices()) +
      "\nproperty float x\nproperty float y\nproperty float z\nelement face " +
      std::to_string(m.num_triangles()) + "\nproperty list uchar int vertex_indices\nend_header\n";
  for (Eigen::Index i = 0; i < m.num_vertices(); ++i)
    for (int k = 0; k < 3; ++k) {
      const auto f = static_cast<float>(m.vertices(i, k));
      out.append(reinterpret_cast<const char*>(&f), sizeof f);
    }
  for (Eigen::Index t = 0; t < m.num_triangles(); ++t) {
    out.push_back(3);
    for (int k = 0; k < 3; ++k) {
      const std::int32_t v = m.triangles(t, k);
      out.append(reinterpret_cast<const char*>(&v), sizeof v);
    }
  }
  return out;
}

// Files written once per process, removed at exit.
class Files {
 public:
  static Files& get() {
    static Files f;
    return f;
  }
  std::filesystem::path stl, ply_double, ply_float, obj;

 private:
  Files() {
    dir_ = std::filesystem::temp_directory_path() /
           ("hardcopy-bench-mesh-io-" + std::to_string(::getpid()));
    std::filesystem::create_directories(dir_);
    const hc::TriangleMesh m = torus();
    stl = dir_ / "torus.stl";
    ply_double = dir_ / "torus.ply";
    ply_float = dir_ / "torus_float.ply";
    obj = dir_ / "torus.obj";
    bool ok = hc::write_mesh(stl, m).ok() && hc::write_mesh(ply_double, m).ok() &&
              hc::write_file_atomic(ply_float, float_ply(m)).ok() && hc::write_mesh(obj, m).ok();
    if (!ok) {
      std::fprintf(stderr, "cannot write the benchmark meshes under %s\n", dir_.c_str());
      std::exit(1);
    }
  }
  ~Files() {
    std::error_code ec;
    std::filesystem::remove_all(dir_, ec);
  }
  std::filesystem::path dir_;
};

void read_mesh_bench(benchmark::State& state, const std::filesystem::path& path,
                     const hc::MeshReadOptions& options = {}) {
  const auto size = static_cast<std::int64_t>(std::filesystem::file_size(path));
  for (auto _ : state) {
    auto m = hc::read_mesh(path, options);
    if (!m.ok()) {
      state.SkipWithError(m.status().to_string().c_str());
      return;
    }
    benchmark::DoNotOptimize(m->triangles.data());
  }
  state.SetBytesProcessed(state.iterations() * size);
}

// parse_mesh on bytes already in memory: read_mesh minus read_file, to show where the time goes.
void parse_mesh_bench(benchmark::State& state, const std::filesystem::path& path,
                      hc::MeshFormat format, const hc::MeshReadOptions& options = {}) {
  const auto bytes = hc::read_file(path);
  if (!bytes.ok()) {
    state.SkipWithError(bytes.status().to_string().c_str());
    return;
  }
  for (auto _ : state) {
    auto m = hc::parse_mesh(*bytes, format, path.string(), options);
    if (!m.ok()) {
      state.SkipWithError(m.status().to_string().c_str());
      return;
    }
    benchmark::DoNotOptimize(m->triangles.data());
  }
  state.SetBytesProcessed(state.iterations() * static_cast<std::int64_t>(bytes->size()));
}

// The I/O floor: read() the whole file into a reused buffer and throw it away.
void read_and_discard_bench(benchmark::State& state, const std::filesystem::path& path) {
  const auto size = static_cast<std::int64_t>(std::filesystem::file_size(path));
  std::vector<char> buf(std::size_t{1} << 17);
  for (auto _ : state) {
    const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
    if (fd < 0) {
      state.SkipWithError("cannot open");
      return;
    }
    std::int64_t total = 0;
    for (ssize_t n; (n = ::read(fd, buf.data(), buf.size())) > 0;) total += n;
    ::close(fd);
    benchmark::DoNotOptimize(total);
  }
  state.SetBytesProcessed(state.iterations() * size);
}

// The baseline the issue names, literally: `cat FILE > /dev/null` (includes starting cat).
void cat_bench(benchmark::State& state, const std::filesystem::path& path) {
  const auto size = static_cast<std::int64_t>(std::filesystem::file_size(path));
  const std::string cmd = "cat '" + path.string() + "' > /dev/null";
  for (auto _ : state) {
    if (std::system(cmd.c_str()) != 0) {
      state.SkipWithError("cat failed");
      return;
    }
  }
  state.SetBytesProcessed(state.iterations() * size);
}

void BM_Cat_Stl(benchmark::State& s) { cat_bench(s, Files::get().stl); }
void BM_Cat_Ply(benchmark::State& s) { cat_bench(s, Files::get().ply_double); }
void BM_ReadAndDiscard_Stl(benchmark::State& s) { read_and_discard_bench(s, Files::get().stl); }
void BM_ReadAndDiscard_Ply(benchmark::State& s) {
  read_and_discard_bench(s, Files::get().ply_double);
}
void BM_ReadBinaryStl_Welded(benchmark::State& s) { read_mesh_bench(s, Files::get().stl); }
void BM_ReadBinaryStl_Unwelded(benchmark::State& s) {
  hc::MeshReadOptions o;
  o.weld_stl_vertices = false;
  read_mesh_bench(s, Files::get().stl, o);
}
void BM_ReadBinaryPly_Double(benchmark::State& s) { read_mesh_bench(s, Files::get().ply_double); }
void BM_ReadBinaryPly_Float(benchmark::State& s) { read_mesh_bench(s, Files::get().ply_float); }
void BM_ReadAsciiObj(benchmark::State& s) { read_mesh_bench(s, Files::get().obj); }
void BM_ParseBinaryStl_Welded(benchmark::State& s) {
  parse_mesh_bench(s, Files::get().stl, hc::MeshFormat::kStl);
}
void BM_ParseBinaryPly_Double(benchmark::State& s) {
  parse_mesh_bench(s, Files::get().ply_double, hc::MeshFormat::kPly);
}

BENCHMARK(BM_Cat_Stl)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_Cat_Ply)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_ReadAndDiscard_Stl)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_ReadAndDiscard_Ply)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_ReadBinaryStl_Welded)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_ReadBinaryStl_Unwelded)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_ReadBinaryPly_Double)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_ReadBinaryPly_Float)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_ReadAsciiObj)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_ParseBinaryStl_Welded)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_ParseBinaryPly_Double)->Unit(benchmark::kMillisecond)->UseRealTime();

}  // namespace

BENCHMARK_MAIN();
