// Per-vertex receivers in receiver clusters (paper 004 section 6.3: "simple Lloyd clustering into a
// manually-specified number of clusters", several hundred vertices each), shared by the techniques
// that shade vertices (SHEXP, paper 004; spherical lights, paper 001, section 7.3). Not installed;
// include by path (techniques/common/...).
#pragma once

#include <cstddef>
#include <cstdint>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include <glm/glm.hpp>

#include "accumulation.hpp"

namespace softgi::render {
class FrameContext;
}

namespace softgi::techniques::common {

// k-means on positions, k-means++ seeding with a fixed seed.
struct LloydResult {
  std::vector<int> assignment;       // per point
  std::vector<glm::vec3> centres;    // per cluster (empty clusters are re-seeded, never returned)
  int iterations = 0;
};
LloydResult lloyd_cluster(const std::vector<glm::vec3>& points, int k, int max_iterations, unsigned seed,
                          const std::vector<glm::vec3>* initial_centres = nullptr);

struct ReceiverCluster {
  std::size_t begin = 0, end = 0;  // range in the cluster-ordered receiver arrays
  glm::vec3 centre{0.0f};          // p_R of paper 004 eq. 36 (centroid)
  float radius = 0.0f;             // r_R: every receiver of the cluster lies within
  glm::vec3 star{0.0f};            // p*: the receiver closest to the centroid (paper 004 section 6.3)
};

// Every vertex of every posed object as a receiver, in cluster order.
struct VertexReceivers {
  ReceiverSoA soa;                                // cluster order
  std::vector<int> object, vertex;                // source of each receiver
  std::vector<ReceiverCluster> clusters;
  std::vector<std::vector<std::uint32_t>> index;  // [object][vertex] -> receiver
  std::size_t bytes() const {
    return soa.size() * (6 * sizeof(float) + 3 * sizeof(int)) + clusters.size() * sizeof(ReceiverCluster);
  }
};

// The clustering kept across frames: a cluster never spans two objects, the count is split by
// vertex count; an object whose vertices did not move keeps its clusters, one that moved is
// re-clustered warm-started from its last centres (section 6.3: recompute when geometry moves).
class ReceiverClustering {
 public:
  // Receivers per cluster when the requested count is 0 ("several hundred vertices per receiver
  // cluster", paper 004 section 6.3).
  static constexpr int kAutoReceiversPerCluster = 300;
  // The receivers of this frame's pose with `clusters` clusters (0 = one per ~300 vertices). Checks
  // the posed objects (throws std::invalid_argument prefixed with `technique`) and records the
  // counters receivers, clusters, receivers_per_cluster_mean/max, lloyd_iterations, reclustered and
  // objects_reclustered on the running pass.
  std::shared_ptr<const VertexReceivers> update(const std::string& technique, render::FrameContext& ctx, int clusters);

 private:
  std::mutex m_;
  std::string key_;
  std::vector<std::vector<int>> assignment_;  // [object][vertex] -> global cluster
  std::vector<glm::vec3> centres_;
  std::vector<int> cluster_object_;
  std::vector<std::vector<glm::vec3>> last_positions_;  // per object, when last clustered
};

}  // namespace softgi::techniques::common
