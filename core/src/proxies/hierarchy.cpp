// Sphere hierarchies over a sphere set (paper 004 section 6.3, "Construction and Animation").
#include "softgi/proxies/hierarchy.hpp"

#include <algorithm>
#include <cmath>
#include <functional>
#include <limits>
#include <stdexcept>
#include <string>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_invoke.h>

#include "detail.hpp"
#include "softgi/progress.hpp"

namespace softgi::proxies {

namespace {
using glm::dvec3;

// A member sphere in double precision, stored contiguously: every Powell evaluation reads them all.
struct Ball {
  dvec3 c;
  double r;
};

// Radius of the smallest sphere centred at x that contains every ball.
double max_reach(const dvec3& x, const std::vector<Ball>& balls) {
  double r = 0.0;
  for (const Ball& b : balls) r = std::max(r, glm::length(b.c - x) + b.r);
  return r;
}

// A float sphere with centre c (rounded to float) that contains every member exactly.
scene::Sphere conservative_bound(const dvec3& c, const std::vector<Ball>& balls) {
  scene::Sphere s;
  s.center = glm::vec3(c);
  s.radius = detail::round_radius_up(max_reach(dvec3(s.center), balls));
  return s;
}

// The cluster's bounding sphere: centre first the average of the member centres, then moved by
// Powell's method to minimise the bounding radius (paper 004 6.3). The radius, a maximum over the
// members, has ridges along which Powell's line searches stall (measured: up to 5% above the
// pairwise-merge bound), so Powell first runs on smooth log-sum-exp approximations of the maximum
// of increasing sharpness, then on the maximum itself; the pairwise-merge centre is a second start.
// `budget` bounds the evaluations over all four stages (a quarter each; a stage may overrun its
// share by one sweep), so a fit costs O(budget x members) whatever the members' layout; 0 keeps
// the better of the two starts.
scene::Sphere fit_bound(const std::vector<scene::Sphere>& spheres, const std::vector<int>& members, int budget) {
  if (members.size() == 1) return spheres[members[0]];
  std::vector<Ball> balls(members.size());
  dvec3 mean(0.0);
  for (size_t k = 0; k < members.size(); ++k) {
    balls[k] = {dvec3(spheres[members[k]].center), static_cast<double>(spheres[members[k]].radius)};
    mean += balls[k].c;
  }
  mean /= static_cast<double>(members.size());
  scene::Sphere chain = spheres[members[0]];
  for (size_t k = 1; k < members.size(); ++k) chain = merge(chain, spheres[members[k]]);
  const double r_mean = max_reach(mean, balls);
  const double r_chain = max_reach(dvec3(chain.center), balls);
  const dvec3 start = r_mean <= r_chain ? mean : dvec3(chain.center);
  const double r_start = std::min(r_mean, r_chain);
  if (budget == 0) return conservative_bound(start, balls);
  const double r0 = std::max(r_start, 1e-30);
  const int share = std::max(1, budget / 4);
  dvec3 c = start;
  std::vector<double> e(balls.size());
  for (double sharp : {30.0, 300.0, 3000.0}) {
    const double beta = sharp / r0;
    auto soft = [&](const dvec3& x) {
      double m = 0.0;
      for (size_t k = 0; k < balls.size(); ++k) {
        e[k] = glm::length(balls[k].c - x) + balls[k].r;
        m = std::max(m, e[k]);
      }
      double sum = 0.0;
      for (double v : e) sum += std::exp(beta * (v - m));
      return m + std::log(sum) / beta;
    };
    c = detail::powell_minimize(soft, c, 2.5 * r0 / sharp * 3.0, 1e-10, 1e-4, 20, share).x;
  }
  c = detail::powell_minimize([&](const dvec3& x) { return max_reach(x, balls); }, c, 1e-3 * r0, 1e-12, 1e-4, 10, share).x;
  if (max_reach(c, balls) > r_start) c = start;
  return conservative_bound(c, balls);
}

// Splits idx[lo, hi) into `parts` groups of (to within one) equal size by recursive median cuts
// across the longest axis of each range's bounding box: a k-d tree's leaves. Ties are broken by
// index, so coincident centres are shared out too.
void median_split(std::vector<int>& idx, size_t lo, size_t hi, int parts, const std::vector<dvec3>& p,
                  std::vector<std::vector<int>>& out) {
  if (parts <= 1 || hi - lo <= 1) {
    out.emplace_back(idx.begin() + static_cast<std::ptrdiff_t>(lo), idx.begin() + static_cast<std::ptrdiff_t>(hi));
    return;
  }
  dvec3 mn(std::numeric_limits<double>::infinity()), mx(-std::numeric_limits<double>::infinity());
  for (size_t i = lo; i < hi; ++i) {
    mn = glm::min(mn, p[idx[i]]);
    mx = glm::max(mx, p[idx[i]]);
  }
  const dvec3 ext = mx - mn;
  const int axis = ext.x >= ext.y && ext.x >= ext.z ? 0 : ext.y >= ext.z ? 1 : 2;
  const int left = parts / 2;
  const size_t mid = lo + (hi - lo) * static_cast<size_t>(left) / static_cast<size_t>(parts);
  std::nth_element(idx.begin() + static_cast<std::ptrdiff_t>(lo), idx.begin() + static_cast<std::ptrdiff_t>(mid),
                   idx.begin() + static_cast<std::ptrdiff_t>(hi),
                   [&](int a, int b) { return p[a][axis] < p[b][axis] || (p[a][axis] == p[b][axis] && a < b); });
  median_split(idx, lo, mid, left, p, out);
  median_split(idx, mid, hi, parts - left, p, out);
}

// A static k-d tree over the cluster centres (median splits along the widest axis, stored
// implicitly: the median of each index range is that node) for exact closest-centre queries in
// O(log k) instead of a scan over all k centres.
class CentreTree {
 public:
  CentreTree(const std::vector<dvec3>& centres, std::vector<int> ids) : c_(centres), ids_(std::move(ids)), axis_(ids_.size(), 0) {
    build(0, ids_.size());
  }
  // Lowers (best, best_d2) to the closest centre strictly closer than best_d2: on a tie the caller's
  // current cluster stays, so coincident centres keep the members they were given.
  void closest(const dvec3& q, int& best, double& best_d2) const { search(0, ids_.size(), q, best, best_d2); }

