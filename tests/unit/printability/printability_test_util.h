// The printability tests' calls of check_mesh and repair_mesh: a failure is a test failure, and the
// test goes on with an empty report or summary.
#pragma once

#include <gtest/gtest.h>

#include "common/mesh.h"
#include "fabrication/printability/mesh_check.h"
#include "fabrication/printability/mesh_repair.h"

namespace hc::testing {

inline fabrication::MeshCheckReport check(const TriangleMesh& m,
                                          fabrication::MeshCheckOptions options = {}) {
  auto r = fabrication::check_mesh(m, options);
  EXPECT_TRUE(r.ok()) << r.status().to_string();
  return r.ok() ? *r : fabrication::MeshCheckReport{};
}

inline fabrication::MeshRepairSummary repair(TriangleMesh* m,
                                             fabrication::MeshRepairOptions options = {}) {
  fabrication::MeshRepairSummary s;
  const Status st = fabrication::repair_mesh(options, m, &s);
  EXPECT_TRUE(st.ok()) << st.to_string();
  return s;
}

}  // namespace hc::testing
