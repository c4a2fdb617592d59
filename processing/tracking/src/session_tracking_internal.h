// Shared pieces of session tracking's translation units (session_detections.cpp: reading the
// detections from the session's MCAP; session_tracking.cpp: tracking, registration to the
// template, force distribution; occlusion_fill.cpp: the probe-contact occlusion fill). Not a
// public header: the public interface is processing/tracking/session_tracking.h.
#pragma once

#include <chrono>
#include <cstdint>
#include <vector>

#include "common/clock.h"
#include "processing/tracking/session_tracking.h"

namespace hc::tracking {

using Clock = std::chrono::steady_clock;

// Nodes on the boundary of a tet mesh: those of faces that belong to one tet only.
std::vector<std::uint8_t> boundary_nodes(const TetMesh& mesh);

// The probe sphere as a constraint of the occlusion fill (template frame). A smooth fill of the
// visible markers' displacements misses the dimple the sphere presses: the visible markers around
// it moved less than the hidden ones under it, and a biharmonic interpolant through a deep point
// under the tip and shallow ones around it overshoots below the sphere near the contact's edge
// (a whole 30-step press reached 0.7 mm there). So the sphere cap over the contact patch is a
// constraint of its own (below), and two rules are applied to the current fill, which is solved
// again with the resulting points as constraints (3 passes: the contact set settles):
//  * any filled point inside the sphere is moved onto it (along the push direction): the
//    specimen cannot enter the probe;
//  * a filled surface node within the contact radius a of the probe's axis is put on the sphere
//    wherever the fill left it: inside the contact patch the surface takes the indenter's shape.
//    For a sphere of radius R pressed to depth d into an elastic body, a = sqrt(R d) (Hertz
//    contact: K. L. Johnson, Contact Mechanics, 1985, Sec. 4.2, d = a^2 / R); d is the depth of
//    the tip below the rest surface there (the rest surface nodes nearest the axis, weighted by
//    inverse lateral distance).
std::vector<Eigen::Vector3d> fill_with_probe_contact(
    const std::vector<Eigen::Vector3d>& known_p, const std::vector<Eigen::Vector3d>& known_d,
    const std::vector<Eigen::Vector3d>& query, const std::vector<std::uint8_t>& query_on_surface,
    const std::vector<Eigen::Vector3d>& surface_nodes, const Eigen::Vector3d& tip,
    const Eigen::Vector3d& down, const SessionTrackOptions& options,
    std::vector<Eigen::Vector3d> filled);

}  // namespace hc::tracking
