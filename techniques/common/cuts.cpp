// Sphere-hierarchy cuts with ratio vectors (paper 004 section 6.3, eqs. 36-37).
#include "cuts.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <stdexcept>
#include <string>

#include "softgi/sh/sh.hpp"

namespace softgi::techniques::common {

double ClusterCuts::mean_size() const {
  double sum = 0.0;
  for (const int l : list_of_cluster) sum += static_cast<double>(lists[static_cast<std::size_t>(l)].size());
  return list_of_cluster.empty() ? 0.0 : sum / static_cast<double>(list_of_cluster.size());
}

std::size_t ClusterCuts::max_size() const {
  std::size_t mx = 0;
  for (const int l : list_of_cluster) mx = std::max(mx, lists[static_cast<std::size_t>(l)].size());
  return mx;
}

BlockerList flat_list(const std::vector<std::vector<scene::Sphere>>& sets, int order) {
  BlockerList b;
  b.order = order;
  for (const auto& set : sets)
    for (const auto& s : set)
      if (s.radius > 0.0f) b.push(s.center, s.radius, nullptr);
  return b;
}

namespace {
float angular_radius(const glm::vec3& p, const scene::Sphere& s) {
  const float dist = glm::length(s.center - p);
  return dist > s.radius ? std::asin(s.radius / dist) : static_cast<float>(sh::kPi / 2);
}
}  // namespace

namespace {

// The cut of make_cut and make_cut_posed: sphere_of(t, id) is node id of tree t's sphere this frame.
template <class SphereOf>
BlockerList cut(const std::vector<const proxies::SphereHierarchy*>& trees, SphereOf sphere_of, const ZhTable& log_table,
                const glm::vec3& pR, float rR, const glm::vec3& pstar, const CutOptions& opt, CutStats* stats) {
  const int n = log_table.order;
  const int n2 = n * n;
  BlockerList out;
  out.order = n;
  const double sin_max = std::sin(opt.theta_max);
  CutStats st;
  std::array<float, sh::kMaxCoeffs> fb{}, fd{}, tmp{};
  std::vector<int> stack, detail;
  for (std::size_t t = 0; t < trees.size(); ++t) {
    const proxies::SphereHierarchy* tree = trees[t];
    if (!tree || tree->root() < 0) continue;
    const auto& nodes = tree->nodes();
    stack.assign(1, tree->root());
    while (!stack.empty()) {
      const int id = stack.back();
      stack.pop_back();
      ++st.nodes_visited;
      const proxies::SphereNode& node = nodes[id];
      const bool leaf = node.children.empty();
      const scene::Sphere& s = sphere_of(t, id);
      // eq. 36: the node subtends less than theta_max over the whole receiver cluster.
      const bool small = s.radius < sin_max * (glm::length(s.center - pR) - rR);
      if (!leaf && !small) {
        for (int ch : node.children) stack.push_back(ch);
        continue;
      }
      if (leaf || !opt.ratio_vectors) {
        if (leaf) ++st.leaves; else ++st.inner;
        out.push(s.center, s.radius, nullptr);
        continue;
      }
      ++st.inner;
      // Ratio vector (eq. 37) from the bounding (f_b) and detailed (f_d) log vectors at p*.
      sphere_zh_vector(log_table, pstar, s.center, s.radius, nullptr, fb.data());
      std::fill(fd.begin(), fd.begin() + n2, 0.0f);
      detail.assign(1, id);
      while (!detail.empty()) {
        const int d = detail.back();
        detail.pop_back();
        const proxies::SphereNode& dn = nodes[d];
        if (!dn.children.empty() && !(opt.theta_min > 0.0 && angular_radius(pstar, sphere_of(t, d)) < opt.theta_min)) {
          for (int ch : dn.children) detail.push_back(ch);
          continue;
        }
        ++st.detail_spheres;
        const scene::Sphere& ds = sphere_of(t, d);
        sphere_zh_vector(log_table, pstar, ds.center, ds.radius, nullptr, tmp.data());
        for (int i = 0; i < n2; ++i) fd[i] += tmp[i];
      }
      std::array<float, kMaxAccOrder> w{};
      for (int l = 0; l < n; ++l) {
        double num = 0.0, den = 0.0;
        for (int m = -l; m <= l; ++m) {
          const int i = sh::index(l, m);
          num += static_cast<double>(fb[i]) * fd[i];
          den += static_cast<double>(fb[i]) * fb[i];
        }
        // A band the bounding vector does not excite carries no information: keep it unscaled.
        w[l] = den > 1e-20 ? static_cast<float>(num / den) : 1.0f;
      }
      out.push(s.center, s.radius, w.data());
    }
  }
  if (stats) *stats += st;
  return out;
}

}  // namespace

BlockerList make_cut(const std::vector<const proxies::SphereHierarchy*>& trees,
                     const std::vector<std::vector<scene::Sphere>>& leaves, const ZhTable& log_table, const glm::vec3& pR,
                     float rR, const glm::vec3& pstar, const CutOptions& opt, CutStats* stats) {
  // A leaf's own sphere where the caller passes the leaf list, else its bound (the same sphere).
  auto sphere_of = [&](std::size_t t, int id) -> const scene::Sphere& {
    const proxies::SphereNode& nd = trees[t]->nodes()[static_cast<std::size_t>(id)];
    if (nd.children.empty() && nd.leaf >= 0 && t < leaves.size() && nd.leaf < static_cast<int>(leaves[t].size()))
      return leaves[t][nd.leaf];
    return nd.bound;
  };
  return cut(trees, sphere_of, log_table, pR, rR, pstar, opt, stats);
}

BlockerList make_cut_posed(const std::vector<const proxies::SphereHierarchy*>& trees,
                           const std::vector<std::vector<scene::Sphere>>& node_spheres, const ZhTable& log_table, const glm::vec3& pR,
                           float rR, const glm::vec3& pstar, const CutOptions& opt, CutStats* stats) {
  for (std::size_t t = 0; t < trees.size(); ++t)
    if (trees[t] && (t >= node_spheres.size() || node_spheres[t].size() != trees[t]->nodes().size()))
      throw std::invalid_argument("make_cut_posed: tree " + std::to_string(t) + " has " + std::to_string(trees[t]->nodes().size()) +
                                  " nodes and " + std::to_string(t < node_spheres.size() ? node_spheres[t].size() : 0) + " posed spheres");
  auto sphere_of = [&](std::size_t t, int id) -> const scene::Sphere& { return node_spheres[t][static_cast<std::size_t>(id)]; };
  return cut(trees, sphere_of, log_table, pR, rR, pstar, opt, stats);
}

}  // namespace softgi::techniques::common
