// SHEXP internals (paper 004, Ren et al. 2006): the pieces of the technique's passes that are
// SHEXP's own (per-vertex receiver clusters, hierarchy cuts with ratio vectors, the product-space
// baseline and the projected reference), on top of the shared accumulation library
// (techniques/common/accumulation.hpp), exposed to tests/shexp and bench/bench_shexp.cpp. Not
// installed; include by path.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include <glm/glm.hpp>

#include "../common/accumulation.hpp"
#include "softgi/proxies/hierarchy.hpp"
#include "softgi/scene/scene.hpp"
#include "softgi/sh/exp_log.hpp"
#include "softgi/sh/sh.hpp"
#include "softgi/sh/tables.hpp"

namespace softgi::techniques::shexp {

// SHEXP's code, tests and benchmarks name the shared library's types unqualified.
using namespace ::softgi::techniques::common;

// ---------------------------------------------------------------------------------------------
// Product-space accumulation (Zhou et al. 2005, paper 004 eq. 6), the baseline: per receiver,
// g = ((1 * g[1]) * g[2]) * ... * g[m], products left to right in blocker-list order, each g[i] the
// cap visibility ZH rotated by eq. 34 with the visibility table G instead of F. Band weights of the
// list are ignored (ratio vectors are defined for log vectors). Returns the number of SH products.
long long accumulate_product(const ZhTable& vis_table, ReplacementRule rule, const ReceiverSoA& rec,
                             std::size_t begin, std::size_t end, const BlockerList& blockers, float* out);
// The order-n projection of the exact binary visibility of the (rule-adjusted) spheres, by a product
// quadrature with `bands` bands (2 bands^2 directions): what no order-n accumulation can beat, for
// error analysis (docs/techniques/shexp.md, Figure 7).
void project_visibility(int order, int bands, ReplacementRule rule, const ReceiverSoA& rec, std::size_t begin,
                        std::size_t end, const BlockerList& blockers, float* out);

// ---------------------------------------------------------------------------------------------
// Receiver clusters (paper 004 section 6.3: "simple Lloyd clustering into a manually-specified
// number of clusters"): k-means on positions, k-means++ seeding with a fixed seed.
struct LloydResult {
  std::vector<int> assignment;       // per point
  std::vector<glm::vec3> centres;    // per cluster (empty clusters are re-seeded, never returned)
  int iterations = 0;
};
LloydResult lloyd_cluster(const std::vector<glm::vec3>& points, int k, int max_iterations, unsigned seed,
                          const std::vector<glm::vec3>* initial_centres = nullptr);

struct ReceiverCluster {
  std::size_t begin = 0, end = 0;  // range in the cluster-ordered receiver arrays
  glm::vec3 centre{0.0f};          // p_R of eq. 36 (centroid)
  float radius = 0.0f;             // r_R: every receiver of the cluster lies within
  glm::vec3 star{0.0f};            // p*: the receiver closest to the centroid (section 6.3)
};

// ---------------------------------------------------------------------------------------------
// Hierarchy cuts (paper 004 section 6.3, eqs. 36-37). `trees` holds one hierarchy per proxy set.
struct CutOptions {
  double theta_max = 25.0 * sh::kPi / 180.0;  // eq. 36 threshold (paper: 20-30 degrees)
  double theta_min = 0.0;                     // detail pruning for f_d at p* (0 = every leaf)
  bool ratio_vectors = true;                  // eq. 37; false: W = 1 (Figure 6b)
};
struct CutStats {
  long long nodes_visited = 0, leaves = 0, inner = 0, detail_spheres = 0;
};
// The cut for a receiver cluster bounded by (pR, rR): nodes with r_i < sin(theta_max)(|P_i - pR| - rR)
// are taken whole, others are opened; leaves are always taken (w = 1). For each inner node taken, the
// bounding (f_b) and detailed (f_d, summed over the leaves below, pruned at theta_min) log vectors at
// p* give the ratio vector w_l = sum_m f_b,lm f_d,lm / sum_m f_b,lm^2 (eq. 37).
BlockerList make_cut(const std::vector<const proxies::SphereHierarchy*>& trees, const std::vector<std::vector<scene::Sphere>>& leaves,
                     const ZhTable& log_table, const glm::vec3& pR, float rR, const glm::vec3& pstar,
                     const CutOptions& opt, CutStats* stats);
// Every leaf of every set, W = 1 (no hierarchy).
BlockerList flat_list(const std::vector<std::vector<scene::Sphere>>& sets, int order);

}  // namespace softgi::techniques::shexp
