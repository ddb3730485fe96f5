// Sphere hierarchies over a sphere set (paper 004 section 6.3).
#pragma once

#include <vector>

#include "softgi/scene/scene.hpp"

namespace softgi::proxies {

struct SphereNode {
  scene::Sphere bound;
  std::vector<int> children;  // node indices; empty for leaves
  int leaf = -1;              // index into the leaf sphere list for leaves
  int parent = -1;
};

class SphereHierarchy {
 public:
  // Levels built leaves-up by Lloyd clustering (assignment to the closest cluster centre, centre
  // optimised to minimise the bounding radius) with average branching ratio `branching` (paper: 4).
  static SphereHierarchy build(const std::vector<scene::Sphere>& leaves, int branching = 4, unsigned seed = 1);
  // Moves the leaves and refits every parent bottom-up with a sphere-pair bound merging each child in
  // turn (section 6.3, during animation). `leaves` must have the same size as at build time.
  void update(const std::vector<scene::Sphere>& leaves);

  const std::vector<SphereNode>& nodes() const { return nodes_; }
  int root() const { return root_; }
  int depth() const;
  double average_branching() const;
  // Every node's bound contains all of its descendants' leaves (tolerance 1e-5 relative).
  bool bounds_are_conservative() const;

 private:
  std::vector<SphereNode> nodes_;
  int root_ = -1;
};

// Smallest sphere containing both a and b.
scene::Sphere merge(const scene::Sphere& a, const scene::Sphere& b);

}  // namespace softgi::proxies
