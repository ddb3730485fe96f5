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

// How SphereHierarchy::build clusters each level. The defaults follow the paper; the limits keep
// the build O(n log n) for sets of 100k spheres.
struct HierarchyBuildOptions {
  // Average children per parent: each level has about n / branching clusters (paper: 4). [2, 64].
  int branching = 4;
  // A cluster with more members is split in space into groups of about `branching` (0: 4 x
  // branching). Lloyd clustering gives this only on degenerate input (many coincident centres,
  // which all have the same closest cluster); on proxy sets it never binds. >= 2 x branching.
  int max_children = 0;
  // Lloyd iterations per level; a level stops earlier once no sphere changes cluster. [1, 1000].
  int lloyd_iterations = 50;
  // Evaluations of the radius that Powell's method may spend on one cluster's bounding sphere,
  // over all its stages. [100, 100000], or 0: no Powell, the better of the average centre and
  // the pairwise-merge centre (a looser but much cheaper tree).
  int fit_evaluations = 1500;
};

class SphereHierarchy {
 public:
  // Levels built leaves-up by Lloyd clustering (assignment to the closest cluster centre, centre
  // optimised to minimise the bounding radius). Deterministic: the same leaves and options give
  // the same tree. Long builds report on softgi::Progress (softgi/progress.hpp).
  static SphereHierarchy build(const std::vector<scene::Sphere>& leaves, const HierarchyBuildOptions& options);
  static SphereHierarchy build(const std::vector<scene::Sphere>& leaves, int branching = 4);
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
