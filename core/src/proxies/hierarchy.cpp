// Sphere hierarchies over a sphere set (paper 004 section 6.3, "Construction and Animation").
#include "softgi/proxies/hierarchy.hpp"

#include <algorithm>
#include <cmath>
#include <functional>
#include <limits>
#include <random>
#include <stdexcept>
#include <string>

#include "detail.hpp"

namespace softgi::proxies {

namespace {
using glm::dvec3;

// Radius of the smallest sphere centred at c that contains every sphere in `members`.
double bounding_radius(const dvec3& c, const std::vector<scene::Sphere>& spheres, const std::vector<int>& members) {
  double r = 0.0;
  for (int m : members) r = std::max(r, glm::length(dvec3(spheres[m].center) - c) + spheres[m].radius);
  return r;
}

// A float sphere with centre c (rounded to float) that contains every member exactly.
scene::Sphere conservative_bound(const dvec3& c, const std::vector<scene::Sphere>& spheres, const std::vector<int>& members) {
  scene::Sphere s;
  s.center = glm::vec3(c);
  s.radius = detail::round_radius_up(bounding_radius(dvec3(s.center), spheres, members));
  return s;
}

// The cluster's bounding sphere: centre first the average of the member centres, then moved by
// Powell's method to minimise the bounding radius (paper 004 6.3). The radius, a maximum over the
// members, has ridges along which Powell's line searches stall (measured: up to 5% above the
// pairwise-merge bound), so Powell first runs on smooth log-sum-exp approximations of the maximum
// of increasing sharpness, then on the maximum itself; the pairwise-merge centre is a second start.
scene::Sphere fit_bound(const std::vector<scene::Sphere>& spheres, const std::vector<int>& members) {
  if (members.size() == 1) return spheres[members[0]];
  dvec3 mean(0.0);
  for (int m : members) mean += dvec3(spheres[m].center);
  mean /= static_cast<double>(members.size());
  scene::Sphere chain = spheres[members[0]];
  for (size_t k = 1; k < members.size(); ++k) chain = merge(chain, spheres[members[k]]);
  const double r_mean = bounding_radius(mean, spheres, members);
  const double r_chain = bounding_radius(dvec3(chain.center), spheres, members);
  const dvec3 start = r_mean <= r_chain ? mean : dvec3(chain.center);
  const double r0 = std::max(std::min(r_mean, r_chain), 1e-30);
  dvec3 c = start;
  std::vector<double> e(members.size());
  for (double sharp : {30.0, 300.0, 3000.0}) {
    const double beta = sharp / r0;
    auto soft = [&](const dvec3& x) {
      double m = 0.0;
      for (size_t k = 0; k < members.size(); ++k) {
        e[k] = glm::length(dvec3(spheres[members[k]].center) - x) + spheres[members[k]].radius;
        m = std::max(m, e[k]);
      }
      double sum = 0.0;
      for (double v : e) sum += std::exp(beta * (v - m));
      return m + std::log(sum) / beta;
    };
    c = detail::powell_minimize(soft, c, 2.5 * r0 / sharp * 3.0, 1e-10, 1e-4, 20, 3000).x;
  }
  c = detail::powell_minimize([&](const dvec3& x) { return bounding_radius(x, spheres, members); }, c, 1e-3 * r0, 1e-12,
                              1e-4, 10, 2000)
          .x;
  if (bounding_radius(c, spheres, members) > bounding_radius(start, spheres, members)) c = start;
  return conservative_bound(c, spheres, members);
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

SphereHierarchy SphereHierarchy::build(const std::vector<scene::Sphere>& leaves, int branching, unsigned seed) {
  if (leaves.empty()) throw std::invalid_argument("SphereHierarchy::build: no leaf spheres");
  if (branching < 2 || branching > 64)
    throw std::invalid_argument("SphereHierarchy::build: branching = " + std::to_string(branching) + " must be in [2, 64]");
  check_leaves(leaves, "SphereHierarchy::build");
  SphereHierarchy h;
  std::vector<int> level;  // node indices of the current level
  for (size_t i = 0; i < leaves.size(); ++i) {
    SphereNode n;
    n.bound = leaves[i];
    n.leaf = static_cast<int>(i);
    h.nodes_.push_back(n);
    level.push_back(static_cast<int>(i));
  }
  std::mt19937 rng(seed);
  while (level.size() > 1) {
    const int n = static_cast<int>(level.size());
    std::vector<scene::Sphere> spheres(n);
    for (int i = 0; i < n; ++i) spheres[i] = h.nodes_[level[i]].bound;
    // Number of clusters so that the average branching ratio is `branching` (paper: 4).
    const int k = std::max(1, static_cast<int>(std::lround(static_cast<double>(n) / branching)));
    std::vector<std::vector<int>> groups;
    if (k == 1) {
      groups.emplace_back();
      for (int i = 0; i < n; ++i) groups.back().push_back(i);
    } else {
      // Lloyd clustering: k-means++ seeds, assignment to the closest cluster centre, bounding sphere
      // update, until the assignment is stable.
      std::vector<dvec3> centre;
      std::vector<double> d2(n, std::numeric_limits<double>::infinity());
      centre.push_back(dvec3(spheres[std::uniform_int_distribution<int>(0, n - 1)(rng)].center));
      while (static_cast<int>(centre.size()) < k) {
        double total = 0.0;
        for (int i = 0; i < n; ++i) {
          const dvec3 d = dvec3(spheres[i].center) - centre.back();
          d2[i] = std::min(d2[i], glm::dot(d, d));
          total += d2[i];
        }
        if (!(total > 0.0)) break;  // fewer distinct centres than clusters
        double x = std::uniform_real_distribution<double>(0.0, total)(rng);
        int pick = n - 1;
        for (int i = 0; i < n; ++i) {
          x -= d2[i];
          if (x <= 0.0) {
            pick = i;
            break;
          }
        }
        centre.push_back(dvec3(spheres[pick].center));
      }
      std::vector<int> assign(n, -1);
      for (int iter = 0; iter < 50; ++iter) {
        bool changed = false;
        for (int i = 0; i < n; ++i) {
          int best = 0;
          double bd = std::numeric_limits<double>::infinity();
          for (size_t c = 0; c < centre.size(); ++c) {
            const dvec3 d = dvec3(spheres[i].center) - centre[c];
            const double dd = glm::dot(d, d);
            if (dd < bd) {
              bd = dd;
              best = static_cast<int>(c);
            }
          }
          if (assign[i] != best) {
            assign[i] = best;
            changed = true;
          }
        }
        groups.assign(centre.size(), {});
        for (int i = 0; i < n; ++i) groups[assign[i]].push_back(i);
        if (!changed && iter > 0) break;
        for (size_t c = 0; c < centre.size(); ++c)
          if (!groups[c].empty()) centre[c] = dvec3(fit_bound(spheres, groups[c]).center);
      }
      groups.erase(std::remove_if(groups.begin(), groups.end(), [](const auto& g) { return g.empty(); }), groups.end());
      if (groups.size() == static_cast<size_t>(n)) {  // no progress possible (all centres equal): one parent
        groups.assign(1, {});
        for (int i = 0; i < n; ++i) groups[0].push_back(i);
      }
    }
    std::vector<int> next;
    for (const std::vector<int>& g : groups) {
      if (g.size() == 1) {  // a single child is promoted, not wrapped
        next.push_back(level[g[0]]);
        continue;
      }
      SphereNode parent;
      parent.bound = fit_bound(spheres, g);
      const int id = static_cast<int>(h.nodes_.size());
      for (int i : g) {
        parent.children.push_back(level[i]);
        h.nodes_[level[i]].parent = id;
      }
      h.nodes_.push_back(parent);
      next.push_back(id);
    }
    level = std::move(next);
  }
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