 private:
  void build(size_t lo, size_t hi) {
    if (hi - lo <= 1) return;
    dvec3 mn(std::numeric_limits<double>::infinity()), mx(-std::numeric_limits<double>::infinity());
    for (size_t i = lo; i < hi; ++i) {
      mn = glm::min(mn, c_[ids_[i]]);
      mx = glm::max(mx, c_[ids_[i]]);
    }
    const dvec3 ext = mx - mn;
    const int axis = ext.x >= ext.y && ext.x >= ext.z ? 0 : ext.y >= ext.z ? 1 : 2;
    const size_t mid = lo + (hi - lo) / 2;
    std::nth_element(ids_.begin() + static_cast<std::ptrdiff_t>(lo), ids_.begin() + static_cast<std::ptrdiff_t>(mid),
                     ids_.begin() + static_cast<std::ptrdiff_t>(hi),
                     [&](int a, int b) { return c_[a][axis] < c_[b][axis] || (c_[a][axis] == c_[b][axis] && a < b); });
    axis_[mid] = static_cast<unsigned char>(axis);
    if (hi - lo > 4096) {
      tbb::parallel_invoke([&] { build(lo, mid); }, [&] { build(mid + 1, hi); });
    } else {
      build(lo, mid);
      build(mid + 1, hi);
    }
  }
  void search(size_t lo, size_t hi, const dvec3& q, int& best, double& bd) const {
    while (lo < hi) {
      const size_t mid = lo + (hi - lo) / 2;
      const int id = ids_[mid];
      const dvec3 d = q - c_[id];
      const double d2 = glm::dot(d, d);
      if (d2 < bd) {
        bd = d2;
        best = id;
      }
      if (hi - lo == 1) return;
      const double off = d[axis_[mid]];
      // Near side first; the far side only if the splitting plane is closer than the best so far.
      const size_t nlo = off < 0.0 ? lo : mid + 1, nhi = off < 0.0 ? mid : hi;
      const size_t flo = off < 0.0 ? mid + 1 : lo, fhi = off < 0.0 ? hi : mid;
      search(nlo, nhi, q, best, bd);
      if (!(off * off < bd)) return;
      lo = flo;
      hi = fhi;
    }
  }

