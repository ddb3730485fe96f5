// Sphere-hierarchy cuts per receiver cluster with ratio vectors (paper 004 section 6.3, eqs. 36-37),
// shared by the techniques that accumulate blockers per receiver cluster (SHEXP, paper 004; the
// direct shadows of spherical lights, paper 001 section 7.3). Not installed; include by path.
#pragma once

#include <vector>

#include <glm/glm.hpp>

#include "accumulation.hpp"
#include "softgi/proxies/hierarchy.hpp"
#include "softgi/scene/scene.hpp"

namespace softgi::techniques::common {

// Hierarchy cuts (paper 004 section 6.3, eqs. 36-37). `trees` holds one hierarchy per proxy set.
struct CutOptions {
  double theta_max = 25.0 * sh::kPi / 180.0;  // eq. 36 threshold (paper: 20-30 degrees)
  double theta_min = 0.0;                     // detail pruning for f_d at p* (0 = every leaf)
  bool ratio_vectors = true;                  // eq. 37; false: W = 1 (Figure 6b)
};
struct CutStats {
  long long nodes_visited = 0, leaves = 0, inner = 0, detail_spheres = 0;
  CutStats& operator+=(const CutStats& o) {
    nodes_visited += o.nodes_visited;
    leaves += o.leaves;
    inner += o.inner;
    detail_spheres += o.detail_spheres;
    return *this;
  }
};
// The cut for a receiver cluster bounded by (pR, rR): nodes with r_i < sin(theta_max)(|P_i - pR| - rR)
// are taken whole, others are opened; leaves are always taken (w = 1). For each inner node taken, the
// bounding (f_b) and detailed (f_d, summed over the leaves below, pruned at theta_min) log vectors at
// p* give the ratio vector w_l = sum_m f_b,lm f_d,lm / sum_m f_b,lm^2 (eq. 37).
BlockerList make_cut(const std::vector<const proxies::SphereHierarchy*>& trees, const std::vector<std::vector<scene::Sphere>>& leaves,
                     const ZhTable& log_table, const glm::vec3& pR, float rR, const glm::vec3& pstar,
                     const CutOptions& opt, CutStats* stats);
// make_cut over trees whose nodes moved apart from their build-time bounds: node_spheres[t][id] is
// node id of tree t as posed this frame (leaves and inner nodes; a tree may be null, and is skipped).
// The rest as make_cut. Throws std::invalid_argument where a tree's node count and its posed spheres
// differ.
BlockerList make_cut_posed(const std::vector<const proxies::SphereHierarchy*>& trees,
                           const std::vector<std::vector<scene::Sphere>>& node_spheres, const ZhTable& log_table, const glm::vec3& pR,
                           float rR, const glm::vec3& pstar, const CutOptions& opt, CutStats* stats);
// Per receiver cluster, the blocker list its receivers sum: lists[list_of_cluster[c]].
struct ClusterCuts {
  std::vector<BlockerList> lists;
  std::vector<int> list_of_cluster;
  std::size_t bytes() const {
    std::size_t b = list_of_cluster.size() * sizeof(int);
    for (const auto& l : lists) b += l.bytes();
    return b;
  }
  // Over the clusters: the mean and the largest size of their lists (0 without clusters).
  double mean_size() const;
  std::size_t max_size() const;
};
// Every leaf of every set, W = 1 (no hierarchy).
BlockerList flat_list(const std::vector<std::vector<scene::Sphere>>& sets, int order);

}  // namespace softgi::techniques::common
