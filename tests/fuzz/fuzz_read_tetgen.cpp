// libFuzzer target: the TetGen .node/.ele reader on arbitrary bytes. The input is the .node text,
// optionally followed by "@@ele\n" and the .ele text (the seed corpus uses that form); without the
// separator only the .node part is parsed. Beyond the sanitizers it checks the reader's contract:
// errors are kInvalidArgument, and an accepted mesh has finite coordinates, every index in range,
// sizes that agree and only positively oriented tets.
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <string_view>

#include "common/tet_mesh_io.h"

namespace {

constexpr std::string_view kSeparator = "@@ele\n";

void check_contract(const hc::Result<hc::TetMesh>& r, bool with_tets) {
  if (!r.ok()) {
    if (r.status().code() != hc::StatusCode::kInvalidArgument) std::abort();
    return;
  }
  const hc::TetMesh& m = *r;
  if (m.num_nodes() == 0 || !m.nodes.allFinite() || !m.node_attributes.allFinite()) std::abort();
  if (!m.node_markers.empty() && std::ssize(m.node_markers) != m.num_nodes()) std::abort();
  if (m.node_attributes.size() > 0 && m.node_attributes.rows() != m.num_nodes()) std::abort();
  if (!with_tets) return;
  if (m.num_tets() == 0) std::abort();
  if (m.tets.minCoeff() < 0 || m.tets.maxCoeff() >= m.num_nodes()) std::abort();
  if (!m.tet_regions.empty() && std::ssize(m.tet_regions) != m.num_tets()) std::abort();
  for (Eigen::Index t = 0; t < m.num_tets(); ++t)
    if (!(hc::tet_signed_volume(m, t) > 0)) std::abort();
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string_view bytes(reinterpret_cast<const char*>(data), size);
  const std::size_t sep = bytes.find(kSeparator);
  hc::TetMeshReadOptions options;
  options.max_elements = 1 << 20;
  if (sep == std::string_view::npos) {
    check_contract(hc::parse_tetgen_node(bytes, "fuzz.node", options), false);
  } else {
    check_contract(hc::parse_tetgen(bytes.substr(0, sep), bytes.substr(sep + kSeparator.size()),
                                    "fuzz.node", "fuzz.ele", options),
                   true);
  }
  return 0;
}