  const std::vector<dvec3>& c_;
  std::vector<int> ids_;
  std::vector<unsigned char> axis_;
};

// One level of the paper's construction: Lloyd clustering of `spheres` into about n / branching
// clusters. Seeds: a k-d split of the centres into groups of `branching` (O(n log n), where
// k-means++ seeding costs O(n k)). Each iteration assigns every sphere to the closest cluster
// centre (distance between centres, found in the centre k-d tree) and refits the bounding sphere
// of every cluster whose members changed; centres are those bounding spheres' centres. Returns the
// member lists (sphere indices in increasing order) and each cluster's bounding sphere.
struct Clustering {
  std::vector<std::vector<int>> groups;
  std::vector<scene::Sphere> bounds;
};

Clustering lloyd_level(const std::vector<scene::Sphere>& spheres, const HierarchyBuildOptions& opt, int max_children,
                       const std::function<void(double)>& on_iteration) {
  const int n = static_cast<int>(spheres.size());
  const int k = std::max(1, static_cast<int>(std::lround(static_cast<double>(n) / opt.branching)));
  std::vector<dvec3> p(n);
  for (int i = 0; i < n; ++i) p[i] = dvec3(spheres[i].center);
  std::vector<int> idx(n);
  for (int i = 0; i < n; ++i) idx[i] = i;
  Clustering cl;
  median_split(idx, 0, idx.size(), k, p, cl.groups);
  for (auto& g : cl.groups) std::sort(g.begin(), g.end());
  const int K = static_cast<int>(cl.groups.size());
  std::vector<int> assign(n);
  for (int c = 0; c < K; ++c)
    for (int i : cl.groups[c]) assign[i] = c;
  cl.bounds.assign(K, scene::Sphere{});
  std::vector<dvec3> centre(K);
  std::vector<char> dirty(K, 1);
  // Clusters whose centre moved in the last refit: only those can have come closer to a sphere.
  std::vector<char> moved(K, 1);
  auto refit = [&] {
    std::vector<int> todo;
    for (int c = 0; c < K; ++c)
      if (dirty[c] && !cl.groups[c].empty()) todo.push_back(c);
    std::fill(moved.begin(), moved.end(), 0);
    tbb::parallel_for(tbb::blocked_range<size_t>(0, todo.size(), 8), [&](const tbb::blocked_range<size_t>& r) {
      for (size_t t = r.begin(); t < r.end(); ++t) {
        const int c = todo[t];
        cl.bounds[c] = fit_bound(spheres, cl.groups[c], opt.fit_evaluations);
        const dvec3 now(cl.bounds[c].center);
        moved[c] = now != centre[c];
        centre[c] = now;
      }
    });
    std::fill(dirty.begin(), dirty.end(), 0);
  };
  // Initial centres: the member closest to each seed group's mean, so every cluster starts with at
  // least that member.
  for (int c = 0; c < K; ++c) {
    dvec3 mean(0.0);
    for (int i : cl.groups[c]) mean += p[i];
    mean /= static_cast<double>(cl.groups[c].size());
    double bd = std::numeric_limits<double>::infinity();
    for (int i : cl.groups[c]) {
      const double d2 = glm::dot(p[i] - mean, p[i] - mean);
      if (d2 < bd) {
        bd = d2;
        centre[c] = p[i];
      }
    }
  }
  if (K > 1) {
    std::vector<int> next(n);
    for (int iter = 0; iter < opt.lloyd_iterations; ++iter) {
      // A sphere was closest to its own centre at the last assignment (ties kept). If that centre
      // stayed, only a centre that moved can now be strictly closer, so such spheres search the
      // moved centres alone; once few clusters change, that tree is small.
      std::vector<int> live, live_moved;
      for (int c = 0; c < K; ++c)
        if (!cl.groups[c].empty()) {
          live.push_back(c);
          if (moved[c]) live_moved.push_back(c);
        }
      if (live_moved.empty()) break;
      const CentreTree all(centre, std::move(live)), recent(centre, std::move(live_moved));
      tbb::parallel_for(tbb::blocked_range<int>(0, n, 256), [&](const tbb::blocked_range<int>& r) {
        for (int i = r.begin(); i < r.end(); ++i) {
          int best = assign[i];
          const dvec3 d = p[i] - centre[best];
          double bd = glm::dot(d, d);
          (moved[best] ? all : recent).closest(p[i], best, bd);
          next[i] = best;
        }
      });
      bool changed = false;
      for (int i = 0; i < n; ++i)
        if (next[i] != assign[i]) {
          dirty[assign[i]] = dirty[next[i]] = 1;
          assign[i] = next[i];
          changed = true;
        }
      int changed_clusters = 0;
      for (int c = 0; c < K; ++c) changed_clusters += dirty[c];
      if (!changed) break;
      for (int c = 0; c < K; ++c)
        if (dirty[c]) cl.groups[c].clear();
      for (int i = 0; i < n; ++i)
        if (dirty[assign[i]]) cl.groups[assign[i]].push_back(i);
      refit();
      // Lloyd converges as fewer clusters change: the level's share done, for the progress line.
      if (on_iteration) on_iteration(1.0 - static_cast<double>(changed_clusters) / K);
    }
  }
  refit();
  // Empty clusters go; a cluster above max_children (coincident centres all share one closest
  // cluster) is split in space like the seeds.
  Clustering out;
  for (int c = 0; c < K; ++c) {
    std::vector<int>& g = cl.groups[c];
    if (g.empty()) continue;
    if (static_cast<int>(g.size()) <= max_children) {
      out.groups.push_back(std::move(g));
      out.bounds.push_back(cl.bounds[c]);
      continue;
    }
    const int parts = static_cast<int>((g.size() + opt.branching - 1) / opt.branching);
    const size_t first = out.groups.size();
    median_split(g, 0, g.size(), parts, p, out.groups);
    for (size_t s = first; s < out.groups.size(); ++s) {
      std::sort(out.groups[s].begin(), out.groups[s].end());
      out.bounds.push_back(fit_bound(spheres, out.groups[s], opt.fit_evaluations));
    }
  }
  return out;
}

void check_options(const HierarchyBuildOptions& o) {
  auto bad = [](const char* what, int v, const char* range) {
    throw std::invalid_argument(std::string("SphereHierarchy::build: ") + what + " = " + std::to_string(v) + " must be " + range);
  };
  if (o.branching < 2 || o.branching > 64) bad("branching", o.branching, "in [2, 64]");
  if (o.max_children != 0 && (o.max_children < 2 * o.branching || o.max_children > 100000))
    bad("max_children", o.max_children, "0 or in [2 x branching, 100000]");
  if (o.lloyd_iterations < 1 || o.lloyd_iterations > 1000) bad("lloyd_iterations", o.lloyd_iterations, "in [1, 1000]");
  if (o.fit_evaluations != 0 && (o.fit_evaluations < 100 || o.fit_evaluations > 100000))
    bad("fit_evaluations", o.fit_evaluations, "0 or in [100, 100000]");
}

void check_leaves(const std::vector<scene::Sphere>& leaves, const char* who) {
  for (size_t i = 0; i < leaves.size(); ++i) {
    const scene::Sphere& s = leaves[i];
    if (!std::isfinite(s.center.x) || !std::isfinite(s.center.y) || !std::isfinite(s.center.z) || !std::isfinite(s.radius) ||
        s.radius < 0.0f)
      throw std::invalid_argument(std::string(who) + ": leaf sphere " + std::to_string(i) + " has centre (" +
                                  std::to_string(s.center.x) + ", " + std::to_string(s.center.y) + ", " +
                                  std::to_string(s.center.z) + ") and radius " + std::to_string(s.radius) +
                                  "; expected finite values and radius >= 0");
  }
}
}  // namespace

scene::Sphere merge(const scene::Sphere& a, const scene::Sphere& b) {
  const dvec3 ca(a.center), cb(b.center);
  const double ra = a.radius, rb = b.radius;
  const double d = glm::length(cb - ca);
  if (d + rb <= ra) return a;
  if (d + ra <= rb) return b;
  const double R = 0.5 * (d + ra + rb);
  const dvec3 c = ca + (cb - ca) * ((R - ra) / d);
  scene::Sphere s;
  s.center = glm::vec3(c);
  const dvec3 cf(s.center);
  s.radius = detail::round_radius_up(std::max(glm::length(ca - cf) + ra, glm::length(cb - cf) + rb));
  return s;
}

SphereHierarchy SphereHierarchy::build(const std::vector<scene::Sphere>& leaves, int branching) {
  HierarchyBuildOptions o;
  o.branching = branching;
  return build(leaves, o);
}

SphereHierarchy SphereHierarchy::build(const std::vector<scene::Sphere>& leaves, const HierarchyBuildOptions& options) {
  if (leaves.empty()) throw std::invalid_argument("SphereHierarchy::build: no leaf spheres");
  check_options(options);
  check_leaves(leaves, "SphereHierarchy::build");
  const int max_children = options.max_children > 0 ? options.max_children : 4 * options.branching;
  SphereHierarchy h;
  std::vector<int> level;  // node indices of the current level
  h.nodes_.reserve(leaves.size() + leaves.size() / std::max(1, options.branching - 1) + 1);
  for (size_t i = 0; i < leaves.size(); ++i) {
    SphereNode n;
    n.bound = leaves[i];
    n.leaf = static_cast<int>(i);
    h.nodes_.push_back(n);
    level.push_back(static_cast<int>(i));
  }
  // Work of a level ~ its node count; the levels shrink geometrically by `branching`.
  const double total = static_cast<double>(leaves.size()) * options.branching / (options.branching - 1);
  double done = 0.0;
  Progress progress("sphere hierarchy over " + std::to_string(leaves.size()) + " spheres");
  while (level.size() > 1) {
    const int n = static_cast<int>(level.size());
    std::vector<scene::Sphere> spheres(n);
    for (int i = 0; i < n; ++i) spheres[i] = h.nodes_[level[i]].bound;
    const Clustering cl =
        lloyd_level(spheres, options, max_children, [&](double f) { progress.update((done + n * std::min(f, 1.0)) / total); });
    // Lloyd gives at most k = round(n / branching) < n clusters, and splitting a cluster of m >
    // 2 x branching members gives ceil(m / branching) < m groups: every level shrinks.
    if (cl.groups.size() >= static_cast<size_t>(n))
      throw std::logic_error("SphereHierarchy::build: a level of " + std::to_string(n) + " nodes did not shrink");
    std::vector<int> next;
    for (size_t g = 0; g < cl.groups.size(); ++g) {
      const std::vector<int>& members = cl.groups[g];
      if (members.size() == 1) {  // a single child is promoted, not wrapped
        next.push_back(level[members[0]]);
        continue;
      }
      SphereNode parent;
      parent.bound = cl.bounds[g];
      const int id = static_cast<int>(h.nodes_.size());
      for (int i : members) {
        parent.children.push_back(level[i]);
        h.nodes_[level[i]].parent = id;
      }
      h.nodes_.push_back(std::move(parent));
      next.push_back(id);
    }
    level = std::move(next);
    done += n;
    progress.update(done / total);
  }
  progress.done();
  h.root_ = level[0];
  return h;
}

void SphereHierarchy::update(const std::vector<scene::Sphere>& leaves) {
  int count = 0;
  for (const SphereNode& n : nodes_) count += n.leaf >= 0;
  if (static_cast<int>(leaves.size()) != count)
    throw std::invalid_argument("SphereHierarchy::update: " + std::to_string(leaves.size()) +
                                " leaves given, the hierarchy was built over " + std::to_string(count));
  check_leaves(leaves, "SphereHierarchy::update");
  // Nodes are stored children first, so one pass in index order is bottom-up.
  for (SphereNode& n : nodes_) {
    if (n.leaf >= 0) {
      n.bound = leaves[n.leaf];
      continue;
    }
    scene::Sphere b = nodes_[n.children[0]].bound;
    for (size_t c = 1; c < n.children.size(); ++c) b = merge(b, nodes_[n.children[c]].bound);
    n.bound = b;
  }
}

int SphereHierarchy::depth() const {
  if (root_ < 0) return 0;
  int best = 0;
  std::vector<std::pair<int, int>> stack{{root_, 1}};
  while (!stack.empty()) {
    auto [id, d] = stack.back();
    stack.pop_back();
    best = std::max(best, d);
    for (int c : nodes_[id].children) stack.emplace_back(c, d + 1);
  }
  return best;
}

double SphereHierarchy::average_branching() const {
  int internal = 0, edges = 0;
  for (const SphereNode& n : nodes_)
    if (!n.children.empty()) {
      ++internal;
      edges += static_cast<int>(n.children.size());
    }
  return internal > 0 ? static_cast<double>(edges) / internal : 0.0;
}

bool SphereHierarchy::bounds_are_conservative() const {
  // For every internal node, every leaf below it must lie inside its bound.
  for (const SphereNode& n : nodes_) {
    if (n.children.empty()) continue;
    const dvec3 c(n.bound.center);
    const double tol = 1e-5 * std::max(static_cast<double>(n.bound.radius), 1e-30);
    std::vector<int> stack(n.children.begin(), n.children.end());
    while (!stack.empty()) {
      const SphereNode& m = nodes_[stack.back()];
      stack.pop_back();
      if (m.leaf >= 0) {
        if (glm::length(dvec3(m.bound.center) - c) + m.bound.radius > n.bound.radius + tol) return false;
      } else {
        stack.insert(stack.end(), m.children.begin(), m.children.end());
      }
    }
  }
  return true;
}

}  // namespace softgi::proxies
