#include "fabrication/composite/design.h"

#include <fmt/format.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <functional>
#include <limits>
#include <map>
#include <mutex>
#include <random>
#include <set>

#include "common/clock.h"

namespace hc::composite {
namespace {

using Clock = std::chrono::steady_clock;

// Lloyd iterations of the per-level K-means (converges in a handful on a few hundred nodes).
constexpr int kKMeansIterations = 20;

struct Scored {
  double screen = 0;
  std::vector<int> design;
};

// K-means (k-means++ start, fixed seed) of the rows of `x`; returns for each cluster the row
// nearest its centroid.
std::vector<int> kmeans_representatives(const Eigen::MatrixXd& x, int k) {
  const Eigen::Index n = x.rows();
  std::mt19937_64 rng(12345);
  Eigen::MatrixXd centres(k, x.cols());
  std::vector<double> d2(static_cast<std::size_t>(n), std::numeric_limits<double>::infinity());
  centres.row(0) = x.row(std::uniform_int_distribution<Eigen::Index>(0, n - 1)(rng));
  for (int c = 1; c < k; ++c) {
    double total = 0;
    for (Eigen::Index i = 0; i < n; ++i) {
      d2[static_cast<std::size_t>(i)] =
          std::min(d2[static_cast<std::size_t>(i)], (x.row(i) - centres.row(c - 1)).squaredNorm());
      total += d2[static_cast<std::size_t>(i)];
    }
    double pick = std::uniform_real_distribution<double>(0, total)(rng);
    Eigen::Index chosen = n - 1;
    for (Eigen::Index i = 0; i < n; ++i) {
      pick -= d2[static_cast<std::size_t>(i)];
      if (pick <= 0) {
        chosen = i;
        break;
      }
    }
    centres.row(c) = x.row(chosen);
  }
  std::vector<int> label(static_cast<std::size_t>(n), 0);
  for (int it = 0; it < kKMeansIterations; ++it) {
    bool changed = false;
    for (Eigen::Index i = 0; i < n; ++i) {
      Eigen::Index best = 0;
      (centres.rowwise() - x.row(i)).rowwise().squaredNorm().minCoeff(&best);
      changed = changed || label[static_cast<std::size_t>(i)] != static_cast<int>(best);
      label[static_cast<std::size_t>(i)] = static_cast<int>(best);
    }
    Eigen::MatrixXd sum = Eigen::MatrixXd::Zero(k, x.cols());
    std::vector<int> count(static_cast<std::size_t>(k), 0);
    for (Eigen::Index i = 0; i < n; ++i) {
      sum.row(label[static_cast<std::size_t>(i)]) += x.row(i);
      ++count[static_cast<std::size_t>(label[static_cast<std::size_t>(i)])];
    }
    for (int c = 0; c < k; ++c)
      if (count[static_cast<std::size_t>(c)] > 0) centres.row(c) = sum.row(c) / count[static_cast<std::size_t>(c)];
    if (!changed && it > 0) break;
  }
  std::vector<int> reps;
  for (int c = 0; c < k; ++c) {
    Eigen::Index best = -1;
    double bd = std::numeric_limits<double>::infinity();
    for (Eigen::Index i = 0; i < n; ++i) {
      if (label[static_cast<std::size_t>(i)] != c) continue;
      const double d = (x.row(i) - centres.row(c)).squaredNorm();
      if (d < bd) {
        bd = d;
        best = i;
      }
    }
    if (best >= 0) reps.push_back(static_cast<int>(best));
  }
  return reps;
}

}  // namespace

Status SearchOptions::validate() const {
  if (clusters < 1) return invalid_argument(fmt::format("clusters must be >= 1, got {}", clusters));
  if (simulate_best < 1) return invalid_argument("simulate_best must be >= 1");
  if (!(margin >= 1)) return invalid_argument(fmt::format("margin must be >= 1, got {}", margin));
  if (min_simulated < 1 || max_simulated < min_simulated)
    return invalid_argument("need 1 <= min_simulated <= max_simulated");
  if (!(max_designs >= 1)) return invalid_argument("max_designs must be >= 1");
  if (!(zero_error_m >= 0)) return invalid_argument("zero_error_m must be >= 0");
  return {};
}

std::vector<int> search_order(const CellGrid& grid) {
  std::vector<int> order(static_cast<std::size_t>(grid.num_cells()));
  for (int c = 0; c < grid.num_cells(); ++c) order[static_cast<std::size_t>(c)] = grid.num_cells() - 1 - c;
  return order;
}

// The decisions of a search: `levels` of them, each choosing one of options(prefix) values; a
// prefix of decisions and a fill material give a design of the cells (the uniform completion).
struct DecisionSpace {
  int levels = 0;
  std::function<int(const std::vector<int>& prefix)> options;
  std::function<std::vector<int>(const std::vector<int>& prefix, int fill)> design;
};

// Number of complete decision sequences.
double count_designs(const DecisionSpace& space, const std::vector<int>& prefix = {}) {
  if (static_cast<int>(prefix.size()) == space.levels) return 1;
  double total = 0;
  std::vector<int> next = prefix;
  next.push_back(0);
  for (int j = 0; j < space.options(prefix); ++j) {
    next.back() = j;
    total += count_designs(space, next);
  }
  return total;
}

// Visits the cell design of every complete decision sequence.
void walk_designs(const DecisionSpace& space, std::vector<int> prefix,
                  const std::function<void(const std::vector<int>&)>& visit) {
  if (static_cast<int>(prefix.size()) == space.levels) {
    visit(space.design(prefix, 0));
    return;
  }
  const int options = space.options(prefix);
  prefix.push_back(0);
  for (int j = 0; j < options; ++j) {
    prefix.back() = j;
    walk_designs(space, prefix, visit);
  }
}

struct CompositeDesigner::Impl {
  const material::Samples* target = nullptr;
  CellGrid grid;
  std::vector<BaseMaterial> library;
  std::vector<int> element_cell;
  Screen screen;
  ExampleSimulator simulator;
  double max_displacement_m = 0;

