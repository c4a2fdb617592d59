// TetGen wrapper and box specimens.
#include "processing/meshing/tetrahedralize.h"

#include <fmt/format.h>
#include <tetgen.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <limits>
#include <memory>
#include <numeric>

#include "common/file_io.h"
#include "geometry/mesh_ops.h"

namespace hc::meshing {
namespace {

// TetGen's termination codes (tetgen.h, terminatetetgen()), thrown as int in library mode.
std::string tetgen_error(int code) {
  switch (code) {
    case 1:
      return "TetGen ran out of memory";
    case 2:
      return "TetGen hit an internal error";
    case 3:
      return "TetGen found self-intersecting facets in the input surface";
    case 4:
      return "TetGen found a very small input feature size (nearly coincident input)";
    case 5:
      return "TetGen found two very close input facets";
    case 10:
      return "TetGen found an input error (e.g. an open or invalid surface)";
    default:
      return fmt::format("TetGen failed with code {}", code);
  }
}

void fill_regions_and_holes(const TetrahedralizeOptions& options, tetgenio& in) {
  if (!options.regions.empty()) {
    delete[] in.regionlist;
    in.numberofregions = static_cast<int>(options.regions.size());
    in.regionlist = new REAL[5 * options.regions.size()];
    for (std::size_t i = 0; i < options.regions.size(); ++i) {
      const RegionSeed& r = options.regions[i];
      in.regionlist[5 * i + 0] = r.seed.x();
      in.regionlist[5 * i + 1] = r.seed.y();
      in.regionlist[5 * i + 2] = r.seed.z();
      in.regionlist[5 * i + 3] = r.attribute;
      in.regionlist[5 * i + 4] = r.max_volume > 0 ? r.max_volume : -1.0;
    }
  }
  if (!options.holes.empty()) {
    delete[] in.holelist;
    in.numberofholes = static_cast<int>(options.holes.size());
    in.holelist = new REAL[3 * options.holes.size()];
    for (std::size_t i = 0; i < options.holes.size(); ++i)
      for (int k = 0; k < 3; ++k)
        in.holelist[3 * i + static_cast<std::size_t>(k)] = options.holes[i][k];
  }
}

Result<TetMesh> run_tetgen(tetgenio& in, const TetrahedralizeOptions& options,
                           bool region_attributes, std::string_view what,
                           TetrahedralizeSummary* summary) {
  const auto start = std::chrono::steady_clock::now();
  std::string switches = options.tetgen_switches();
  if (region_attributes && switches.find('A') == std::string::npos)
    switches = "pA" + switches.substr(1);
  tetgenio out;
  tetgenio background;  // the sizing function's background mesh (TetGen 'm')
  if (options.edge_size) {
    Eigen::AlignedBox3d box;
    for (int i = 0; i < in.numberofpoints; ++i)
      box.extend(Eigen::Vector3d(in.pointlist[3 * i], in.pointlist[3 * i + 1],
                                 in.pointlist[3 * i + 2]));
    HC_ASSIGN_OR_RETURN(const TetMesh bg, background_mesh(options.edge_size, box));
    background.firstnumber = 0;
    background.numberofpoints = static_cast<int>(bg.num_nodes());
    background.pointlist = new REAL[static_cast<std::size_t>(3 * bg.num_nodes())];
    std::memcpy(background.pointlist, bg.nodes.data(),
                static_cast<std::size_t>(3 * bg.num_nodes()) * sizeof(double));
    background.numberofpointmtrs = 1;
    background.pointmtrlist = new REAL[static_cast<std::size_t>(bg.num_nodes())];
    for (Eigen::Index i = 0; i < bg.num_nodes(); ++i)
      background.pointmtrlist[i] = bg.node_attributes(i, 0);
    background.numberofcorners = 4;
    background.numberoftetrahedra = static_cast<int>(bg.num_tets());
    background.tetrahedronlist = new int[static_cast<std::size_t>(4 * bg.num_tets())];
    std::memcpy(background.tetrahedronlist, bg.tets.data(),
                static_cast<std::size_t>(4 * bg.num_tets()) * sizeof(int));
  }
  try {
    tetgenbehavior b;
    std::vector<char> sw(switches.begin(), switches.end());
    sw.push_back('\0');
    if (!b.parse_commandline(sw.data()))
      return internal_error(fmt::format("TetGen rejected the switches \"{}\"", switches));
    tetrahedralize(&b, &in, &out, nullptr, options.edge_size ? &background : nullptr);
  } catch (int code) {
    return invalid_argument(fmt::format("{}: {}", what, tetgen_error(code)));
  } catch (const std::exception& e) {
    return internal_error(fmt::format("{}: TetGen failed: {}", what, e.what()));
  } catch (...) {
    return internal_error(fmt::format("{}: TetGen failed", what));
  }
  if (out.numberoftetrahedra <= 0 || out.numberofpoints <= 0)
    return failed_precondition(fmt::format("{}: TetGen produced no tetrahedra", what));
  if (out.numberofcorners != 4)
    return internal_error(fmt::format("TetGen produced {}-node tetrahedra", out.numberofcorners));

  TetMesh mesh;
  const Eigen::Index n = out.numberofpoints;
  mesh.nodes.resize(n, 3);
  std::memcpy(mesh.nodes.data(), out.pointlist, static_cast<std::size_t>(3 * n) * sizeof(double));
  // Markers: 1 on every node of a facet face (TetGen's trifaces: the boundary and any internal
  // facets), 0 elsewhere. TetGen's own point markers only echo input markers.
  mesh.node_markers.assign(static_cast<std::size_t>(n), 0);
  if (out.trifacelist != nullptr) {
    for (Eigen::Index f = 0; f < 3 * Eigen::Index{out.numberoftrifaces}; ++f) {
      const int v = out.trifacelist[f] - out.firstnumber;
      if (v >= 0 && v < n) mesh.node_markers[static_cast<std::size_t>(v)] = 1;
    }
  }
  const Eigen::Index nt = out.numberoftetrahedra;
  const int base = out.firstnumber;
  mesh.tets.resize(nt, 4);
  for (Eigen::Index t = 0; t < nt; ++t)
    for (int k = 0; k < 4; ++k) mesh.tets(t, k) = out.tetrahedronlist[4 * t + k] - base;
  if (out.numberoftetrahedronattributes > 0 && region_attributes) {
    mesh.tet_regions.resize(static_cast<std::size_t>(nt));
    for (Eigen::Index t = 0; t < nt; ++t)
      mesh.tet_regions[static_cast<std::size_t>(t)] = static_cast<int>(
          std::lround(out.tetrahedronattributelist[t * out.numberoftetrahedronattributes]));
  }
  // TetGen's orientation convention is the opposite of ours for some tets: make every tet
  // positive (a zero-volume tet from TetGen would be a bug in its output).
  double vmin = std::numeric_limits<double>::infinity(), vmax = 0, vsum = 0;
  for (Eigen::Index t = 0; t < nt; ++t) {
    double v = tet_signed_volume(mesh, t);
    if (v < 0) {
      std::swap(mesh.tets(t, 2), mesh.tets(t, 3));
      v = -v;
    }
    if (!(v > 0))
      return internal_error(fmt::format("{}: TetGen produced a degenerate tet {}", what, t));
    vmin = std::min(vmin, v);
    vmax = std::max(vmax, v);
    vsum += v;
  }
  if (summary != nullptr) {
    summary->switches = switches;
    summary->input_vertices = in.numberofpoints;
    summary->input_facets = in.numberoffacets;
    summary->nodes = n;
    summary->tets = nt;
    summary->boundary_faces = out.numberoftrifaces;
    summary->volume = vsum;
    summary->min_tet_volume = vmin;
    summary->max_tet_volume = vmax;
    summary->time_s =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  }
  return mesh;
}

}  // namespace

Status TetrahedralizeOptions::validate() const {
  if (!(std::isfinite(max_radius_edge_ratio) &&
        (max_radius_edge_ratio == 0 || max_radius_edge_ratio >= kMinRadiusEdgeRatio)))
    return invalid_argument(fmt::format(
        "quality (max radius-edge ratio) {} must be 0 (off) or >= {} (Delaunay refinement is "
        "proven to terminate for bounds >= 2; 1.00-1.03 were seen never finishing, 1.1 meshes "
        "pinion.off in 34 s)",
        max_radius_edge_ratio, kMinRadiusEdgeRatio));
  if (!(std::isfinite(min_dihedral_deg) && min_dihedral_deg >= 0 && min_dihedral_deg < 30))
    return invalid_argument(
        fmt::format("min dihedral angle {} must be in [0, 30) degrees", min_dihedral_deg));
  if (max_steiner_points < 0 || max_steiner_points > std::numeric_limits<int>::max())
    return invalid_argument(fmt::format("max Steiner points {} must be in [0, {}]",
                                        max_steiner_points, std::numeric_limits<int>::max()));
  if (!(std::isfinite(max_volume) && max_volume >= 0))
    return invalid_argument(fmt::format("max tet volume {} must be >= 0", max_volume));
  for (const RegionSeed& r : regions)
    if (!r.seed.allFinite() || !std::isfinite(r.max_volume))
      return invalid_argument("a region seed or volume is not finite");
  for (const Eigen::Vector3d& h : holes)
    if (!h.allFinite()) return invalid_argument("a hole point is not finite");
  return {};
}

std::string TetrahedralizeOptions::tetgen_switches() const {
  std::string s = "p";
  if (max_radius_edge_ratio > 0) {
    s += fmt::format("q{}", max_radius_edge_ratio);
    if (min_dihedral_deg > 0) s += fmt::format("/{}", min_dihedral_deg);
  }
  if (max_volume > 0) s += fmt::format("a{}", max_volume);
  if (edge_size) s += "m";
  if (!regions.empty()) {
    s += "A";
    const bool per_region = std::any_of(regions.begin(), regions.end(),
                                        [](const RegionSeed& r) { return r.max_volume > 0; });
    if (per_region) s += "a";
  }
  if (max_steiner_points > 0) s += fmt::format("S{}", max_steiner_points);
  s += "Q";
  return s;
}

Result<TetMesh> tetrahedralize(const TriangleMesh& surface, const TetrahedralizeOptions& options,
                               TetrahedralizeSummary* summary) {
  HC_RETURN_IF_ERROR(options.validate());
  const Eigen::Index nv = surface.num_vertices();
  const Eigen::Index nf = surface.num_triangles();
  if (nv < 4 || nf < 4)
    return invalid_argument(fmt::format(
        "surface has {} vertices and {} triangles, a closed surface needs at least 4 of each", nv,
        nf));
  if (!surface.vertices.allFinite()) return invalid_argument("surface has a non-finite vertex");
  if (surface.triangles.minCoeff() < 0 || surface.triangles.maxCoeff() >= nv)
    return invalid_argument("surface has a triangle index out of range");
  if (nv > std::numeric_limits<int>::max() / 3 || nf > std::numeric_limits<int>::max())
    return invalid_argument("surface too large for TetGen");
  // TetGen 1.5.0 frees its memory twice when it gives up on an input (terminatetetgen() frees,
  // then the unwinding destructor frees again: measured as a crash under AddressSanitizer on an
  // open surface), so the common defects are refused here, before TetGen sees them: every directed
  // edge must occur once and its reverse once (closed, manifold, consistently oriented), and no
  // triangle may repeat a corner.
  {
    std::vector<std::uint64_t> edges;
    edges.reserve(static_cast<std::size_t>(3 * nf));
    const auto key = [](int a, int b) {
      return (static_cast<std::uint64_t>(static_cast<std::uint32_t>(a)) << 32) |
             static_cast<std::uint32_t>(b);
    };
    for (Eigen::Index f = 0; f < nf; ++f) {
      const int a = surface.triangles(f, 0), b = surface.triangles(f, 1),
                c = surface.triangles(f, 2);
      if (a == b || b == c || a == c)
        return invalid_argument(fmt::format("surface triangle {} repeats a vertex", f));
      edges.push_back(key(a, b));
      edges.push_back(key(b, c));
      edges.push_back(key(c, a));
    }
    std::sort(edges.begin(), edges.end());
    std::size_t bad = 0;
    for (std::size_t i = 0; i < edges.size(); ++i) {
      const bool repeated =
          (i > 0 && edges[i] == edges[i - 1]) || (i + 1 < edges.size() && edges[i] == edges[i + 1]);
      const std::uint64_t rev = (edges[i] << 32) | (edges[i] >> 32);
      if (repeated || !std::binary_search(edges.begin(), edges.end(), rev)) ++bad;
    }
    if (bad > 0)
      return invalid_argument(fmt::format(
          "surface is not closed and consistently oriented: {} of {} edge sides have no single "
          "opposite partner (TetGen needs a closed manifold surface; try `hardcopy mesh repair`)",
          bad, edges.size()));
  }
  // ... and a self-intersecting surface (TetGen's own check then takes the crashing path: a double
  // free on ../shared/data/meshes/candleStand.stl). CGAL's exact test through the geometry target;
  // the first intersecting pair settles it.
  {
    geometry::SelfIntersectionQuery query;
    query.triangles.resize(static_cast<std::size_t>(nf));
    std::iota(query.triangles.begin(), query.triangles.end(), 0);
    query.is_polygon_mesh = true;  // closed, manifold and consistently oriented (checked above)
    query.max_pairs = 1;
    HC_ASSIGN_OR_RETURN(const geometry::SelfIntersectionCount count,
                        geometry::count_self_intersecting_pairs(surface, query));
    if (count.pairs > 0)
      return invalid_argument(
          "the surface intersects itself; TetGen needs a closed surface without "
          "self-intersections (try `hardcopy mesh repair --resolve-self-intersections`)");
  }

  tetgenio in;  // frees every list below in its destructor (delete[])
  in.firstnumber = 0;
  in.numberofpoints = static_cast<int>(nv);
  in.pointlist = new REAL[static_cast<std::size_t>(3 * nv)];
  std::memcpy(in.pointlist, surface.vertices.data(),
              static_cast<std::size_t>(3 * nv) * sizeof(double));
  in.numberoffacets = static_cast<int>(nf);
  in.facetlist = new tetgenio::facet[static_cast<std::size_t>(nf)];
  in.facetmarkerlist = new int[static_cast<std::size_t>(nf)];
  for (Eigen::Index f = 0; f < nf; ++f) {
    tetgenio::facet& facet = in.facetlist[f];
    tetgenio::init(&facet);
    facet.numberofpolygons = 1;
    facet.polygonlist = new tetgenio::polygon[1];
    tetgenio::init(&facet.polygonlist[0]);
    facet.polygonlist[0].numberofvertices = 3;
    facet.polygonlist[0].vertexlist = new int[3];
    for (int k = 0; k < 3; ++k) facet.polygonlist[0].vertexlist[k] = surface.triangles(f, k);
    in.facetmarkerlist[f] = 1;
  }
  fill_regions_and_holes(options, in);
  return run_tetgen(in, options, !options.regions.empty(), "surface", summary);
}

Result<TetMesh> tetrahedralize(const Plc& plc, const TetrahedralizeOptions& options,
                               TetrahedralizeSummary* summary, bool region_attributes) {
  HC_RETURN_IF_ERROR(options.validate());
  const Eigen::Index np = plc.points.rows();
  if (np < 4 || plc.facets.size() < 4)
    return invalid_argument(fmt::format(
        "PLC has {} points and {} facets, at least 4 of each needed", np, plc.facets.size()));
  if (!plc.points.allFinite()) return invalid_argument("PLC has a non-finite point");
  if (np > std::numeric_limits<int>::max() / 3 ||
      plc.facets.size() > static_cast<std::size_t>(std::numeric_limits<int>::max()))
    return invalid_argument("PLC too large for TetGen");
  tetgenio in;  // frees every list below in its destructor (delete[])
  in.firstnumber = 0;
  in.numberofpoints = static_cast<int>(np);
  in.pointlist = new REAL[static_cast<std::size_t>(3 * np)];
  std::memcpy(in.pointlist, plc.points.data(), static_cast<std::size_t>(3 * np) * sizeof(double));
  in.numberoffacets = static_cast<int>(plc.facets.size());
  in.facetlist = new tetgenio::facet[plc.facets.size()];
  in.facetmarkerlist = new int[plc.facets.size()];
  for (std::size_t f = 0; f < plc.facets.size(); ++f) {
    const Plc::Facet& src = plc.facets[f];
    tetgenio::facet& facet = in.facetlist[f];
    tetgenio::init(&facet);
    in.facetmarkerlist[f] = src.marker;
    if (src.polygons.empty() || src.polygons.size() > 1000000)
      return invalid_argument(fmt::format("facet {} has no polygon", f));
    facet.numberofpolygons = static_cast<int>(src.polygons.size());
    facet.polygonlist = new tetgenio::polygon[src.polygons.size()];
    for (std::size_t p = 0; p < src.polygons.size(); ++p) {
      tetgenio::init(&facet.polygonlist[p]);
      const std::vector<int>& poly = src.polygons[p];
      facet.polygonlist[p].numberofvertices = static_cast<int>(poly.size());
      facet.polygonlist[p].vertexlist = new int[poly.size()];
      for (std::size_t k = 0; k < poly.size(); ++k) {
        if (poly[k] < 0 || poly[k] >= np)
          return invalid_argument(fmt::format("facet {}: point index {} out of range", f, poly[k]));
        facet.polygonlist[p].vertexlist[k] = poly[k];
      }
    }
    if (!src.holes.empty()) {
      facet.numberofholes = static_cast<int>(src.holes.size());
      facet.holelist = new REAL[3 * src.holes.size()];
      for (std::size_t h = 0; h < src.holes.size(); ++h)
        for (int k = 0; k < 3; ++k)
          facet.holelist[3 * h + static_cast<std::size_t>(k)] = src.holes[h][k];
    }
  }
  TetrahedralizeOptions merged = options;
  merged.holes.insert(merged.holes.begin(), plc.holes.begin(), plc.holes.end());
  merged.regions.insert(merged.regions.begin(), plc.regions.begin(), plc.regions.end());
  fill_regions_and_holes(merged, in);
  // The PLC's own regions only count when asked for (TetGen's -A): keep the switches of `options`.
  TetrahedralizeOptions switches_from = options;
  return run_tetgen(in, switches_from, region_attributes || !options.regions.empty(), "PLC",
                    summary);
}

Result<TetMesh> tetrahedralize_poly(const std::filesystem::path& path,
                                    const TetrahedralizeOptions& options,
                                    TetrahedralizeSummary* summary, bool region_attributes) {
  HC_ASSIGN_OR_RETURN(const Plc plc, read_poly(path));
  Result<TetMesh> m = tetrahedralize(plc, options, summary, region_attributes);
  if (!m.ok()) return m.status().with_context(path.string());
  return m;
}

TriangleMesh box_surface(const Eigen::Vector3d& size) {
  TriangleMesh s;
  s.vertices.resize(8, 3);
  for (int i = 0; i < 8; ++i)
    s.vertices.row(i) << ((i & 1) ? size.x() : 0.0), ((i & 2) ? size.y() : 0.0),
        ((i & 4) ? size.z() : 0.0);
  // Counter-clockwise seen from outside.
  s.triangles.resize(12, 3);
  s.triangles << 0, 2, 1, 1, 2, 3,  // z = 0
      4, 5, 6, 5, 7, 6,             // z = size.z
      0, 1, 4, 1, 5, 4,             // y = 0
      2, 6, 3, 3, 6, 7,             // y = size.y
      0, 4, 2, 2, 4, 6,             // x = 0
      1, 3, 5, 3, 7, 5;             // x = size.x
  return s;
}

namespace {

Status check_box_size(const Eigen::Vector3d& size) {
  if (!size.allFinite() || (size.array() <= 0).any())
    return invalid_argument(fmt::format("box size [{}, {}, {}] must be positive and finite",
                                        size.x(), size.y(), size.z()));
  return {};
}

void mark_box_nodes(const Eigen::Vector3d& size, TetMesh& mesh) {
  const double tol = 1e-9 * size.maxCoeff();
  mesh.node_markers.assign(static_cast<std::size_t>(mesh.num_nodes()), kMarkerInterior);
  for (Eigen::Index i = 0; i < mesh.num_nodes(); ++i) {
    const Eigen::Vector3d p = mesh.nodes.row(i).transpose();
    int& m = mesh.node_markers[static_cast<std::size_t>(i)];
    if (std::abs(p.z()) <= tol) {
      m = kMarkerBottom;
    } else if (std::abs(p.z() - size.z()) <= tol) {
      m = kMarkerTop;
    } else if (std::abs(p.x()) <= tol || std::abs(p.x() - size.x()) <= tol ||
               std::abs(p.y()) <= tol || std::abs(p.y() - size.y()) <= tol) {
      m = kMarkerSide;
    }
  }
}

}  // namespace

Result<TetMesh> structured_box(const Eigen::Vector3d& size, const Eigen::Vector3i& cells) {
  HC_RETURN_IF_ERROR(check_box_size(size));
  if ((cells.array() < 1).any() || (cells.cast<double>().array() > 1000).any())
    return invalid_argument(
        fmt::format("box cells [{}, {}, {}] must be in 1..1000", cells.x(), cells.y(), cells.z()));
  const Eigen::Vector3i np = cells + Eigen::Vector3i::Ones();
  const std::int64_t n = std::int64_t{np.x()} * np.y() * np.z();
  const std::int64_t nt = 6 * std::int64_t{cells.x()} * cells.y() * cells.z();
  if (nt > std::numeric_limits<int>::max() / 4) return invalid_argument("box has too many cells");
  const auto id = [&](int i, int j, int k) { return i + np.x() * (j + np.y() * k); };
  TetMesh mesh;
  mesh.nodes.resize(n, 3);
  for (int k = 0; k < np.z(); ++k)
    for (int j = 0; j < np.y(); ++j)
      for (int i = 0; i < np.x(); ++i)
        mesh.nodes.row(id(i, j, k)) << size.x() * i / cells.x(), size.y() * j / cells.y(),
            size.z() * k / cells.z();
  // Freudenthal/Kuhn: the 6 monotone paths from corner 000 to 111, one tet per permutation of
  // the axes; every face is cut along its min-to-max diagonal, so neighbouring cells conform.
  static constexpr int kPerm[6][3] = {{0, 1, 2}, {0, 2, 1}, {1, 0, 2},
                                      {1, 2, 0}, {2, 0, 1}, {2, 1, 0}};
  mesh.tets.resize(nt, 4);
  Eigen::Index t = 0;
  for (int k = 0; k < cells.z(); ++k)
    for (int j = 0; j < cells.y(); ++j)
      for (int i = 0; i < cells.x(); ++i)
        for (const auto& perm : kPerm) {
          int c[3] = {i, j, k};
          mesh.tets(t, 0) = id(c[0], c[1], c[2]);
          for (int s = 0; s < 3; ++s) {
            ++c[perm[s]];
            mesh.tets(t, s + 1) = id(c[0], c[1], c[2]);
          }
          if (tet_signed_volume(mesh, t) < 0) std::swap(mesh.tets(t, 2), mesh.tets(t, 3));
          ++t;
        }
  mark_box_nodes(size, mesh);
  return mesh;
}

Result<TetMesh> box_tet_mesh(const Eigen::Vector3d& size, const TetrahedralizeOptions& options,
                             TetrahedralizeSummary* summary) {
  HC_RETURN_IF_ERROR(check_box_size(size));
  HC_ASSIGN_OR_RETURN(TetMesh mesh, tetrahedralize(box_surface(size), options, summary));
  mark_box_nodes(size, mesh);
  return mesh;
}

std::vector<int> nodes_with_marker(const TetMesh& mesh, int marker) {
  std::vector<int> out;
  for (std::size_t i = 0; i < mesh.node_markers.size(); ++i)
    if (mesh.node_markers[i] == marker) out.push_back(static_cast<int>(i));
  return out;
}

std::vector<int> nodes_on_plane(const TetMesh& mesh, int axis, double value, double tolerance) {
  std::vector<int> out;
  if (axis < 0 || axis > 2) return out;
  for (Eigen::Index i = 0; i < mesh.num_nodes(); ++i)
    if (std::abs(mesh.nodes(i, axis) - value) <= tolerance) out.push_back(static_cast<int>(i));
  return out;
}

double total_volume(const TetMesh& mesh) {
  double v = 0;
  for (Eigen::Index t = 0; t < mesh.num_tets(); ++t) v += tet_signed_volume(mesh, t);
  return v;
}

}  // namespace hc::meshing
