// Helpers for the mesh I/O tests: gzip in memory, the signed volume of a mesh, and lib3mf as a
// third-party reader of the 3MF files we write (when the build found it: HARDCOPY_HAVE_LIB3MF).
#pragma once

#include <gtest/gtest.h>
#include <zlib.h>
#include <Eigen/Geometry>

#include <cmath>
#include <string>
#include <string_view>

#include "common/mesh.h"
#include "sanitizer.h"  // HC_TEST_SANITIZED: ASan, whose leak checker comes with it

#if HARDCOPY_HAVE_LIB3MF
#include <filesystem>

#include <Model/COM/NMR_DLLInterfaces.h>
#endif
#ifdef HC_TEST_SANITIZED
#include <sanitizer/lsan_interface.h>
#endif

namespace hc::testing {

// `plain` gzip-compressed (the gzip wrapper, which compress() does not write), at level 9.
inline std::string gzip(std::string_view plain) {
  z_stream zs{};
  EXPECT_EQ(deflateInit2(&zs, 9, Z_DEFLATED, 15 + 16, 8, Z_DEFAULT_STRATEGY), Z_OK);
  std::string gz(deflateBound(&zs, static_cast<uLong>(plain.size())) + 64, '\0');
  zs.next_in = reinterpret_cast<Bytef*>(const_cast<char*>(plain.data()));
  zs.avail_in = static_cast<uInt>(plain.size());
  zs.next_out = reinterpret_cast<Bytef*>(gz.data());
  zs.avail_out = static_cast<uInt>(gz.size());
  EXPECT_EQ(deflate(&zs, Z_FINISH), Z_STREAM_END);
  gz.resize(zs.total_out);
  deflateEnd(&zs);
  return gz;
}

// Sum of det[a b c] / 6 over triangles (the enclosed volume of a closed, outward-oriented mesh),
// and the sum of its terms' magnitudes: the scale that rounding errors are relative to. They
// differ when terms cancel, as in blobby-shuffled.off whose misoriented faces leave a net volume
// a thousandth of its size.
struct Volume {
  double signed_sum = 0;
  double magnitude = 0;
};
inline Volume signed_volume(const TriangleMesh& m) {
  Volume v;
  for (Eigen::Index t = 0; t < m.num_triangles(); ++t) {
    const Eigen::Vector3d a = m.vertices.row(m.triangles(t, 0)).transpose();
    const Eigen::Vector3d b = m.vertices.row(m.triangles(t, 1)).transpose();
    const Eigen::Vector3d c = m.vertices.row(m.triangles(t, 2)).transpose();
    const double term = a.dot(b.cross(c)) / 6.0;
    v.signed_sum += term;
    v.magnitude += std::abs(term);
  }
  return v;
}

#if HARDCOPY_HAVE_LIB3MF
// lib3mf 1.8.1's package reader never closes the zip entries it opens
// (NMR::COpcPackageReader::openZIPEntryIndexed); keep LeakSanitizer from blaming the test for it.
inline int read_3mf_file(NMR::PLib3MFModelReader* reader, const std::filesystem::path& path) {
#ifdef HC_TEST_SANITIZED
  __lsan::ScopedDisabler third_party_leak;
#endif
  return NMR::lib3mf_reader_readfromfileutf8(reader, path.c_str());
}
#endif  // HARDCOPY_HAVE_LIB3MF

}  // namespace hc::testing