  Result<std::vector<MatrixX3d>> simulate(const std::vector<int>& design, double* rms_m) {
    HC_ASSIGN_OR_RETURN(const CompositeMaterial material,
                        make_composite(library, element_cell, design, grid.num_cells()));
    const std::size_t n = simulator.num_examples();
    std::vector<MatrixX3d> out(n);
    std::vector<Status> st(n);
    // Examples use separate FEMs: safe in parallel.
    tbb::parallel_for(std::size_t{0}, n, [&](std::size_t i) {
      Result<MatrixX3d> x = simulator.simulate(i, material);
      if (x.ok())
        out[i] = std::move(x).value();
      else
        st[i] = x.status();
    });
    for (const Status& s : st) HC_RETURN_IF_ERROR(s);
    if (rms_m != nullptr) {
      double sum = 0;
      Eigen::Index nodes = 0;
      for (std::size_t i = 0; i < n; ++i) {
        const ExampleError e = example_error(target->examples[i], out[i]);
        sum += e.sum_sq_m2;
        nodes += e.nodes;
      }
      *rms_m = nodes > 0 ? std::sqrt(sum / static_cast<double>(nodes)) : 0.0;
    }
    return out;
  }

  Result<DesignResult> branch_and_bound(const SearchOptions& o, const DecisionSpace& space);
  Status simulate_best(const std::vector<Scored>& ranked, int count, DesignResult* r);
  Result<DesignResult> exact(const SearchOptions& o, const DecisionSpace* space = nullptr);
};

CompositeDesigner::CompositeDesigner(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
CompositeDesigner::CompositeDesigner(CompositeDesigner&&) noexcept = default;
CompositeDesigner& CompositeDesigner::operator=(CompositeDesigner&&) noexcept = default;
CompositeDesigner::~CompositeDesigner() = default;

Result<CompositeDesigner> CompositeDesigner::create(const material::Samples& target,
                                                    const CellGrid& grid,
                                                    std::vector<BaseMaterial> library,
                                                    const ScreenOptions& screen) {
  if (library.empty()) return invalid_argument("design: the library lists no base materials");
  HC_ASSIGN_OR_RETURN(Screen s, Screen::create(target, grid, library, screen));
  HC_ASSIGN_OR_RETURN(ExampleSimulator sim, ExampleSimulator::create(target, screen.forward));
  auto impl = std::unique_ptr<Impl>(new Impl{&target, grid, std::move(library),
                                             element_cells(target.mesh, grid), std::move(s),
                                             std::move(sim), target.max_displacement_m()});
  return CompositeDesigner(std::move(impl));
}

Status CompositeDesigner::set_target(const material::Samples& target) {
  HC_RETURN_IF_ERROR(impl_->screen.set_target(target));
  impl_->target = &target;
  impl_->max_displacement_m = target.max_displacement_m();
  return {};
}

Result<DesignResult> CompositeDesigner::search_layers(int layers, const SearchOptions& options) {
  HC_RETURN_IF_ERROR(options.validate());
  const CellGrid& g = impl_->grid;
  const int s = g.num_cells();
  if (!g.is_layers())
    return invalid_argument("thickness search: the cells must be a stack of sublayers");
  if (layers < 1 || layers > s)
    return invalid_argument(fmt::format(
        "thickness search: {} layers do not fit {} sublayers (each layer needs at least one)",
        layers, s));
  const auto t0 = Clock::now();
  const int m = static_cast<int>(impl_->library.size());
  // Decision l (top layer first): material + m (thickness - 1), thickness in sublayers; every
  // layer below needs at least one sublayer, and the last takes what is left.
  const auto used = [m](const std::vector<int>& prefix) {
    int u = 0;
    for (int d : prefix) u += d / m + 1;
    return u;
  };
  DecisionSpace space;
  space.levels = layers;
  space.options = [=](const std::vector<int>& prefix) {
    const int left = s - used(prefix);
    const int after = layers - static_cast<int>(prefix.size()) - 1;
    if (after == 0) return left >= 1 ? m : 0;  // the bottom layer takes the rest (encoded below)
    return m * std::max(0, left - after);
  };
  space.design = [=](const std::vector<int>& prefix, int fill) {
    std::vector<int> d(static_cast<std::size_t>(s), fill);
    int top = s;  // sublayers are numbered bottom first; decisions start at the top
    for (std::size_t l = 0; l < prefix.size(); ++l) {
      const bool last = static_cast<int>(l) + 1 == layers;
      const int thickness = last ? top : prefix[l] / m + 1;
      for (int k = 0; k < thickness && top > 0; ++k) d[static_cast<std::size_t>(--top)] = prefix[l] % m;
    }
    return d;
  };
  DesignResult r;
  if (options.mode == SearchMode::kExact) {
    HC_ASSIGN_OR_RETURN(r, impl_->exact(options, &space));
  } else {
    HC_ASSIGN_OR_RETURN(r, impl_->branch_and_bound(options, space));
  }
  r.time_s = seconds_since(t0);
  return r;
}

const Screen& CompositeDesigner::screen() const { return impl_->screen; }
const CellGrid& CompositeDesigner::grid() const { return impl_->grid; }
double CompositeDesigner::setup_time_s() const { return impl_->screen.setup_time_s(); }

Result<std::vector<MatrixX3d>> CompositeDesigner::simulate(const std::vector<int>& design,
                                                           double* rms_m) {
  return impl_->simulate(design, rms_m);
}

Result<DesignResult> CompositeDesigner::search(const SearchOptions& options) {
  HC_RETURN_IF_ERROR(options.validate());
  const auto t0 = Clock::now();
  DesignResult r;
  if (options.mode == SearchMode::kExact) {
    HC_ASSIGN_OR_RETURN(r, impl_->exact(options));
  } else {
    // One decision per cell in search order, each a material.
    const std::vector<int> order = search_order(impl_->grid);
    const int m = static_cast<int>(impl_->library.size());
    DecisionSpace space;
    space.levels = impl_->grid.num_cells();
    space.options = [m](const std::vector<int>&) { return m; };
    space.design = [&order](const std::vector<int>& prefix, int fill) {
      std::vector<int> d(order.size(), fill);
      for (std::size_t l = 0; l < prefix.size(); ++l) d[static_cast<std::size_t>(order[l])] = prefix[l];
      return d;
    };
    HC_ASSIGN_OR_RETURN(r, impl_->branch_and_bound(options, space));
  }
  r.time_s = seconds_since(t0);
  return r;
}

Result<DesignResult> CompositeDesigner::Impl::branch_and_bound(const SearchOptions& o,
                                                               const DecisionSpace& space) {
  const auto t0 = Clock::now();
  const int m = static_cast<int>(library.size());
  const Eigen::VectorXd& t = screen.target_displacements();
  const double nodes = static_cast<double>(std::max<Eigen::Index>(screen.measured_nodes(), 1));
  struct Eval {
    double error;
    Eigen::VectorXd z;  // displacements at the measured coordinates (the bounds' boxes)
    Eigen::VectorXd w;  // short coordinates with Eq. 5.5's distances (the clustering)
  };
  std::map<std::vector<int>, Eval> cache;
  double best_error = std::numeric_limits<double>::infinity();
  const auto eval = [&](const std::vector<int>& d) -> const Eval& {
    auto it = cache.find(d);
    if (it == cache.end()) {
      Eval e;
      screen.evaluate(d, &e.error, &e.z, &e.w);
      best_error = std::min(best_error, e.error);
      it = cache.emplace(d, std::move(e)).first;
    }
    return it->second;
  };
  std::vector<std::vector<int>> level_nodes{{}};
  if (o.progress) o.progress->begin("branch and bound", static_cast<std::uint64_t>(space.levels));
  for (int level = 0; level < space.levels && !level_nodes.empty(); ++level) {
    // Bounds from the uniform completions (Sec. 5.5.3), cull, cluster (Sec. 5.5.4), split.
    std::vector<std::vector<int>> kept;
    std::vector<Eigen::VectorXd> features;
    for (const std::vector<int>& node : level_nodes) {
      Eigen::VectorXd lo, hi, feature;
      for (int j = 0; j < m; ++j) {
        const Eval& e = eval(space.design(node, j));
        lo = j == 0 ? e.z : lo.cwiseMin(e.z).eval();
        hi = j == 0 ? e.z : hi.cwiseMax(e.z).eval();
        if (j == 0) feature.resize(m * e.w.size());
        feature.segment(j * e.w.size(), e.w.size()) = e.w;
      }
      const double dist =
          std::sqrt(((lo - t).cwiseMax(0.0) + (t - hi).cwiseMax(0.0)).squaredNorm() / nodes);
      if (dist > best_error) continue;  // culled (the thesis's "dist < d_min" keeps the rest)
      kept.push_back(node);
      features.push_back(std::move(feature));
    }
    std::vector<int> reps(kept.size());
    for (std::size_t i = 0; i < kept.size(); ++i) reps[i] = static_cast<int>(i);
    if (static_cast<int>(kept.size()) > o.clusters) {
      Eigen::MatrixXd x(static_cast<Eigen::Index>(kept.size()), features.front().size());
      for (std::size_t i = 0; i < kept.size(); ++i)
        x.row(static_cast<Eigen::Index>(i)) = features[i].transpose();
      reps = kmeans_representatives(x, o.clusters);
    }
    std::vector<std::vector<int>> children;
    for (int r : reps) {
      const std::vector<int>& parent = kept[static_cast<std::size_t>(r)];
      const int options = space.options(parent);
      for (int j = 0; j < options; ++j) {
        std::vector<int> child = parent;
        child.push_back(j);
        children.push_back(std::move(child));
      }
    }
    level_nodes = std::move(children);
    if (o.progress) o.progress->update(static_cast<std::uint64_t>(level) + 1);
  }
  for (const std::vector<int>& leaf : level_nodes) eval(space.design(leaf, 0));
  if (o.progress) o.progress->end("");
  DesignResult r;
  r.designs_screened = static_cast<long long>(cache.size());
  r.search_time_s = seconds_since(t0);
  std::vector<Scored> ranked;
  for (const auto& [d, e] : cache) ranked.push_back({e.error, d});
  std::sort(ranked.begin(), ranked.end(),
            [](const Scored& a, const Scored& b) { return a.screen < b.screen; });
  HC_RETURN_IF_ERROR(simulate_best(ranked, o.simulate_best, &r));
  r.gap_m = std::numeric_limits<double>::quiet_NaN();  // the thesis's B&B gives no bound
  return r;
}

Status CompositeDesigner::Impl::simulate_best(const std::vector<Scored>& ranked, int count,
                                             DesignResult* r) {
  const auto t1 = Clock::now();
  r->rms_error_m = std::numeric_limits<double>::infinity();
  for (int k = 0; k < std::min<int>(count, static_cast<int>(ranked.size())); ++k) {
    const Scored& c = ranked[static_cast<std::size_t>(k)];
    double full = 0;
    HC_RETURN_IF_ERROR(simulate(c.design, &full).status());
    ++r->designs_simulated;
    r->max_screen_discrepancy_m = std::max(r->max_screen_discrepancy_m, std::abs(full - c.screen));
    if (full < r->rms_error_m) {
      r->rms_error_m = full;
      r->design = c.design;
      r->screen_error_m = c.screen;
    }
  }
  r->simulate_time_s = seconds_since(t1);
  return {};
}

Result<DesignResult> CompositeDesigner::Impl::exact(const SearchOptions& o,
                                                    const DecisionSpace* space) {
  const int n = grid.num_cells();
  const int m = static_cast<int>(library.size());
  const double count = space != nullptr ? count_designs(*space) : std::pow(static_cast<double>(m), n);
  if (count > o.max_designs)
    return invalid_argument(fmt::format(
        "exact search: {} materials in {} cells are {:.4g} designs, more than the {:.4g} it "
        "enumerates (use --search bnb, fewer cells or fewer materials)",
        m, n, count, o.max_designs));
  const auto t0 = Clock::now();
  // Keep the max_simulated + 1 best screened designs (the extra one bounds all others).
  const std::size_t keep = static_cast<std::size_t>(o.max_simulated) + 1;
  std::mutex mutex;
  std::vector<Scored> best;  // max-heap on the screened error
  const auto worse = [](const Scored& a, const Scored& b) { return a.screen < b.screen; };
  if (o.progress) o.progress->begin("exact: screen every design", 0);
  const auto visit = [&](const std::vector<int>& d, double e) {
    std::lock_guard<std::mutex> lock(mutex);
    if (best.size() < keep) {
      best.push_back({e, d});
      std::push_heap(best.begin(), best.end(), worse);
    } else if (e < best.front().screen) {
      std::pop_heap(best.begin(), best.end(), worse);
      best.back() = {e, d};
      std::push_heap(best.begin(), best.end(), worse);
    }
  };
  if (space == nullptr)
    screen.enumerate(search_order(grid), visit);
  else
    walk_designs(*space, {}, [&](const std::vector<int>& d) { visit(d, screen.error(d)); });
  if (o.progress) o.progress->end("");
  std::sort_heap(best.begin(), best.end(), worse);
  DesignResult r;
  r.designs_screened = static_cast<long long>(count);
  r.search_time_s = seconds_since(t0);
  const auto t1 = Clock::now();
  const double zero = o.zero_error_m > 0 ? o.zero_error_m : 1e-9 * max_displacement_m;
  r.rms_error_m = std::numeric_limits<double>::infinity();
  double delta = 0;
  std::size_t k = 0;
  std::set<std::vector<int>> simulated;  // decision spaces may reach a design more than once
  for (; k < best.size() && k < static_cast<std::size_t>(o.max_simulated); ++k) {
    if (!simulated.insert(best[k].design).second) continue;
    if (r.rms_error_m <= zero) {
      r.certified = true;
      r.certificate = "zero_error";
      break;
    }
    if (static_cast<int>(k) >= o.min_simulated && best[k].screen - o.margin * delta >= r.rms_error_m) {
      r.certified = true;
      r.certificate = "screen_bound";
      break;
    }
    double full = 0;
    HC_RETURN_IF_ERROR(simulate(best[k].design, &full).status());
    ++r.designs_simulated;
    delta = std::max(delta, std::abs(full - best[k].screen));
    if (full < r.rms_error_m) {
      r.rms_error_m = full;
      r.design = best[k].design;
      r.screen_error_m = best[k].screen;
    }
  }
  if (!r.certified && r.rms_error_m <= zero) {
    r.certified = true;
    r.certificate = "zero_error";
  } else if (!r.certified && k >= best.size() && static_cast<double>(best.size()) >= count) {
    r.certified = true;  // every design was simulated in full
    r.certificate = "exhaustive";
  } else if (!r.certified && k < best.size() && static_cast<int>(k) >= o.min_simulated &&
             best[k].screen - o.margin * delta >= r.rms_error_m) {
    r.certified = true;
    r.certificate = "screen_bound";
  }
  r.max_screen_discrepancy_m = delta;
  r.screen_bound_m = o.margin * delta;
  if (!r.certified) {
    // Every design not simulated has screened error >= best[k].screen.
    const double lower = k < best.size() ? best[k].screen - r.screen_bound_m : r.rms_error_m;
    r.gap_m = std::max(0.0, r.rms_error_m - lower);
  }
  r.simulate_time_s = seconds_since(t1);
  return r;
}

}  // namespace hc::composite
